//! Where encoders write: anything that can take bytes, a growable `Vec<u8>`
//! (emulator, tests) or a fixed-capacity `heapless::Vec` (driver hot path).

/// Why encoding a command or reply failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum EncodeError {
    /// The output buffer is full.
    #[error("output buffer is full")]
    Overflow,
    /// A number does not fit the field it must be written into.
    #[error("value {value} does not fit in {width} characters")]
    ValueTooLarge {
        /// The value that was to be written.
        value: u64,
        /// The field width in characters.
        width: usize,
    },
    /// A text field holds a byte a SCIP line cannot carry (LF, CR, `;` or
    /// non-printable).
    #[error("text field holds a byte a SCIP line cannot carry: 0x{0:02x}")]
    BadText(u8),
}

/// A byte destination for the SCIP encoders.
pub trait ByteSink {
    /// Appends `bytes`, or fails without a partial guarantee when full.
    fn put(&mut self, bytes: &[u8]) -> Result<(), EncodeError>;
}

#[cfg(any(test, feature = "alloc"))]
impl ByteSink for alloc::vec::Vec<u8> {
    fn put(&mut self, bytes: &[u8]) -> Result<(), EncodeError> {
        self.extend_from_slice(bytes);
        Ok(())
    }
}

impl<const N: usize> ByteSink for heapless::Vec<u8, N> {
    fn put(&mut self, bytes: &[u8]) -> Result<(), EncodeError> {
        self.extend_from_slice(bytes)
            .map_err(|_| EncodeError::Overflow)
    }
}
