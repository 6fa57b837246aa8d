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

/// Builds the wheel-base driver the config selects, opening `p.device` as a
/// tty (raw, exclusive, through [`crate::serial::DeviceConnector`]) on its
/// first poll.
pub fn open_base(
    p: &MotorParams,
    robot: &crate::config::RobotParams,
    clock: crate::clock::SharedClock,
) -> Box<dyn DiffDriveBase> {
    let mut dev = crate::serial::DeviceConnector::new(p.device.clone());
    dev.baud = p.baud;
    let opener = Box::new(link::ConnectorOpener(Box::new(dev)));
    match p.kind {
        BaseKind::Roboclaw => Box::new(roboclaw::driver::RoboClawDriver::new(
            p, robot, opener, clock,
        )),
        BaseKind::Create2 => Box::new(create2::driver::Create2Driver::new(p, robot, opener, clock)),
    }
}
