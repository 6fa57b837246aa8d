//! iRobot Create 2 / Roomba Open Interface: the sans-IO [`codec`] and the
//! [`driver`] that owns the port.

pub mod codec;
pub mod driver;
