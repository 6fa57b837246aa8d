//! SCIP 2.0 codec (sans-IO): byte framing, checksums, character decoding,
//! typed commands and replies for the Hokuyo URG family. No ports, threads,
//! clocks or allocation on the scan path; never panics on any input.
//!
//! Host side: encode a [`TaggedCommand`] with [`TaggedCommand::encode`], feed
//! whatever bytes the port returns to a [`Decoder`], and turn each complete
//! [`RawReply`] into a typed [`Reply`] with [`RawReply::decode`]. A scan reply
//! borrows the decoder's buffer ([`ScanData`]), whose values decode lazily
//! without allocating (sweepline's driver turns them into its `LaserScan`).
//!
//! Sensor side (the emulator): parse a received line with
//! [`TaggedCommand::parse`], answer with the encoders in [`reply`]
//! ([`write_status_reply`], [`encode_reply`], [`DataLineWriter`]).
//!
//! Ranges stay in millimetres and angles in sensor steps here; [`SensorParams`]
//! converts steps to radians and seconds from the sensor's own PP answer.
//!
//! ```
//! use sweepline_wire::scip::{Command, Decoder, Event, ReplyBody, SensorParams, TaggedCommand};
//!
//! // Host → sensor: exact bytes.
//! let mut out = heapless::Vec::<u8, 64>::new();
//! TaggedCommand::new(Command::Pp).encode(&mut out).unwrap();
//! assert_eq!(&out[..], b"PP\n");
//!
//! // Sensor → host: bytes in whatever chunks read() returns.
//! let reply = b"PP\n00P\nMODL:URG-04LX(Hokuyo Automatic Co.,Ltd.);N\nDMIN:20;4\n\
//!     DMAX:5600;_\nARES:1024;\\\nAMIN:44;7\nAMAX:725;o\nAFRT:384;6\nSCAN:600;e\n\n";
//! let mut dec = Decoder::default();
//! let mut params = None;
//! for chunk in reply.chunks(7) {
//!     dec.feed_each(chunk, |ev| match ev {
//!         Event::Reply(raw) => {
//!             if let Ok(r) = raw.decode() {
//!                 if let ReplyBody::Params(p) = r.body {
//!                     params = Some(p);
//!                 }
//!             }
//!         }
//!         Event::Error(e) => eprintln!("dropped: {e}"),
//!     });
//! }
//! assert_eq!(params, Some(SensorParams::urg_04lx()));
//! assert_eq!(dec.stats().checksum_errors(), 0);
//! ```
//!
//! Recovery: a broken reply (bad checksum, noise, overlong line, lost line
//! end) is reported once as [`FrameError`] and counted in [`DecoderStats`];
//! the decoder skips to the next reply boundary by itself, or to the next
//! valid echo (so the `QT` echo is found even in the middle of a stream).

pub mod capacity;
#[cfg(any(test, feature = "alloc"))]
pub mod capture;
pub mod checksum;
pub mod clock;
pub mod command;
pub mod decoder;
pub mod encoding;
pub mod error_codes;
pub mod framer;
pub mod params;
pub mod reply;
pub mod scan;
pub mod sink;
pub mod status;

#[cfg(any(test, feature = "alloc"))]
pub use capture::{parse_capture, CaptureError, CaptureRecord};
pub use checksum::{checksum, ChecksumError, KvQuirk};
pub use clock::ClockUnwrapper;
pub use command::{
    Cluster, Command, CommandError, CommandKind, DataKind, ScanRequest, StreamRequest, Tag,
    TaggedCommand, TimeControl,
};
pub use decoder::{Decoder, DecoderOptions, DecoderStats, Event, FrameError, RawReply};
pub use encoding::{decode_value, encode_value, EncodingError, Width};
pub use error_codes::{ErrorKind, ErrorReading, ModelFamily, Reading};
pub use framer::{LineEvent, LineFramer};
pub use params::{KvLine, SensorInfo, SensorParams, VersionInfo};
pub use reply::{encode_reply, write_status_reply, DataLineWriter, Reply, ReplyBody, ReplyError};
pub use scan::{ScanData, ScanError, ScanValue};
pub use sink::{ByteSink, EncodeError};
pub use status::{Status, StatusCode};
