//! Basicmicro RoboClaw over packet serial: the sans-IO [`codec`] and the
//! [`driver`] that owns the port.

pub use sweepline_wire::roboclaw as codec;
pub mod driver;
