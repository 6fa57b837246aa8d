//! Sans-IO wire codecs for a coverage robot's devices, without a port, a
//! clock, a thread or an allocation:
//!
//! * [`scip`]: Hokuyo's SCIP 2.0 (URG-04LX, UTM-30LX and the rest of the
//!   URG family): command encoding and parsing, the reply framer and
//!   decoder with checksums and resynchronisation, scan data, status and
//!   error codes, the sensor clock's wrap;
//! * [`roboclaw`]: Basicmicro RoboClaw packet serial (reads `[address,
//!   command]` answered with data and CRC16; writes with CRC16 answered
//!   `0xFF`), both sides;
//! * [`create2`]: the iRobot Create 2 / Roomba Open Interface: opcodes with
//!   their data lengths, sensor packets and groups, the stream frames;
//! * [`crc16`]: the CRC16-CCITT (XModem) RoboClaw uses.
//!
//! `#![no_std]` and no `alloc`: every buffer is a `heapless` one whose size
//! is in its type, and no input makes a codec panic (each has a property
//! test feeding it arbitrary bytes). The `alloc` feature adds what a host
//! wants besides: [`scip::ByteSink`] for `Vec<u8>` and the capture-file
//! parser (`scip::parse_capture`).
//!
//! This crate is the bottom layer of sweepline (see its
//! `docs/architecture.md`); it depends on nothing of it.

#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

#[cfg(any(test, feature = "alloc"))]
extern crate alloc;

pub mod crc16;
pub mod create2;
mod float;
pub mod roboclaw;
pub mod scip;
