//! The wheel-base link: sans-IO codecs for RoboClaw packet serial and the
//! iRobot Create 2 Open Interface, drivers over a port, odometry and safety.
//!
//! * [`types`]: [`WheelSpeeds`], [`Odometry`], [`SafetyEvent`], [`LinkHealth`]
//!   and the [`DiffDriveBase`] trait every driver implements;
//! * [`roboclaw`] and [`create2`]: each a sans-IO `codec` and a `driver`;
//! * [`odometry`]: wrapping counters to pose increments, and
//!   [`odometry::OdometryTrack`] for the pose at a scan's timestamp;
//! * [`safety`]: the dead-man and the bumper/wheel-drop gate;
//! * [`command`]: the requested set-point, dead-man, gate and pending safety
//!   events every driver holds;
//! * [`link`]: the port under a driver, re-opened after the device vanished;
//! * [`params`]: the `[motor]` table.
//!
//! The daemon's motor thread, in short, is the example in
//! `sweepline::sim::base_emu` (run there against an emulated RoboClaw on a
//! pty, exactly as against `/dev/sweepline-base`).

pub mod command;
pub use sweepline_wire::crc16;
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
    robot: &crate::robot::RobotParams,
    clock: crate::clock::SharedClock,
) -> Box<dyn DiffDriveBase> {
    let mut dev = crate::serial::DeviceConnector::new(p.device.clone());
    dev.baud = p.baud;
    let opener = Box::new(link::ConnectorOpener(Box::new(dev)));
    base_driver(p.kind, p, robot, opener, clock)
}

/// Builds the driver for a base of `kind` over whatever port `opener` opens (a
/// tty, an emulator's pty, an in-process loopback): [`open_base`] without the
/// choice of port.
pub fn base_driver(
    kind: BaseKind,
    p: &MotorParams,
    robot: &crate::robot::RobotParams,
    opener: Box<dyn link::LinkOpener>,
    clock: crate::clock::SharedClock,
) -> Box<dyn DiffDriveBase> {
    match kind {
        BaseKind::Roboclaw => Box::new(roboclaw::driver::RoboClawDriver::new(
            p, robot, opener, clock,
        )),
        BaseKind::Create2 => Box::new(create2::driver::Create2Driver::new(p, robot, opener, clock)),
    }
}
