//! The wheel-base link: sans-IO codecs for RoboClaw packet serial and the
//! iRobot Create 2 Open Interface, drivers over a port, odometry and safety.

pub mod crc16;
pub mod create2;
pub mod roboclaw;
pub mod types;

pub use types::{
    BaseFeedback, DiffDriveBase, LinkHealth, MotorError, Odometry, SafetyEvent, Sides, WheelSpeeds,
};

/// Wheel-base link settings.
/// Loaded from the `[motor]` table of the config file; every field is documented
/// in `hw/robot.toml`.
#[derive(Clone, Debug, Default, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct MotorParams {}
