//! The checks that run beside the daemon's stages, as pure algorithms fed
//! by the stages:
//!
//! * the scanner's mount: [`offset_check`] (the mount's offset, from turns
//!   in place), [`travel_check`] (its yaw and the wheels' scale, from the
//!   first metre), [`turn_check`] (the wheel base, from turns against the
//!   walls);
//! * [`align`]: the map frame turned to the room's walls at a fresh start;
//! * [`contact`]: bumper contacts marked in the map, and when to take a
//!   mark out to try the floor behind it;
//! * [`relocalise`]: finding the robot in its checkpointed map after a
//!   restart;
//! * [`consistency`]: whether a matched scan agrees with the map (a match
//!   at a wrong place puts its end points on floor seen free);
//! * [`stuck`]: the control stage's progress watch.
//!
//! Deskewing a scan by the odometry's motion is
//! [`LaserScan::deskew_steady`](crate::scan::LaserScan::deskew_steady).

pub mod align;
pub mod consistency;
pub mod contact;
pub mod offset_check;
pub mod relocalise;
pub mod stuck;
pub mod travel_check;
pub mod turn_check;
