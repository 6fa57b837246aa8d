//! Basicmicro RoboClaw over packet serial: the sans-IO [`codec`] and the
//! [`driver`] that owns the port.

pub mod codec;
pub mod driver;
