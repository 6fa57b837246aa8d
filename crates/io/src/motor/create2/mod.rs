//! iRobot Create 2 / Roomba Open Interface: the sans-IO [`codec`] and the
//! [`driver`] that owns the port.

pub use sweepline_wire::create2 as codec;
pub mod driver;
