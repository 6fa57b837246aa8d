//! The wheel-base link: sans-IO codecs for RoboClaw packet serial and the
//! iRobot Create 2 Open Interface, drivers over a port, odometry and safety.

pub mod crc16;
pub mod create2;
pub mod link;
pub mod odometry;
pub mod params;
pub mod roboclaw;
pub mod safety;
pub mod types;

pub use params::{BaseKind, Create2Params, MotorParams, RoboClawParams};
pub use types::{
    BaseFeedback, DiffDriveBase, LinkHealth, MotorError, Odometry, SafetyEvent, Sides, WheelSpeeds,
};
