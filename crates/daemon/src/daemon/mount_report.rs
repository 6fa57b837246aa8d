//! The run folder's `mount.toml`: what this run's checks measured of the
//! scanner's mount and the wheels ([`super::offset_check`],
//! [`super::travel_check`], [`super::turn_check`]), written as the `[robot]`
//! values that fit the measurements, to compare with the configuration or
//! paste into it. Pure: status and configuration in, text out.

use nalgebra::Rotation2;

use super::shared::LiveStatus;
use crate::robot::RobotParams;

/// Name of the file in the run folder.
pub(crate) const MOUNT_FILE: &str = "mount.toml";

/// The `mount.toml` text for a run configured with `robot` whose checks
/// left `status`; `None` when no check measured anything.
pub(crate) fn mount_toml(robot: &RobotParams, status: &LiveStatus) -> Option<String> {
    let (offset, travel, turn) = (status.offset_fit, status.travel_fit, status.turn_ratio);
    if offset.is_none() && travel.is_none() && turn.is_none() {
        return None;
    }
    let mut s = String::from(
        "# What this run's checks measured of the scanner's mount and the wheels\n\
         # (written by sweepline at the end of the run). Each value fits the\n\
         # measurement named beside it; a key left as a comment was not measured.\n\n\
         [robot]\n",
    );
    match offset {
        Some(f) => {
            // Fitted under the configured yaw: a yaw measured off by α
            // turned the fitted offset by α (see `offset_check`).
            let alpha = travel.map_or(0.0, |t| t.angle);
            let t = Rotation2::new(-alpha) * f.offset;
            let how = format!("fitted over {:.0}° turning in place", f.turned.to_degrees());
            s += &format!(
                "scanner_offset_x = {:.3}  # configured {:.3}; {how}\n",
                t.x, robot.scanner_offset_x
            );
            s += &format!(
                "scanner_offset_y = {:.3}  # configured {:.3}\n",
                t.y, robot.scanner_offset_y
            );
        }
        None => {
            s += "# scanner_offset_x, scanner_offset_y: no half turn in place over scans that pin the pose down (matched, firm in every direction)\n"
        }
    }
    match travel {
        Some(f) => {
            s += &format!(
                "scanner_yaw = {:.4}  # configured {:.4}; the scans moved {:+.2}° off the heading over {:.2} m driven straight ({:.1} % of the wheels' distance)\n",
                f.fitting_yaw(),
                robot.scanner_yaw,
                f.angle.to_degrees(),
                f.driven,
                f.scale * 100.0
            );
        }
        None => s += "# scanner_yaw: no metre driven straight over scans that pin the pose down (matched, firm in every direction)\n",
    }
    if let Some(f) = travel {
        // A comment only: one metre measures the scale to a percent or two.
        s += &format!(
            "# wheel_radius = {:.4}  # configured {:.4}; fits the scans' {:.1} % of the wheels' distance over {:.2} m (a 1 m check: trust it beyond a few percent)\n",
            robot.wheel_radius * f.scale,
            robot.wheel_radius,
            f.scale * 100.0,
            f.driven
        );
    }
    match turn {
        Some(r) if r > 0.0 => {
            // The wheels' turn is scaled by the wheel radius as their
            // distance is: the first metre's scale takes that part out.
            let scale = travel.map_or(1.0, |t| t.scale);
            let how = if travel.is_some() {
                format!(
                    ", divided by the first metre's distance scale of {:.1} %",
                    scale * 100.0
                )
            } else {
                String::new()
            };
            s += &format!(
                "wheel_base = {:.3}  # configured {:.3}; the scans turned {:.1} % of the wheels' first quarter turn{how}\n",
                super::turn_check::fitting_wheel_base(r, robot.wheel_base) * scale,
                robot.wheel_base,
                r * 100.0
            );
        }
        Some(r) => {
            s += &format!(
                "# wheel_base: the scans turned against the wheels ({:.0} %): a mirrored scanner or swapped wheels\n",
                r * 100.0
            );
        }
        None => s += "# wheel_base: no quarter turn with walls in view\n",
    }
    Some(s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::daemon::offset_check::OffsetFit;
    use crate::daemon::travel_check::TravelFit;
    use nalgebra::Vector2;

    #[test]
    fn nothing_measured_writes_nothing() {
        assert_eq!(
            mount_toml(&RobotParams::default(), &LiveStatus::default()),
            None
        );
    }

    #[test]
    fn the_measured_values_are_written_as_robot_keys_that_parse() {
        let robot = RobotParams::default();
        let mut st = LiveStatus {
            offset_fit: Some(OffsetFit {
                offset: Rotation2::new(-0.05) * Vector2::new(0.08, 0.04),
                turned: 3.2,
            }),
            travel_fit: Some(TravelFit {
                angle: -0.05,
                scale: 1.01,
                driven: 1.02,
                yaw: 0.0,
            }),
            turn_ratio: Some(robot.wheel_base / 0.25),
            ..LiveStatus::default()
        };
        let text = mount_toml(&robot, &st).unwrap();
        let v: toml::Table = text.parse().unwrap_or_else(|e| panic!("{e}\n{text}"));
        let r = v["robot"].as_table().unwrap();
        let get = |k: &str| r[k].as_float().unwrap();
        assert!((get("scanner_offset_x") - 0.08).abs() < 6e-4, "{text}");
        assert!((get("scanner_offset_y") - 0.04).abs() < 6e-4, "{text}");
        assert!((get("scanner_yaw") - 0.05).abs() < 6e-5, "{text}");
        // Turn ratio and distance scale both off by the radius's 1 %: the
        // base is the ratio's, corrected by the scale.
        assert!((get("wheel_base") - 0.25 * 1.01).abs() < 6e-4, "{text}");
        // The wheel radius from one metre is a comment, never a key.
        assert!(!r.contains_key("wheel_radius"), "{text}");
        assert!(text.contains("# wheel_radius = 0.0364"), "{text}");
        // Unmeasured, or mirrored: comments, no keys.
        st.travel_fit = None;
        st.turn_ratio = Some(-1.0);
        let text = mount_toml(&robot, &st).unwrap();
        let v: toml::Table = text.parse().unwrap();
        let r = v["robot"].as_table().unwrap();
        assert!(
            !r.contains_key("scanner_yaw") && !r.contains_key("wheel_base"),
            "{text}"
        );
        assert!(
            text.contains("mirrored scanner or swapped wheels"),
            "{text}"
        );
    }
}
