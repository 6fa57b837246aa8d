//! The physical robot: footprint, tool, wheels, drive limits and where the
//! scanner sits. Shared by the planner, the controller, the wheel-base
//! drivers and the simulator; the `[robot]` table of the configuration.

use serde::{Deserialize, Serialize};

use crate::param_check::{invalid, ParamError};

/// Physical robot: footprint, tool and drive limits. Shared by planner,
/// controller, motor link and simulator.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct RobotParams {
    /// Radius of the robot's circular footprint (m); walls are inflated by it.
    pub radius: f64,
    /// Width of the cleaning tool (m); lanes are this far apart at most.
    pub tool_width: f64,
    /// Distance between the wheels' contact points (m).
    pub wheel_base: f64,
    /// Wheel radius (m).
    pub wheel_radius: f64,
    /// Top linear speed (m/s); the paper's robot: 0.226.
    pub(crate) max_speed: f64,
    /// Top turn rate (rad/s); the paper's robot: 0.78.
    pub(crate) max_turn_rate: f64,
    /// Scanner mounting offset forward of the wheel axle centre (m).
    pub scanner_offset_x: f64,
    /// Scanner mounting offset to the left of the wheel axle centre (m).
    pub scanner_offset_y: f64,
    /// Direction (rad, counter-clockwise from the robot's front) of the
    /// scanner's own front (its 0° beam).
    pub scanner_yaw: f64,
    /// The scanner is mounted upside down: it sweeps clockwise as seen from
    /// above, so its beam angles are mirrored.
    pub scanner_upside_down: bool,
}

impl RobotParams {
    /// Checks the values (each error names its `robot.` key).
    pub fn validate(&self) -> Result<(), ParamError> {
        crate::check_keys!(
            self,
            "robot",
            positive: [radius, tool_width, wheel_base, wheel_radius, max_speed, max_turn_rate],
            finite: [scanner_offset_x, scanner_offset_y],
        );
        let y = self.scanner_yaw;
        if !(y.is_finite() && (-std::f64::consts::PI..=std::f64::consts::PI).contains(&y)) {
            return Err(invalid(
                "robot.scanner_yaw",
                &format!("must be an angle in radians within -pi..=pi, got {y:?}"),
            ));
        }
        Ok(())
    }

    /// The scanner's pose in the robot frame (offsets and yaw); an
    /// upside-down mount mirrors the beams besides (see
    /// [`crate::scan::LaserScan::mirror`]).
    pub fn scanner_mount(&self) -> crate::geom::Pose {
        crate::geom::pose(
            self.scanner_offset_x,
            self.scanner_offset_y,
            self.scanner_yaw,
        )
    }
}

impl Default for RobotParams {
    fn default() -> Self {
        Self {
            radius: 0.17,
            tool_width: 0.30,
            wheel_base: 0.235,
            wheel_radius: 0.036,
            max_speed: 0.226,
            max_turn_rate: 0.78,
            scanner_offset_x: 0.0,
            scanner_offset_y: 0.0,
            scanner_yaw: 0.0,
            scanner_upside_down: false,
        }
    }
}
