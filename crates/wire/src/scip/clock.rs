//! The sensor's 24-bit millisecond clock wraps every 2^24 ms (about 4 h 40 min);
//! [`ClockUnwrapper`] turns successive stamps into a monotonic 64-bit count.

/// Period of the sensor clock in milliseconds.
pub const CLOCK_PERIOD_MS: u64 = 1 << 24;

/// Unwraps successive 24-bit sensor stamps. A drop of more than half the
/// period counts as a wrap; a smaller step backwards is reported (clock reset
/// or reordering) and does not move the wrap count.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ClockUnwrapper {
    last: Option<u32>,
    wraps: u64,
    backwards: u64,
}

impl ClockUnwrapper {
    /// A fresh unwrapper (no stamp seen yet).
    pub fn new() -> Self {
        Self::default()
    }

    /// Unwraps `stamp` (only its low 24 bits are used) into milliseconds since
    /// the first stamp's epoch.
    pub fn unwrap(&mut self, stamp: u32) -> u64 {
        let stamp = stamp & 0x00ff_ffff;
        if let Some(last) = self.last {
            if stamp < last {
                if last - stamp > (1 << 23) {
                    self.wraps += 1;
                } else {
                    self.backwards += 1;
                }
            } else if stamp - last > (1 << 23) && self.wraps > 0 {
                // A late stamp from before the last wrap.
                self.backwards += 1;
                return (self.wraps - 1) * CLOCK_PERIOD_MS + u64::from(stamp);
            }
        }
        self.last = Some(stamp);
        self.wraps * CLOCK_PERIOD_MS + u64::from(stamp)
    }

    /// Forgets all history (after RS, which resets the sensor clock to 0).
    pub fn reset(&mut self) {
        *self = Self::default();
    }

    /// Number of wraps seen.
    pub fn wraps(&self) -> u64 {
        self.wraps
    }

    /// Number of small backward steps seen (resets, reordering).
    pub fn backward_steps(&self) -> u64 {
        self.backwards
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unwraps_across_the_24_bit_boundary() {
        let mut u = ClockUnwrapper::new();
        assert_eq!(u.unwrap(0xFF_FF00), 0xFF_FF00);
        assert_eq!(u.unwrap(0xFF_FFF0), 0xFF_FFF0);
        assert_eq!(u.unwrap(0x00_0050), CLOCK_PERIOD_MS + 0x50);
        assert_eq!(u.wraps(), 1);
        assert_eq!(u.unwrap(0x00_00B4), CLOCK_PERIOD_MS + 0xB4);
        assert_eq!(u.unwrap(0x00_00A0), CLOCK_PERIOD_MS + 0xA0);
        assert_eq!(u.backward_steps(), 1);
        assert_eq!(u.wraps(), 1);
        u.reset();
        assert_eq!(u.unwrap(5), 5);
    }

    #[test]
    fn late_stamp_from_before_a_wrap_is_not_a_jump() {
        let mut u = ClockUnwrapper::new();
        u.unwrap(0xFF_FFF0);
        u.unwrap(0x10);
        assert_eq!(u.unwrap(0xFF_FFF8), 0xFF_FFF8);
        assert_eq!(u.wraps(), 1);
        assert_eq!(u.unwrap(0x20), CLOCK_PERIOD_MS + 0x20);
        assert_eq!(u.wraps(), 1);
    }

    #[test]
    fn high_bits_are_ignored() {
        let mut u = ClockUnwrapper::new();
        assert_eq!(u.unwrap(0xFF00_0001), 1);
    }
}
