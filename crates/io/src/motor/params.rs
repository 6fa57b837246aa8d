//! Settings of the wheel-base link (`[motor]` table of the config file).

use serde::{Deserialize, Serialize};

use crate::param_check::{invalid, ParamError};

/// Which wheel-base protocol the daemon speaks.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum BaseKind {
    /// Basicmicro RoboClaw, packet serial (the default).
    #[default]
    Roboclaw,
    /// iRobot Create 2 / Roomba Open Interface.
    Create2,
}

impl BaseKind {
    /// The device's name for people: "RoboClaw" or "Create 2".
    pub fn name(self) -> &'static str {
        match self {
            BaseKind::Roboclaw => "RoboClaw",
            BaseKind::Create2 => "Create 2",
        }
    }
}

impl std::str::FromStr for BaseKind {
    type Err = String;

    /// Parses `roboclaw` or `create2` (as on the `sweepline emulate` command line).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "roboclaw" => Ok(BaseKind::Roboclaw),
            "create2" | "create" | "roomba" => Ok(BaseKind::Create2),
            other => Err(format!(
                "unknown wheel base `{other}`: expected `roboclaw` or `create2`"
            )),
        }
    }
}

/// Wheel-base link settings.
/// Loaded from the `[motor]` table of the config file; every field is documented
/// in `hw/robot.toml`.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct MotorParams {
    /// Protocol: `roboclaw` or `create2`.
    pub kind: BaseKind,
    /// Serial device path (a udev symlink, a tty, or an emulator's pty link).
    pub device: String,
    /// Bit rate (ignored by USB-CDC devices and ptys).
    pub baud: u32,
    /// Dead-man time (s): wheels stop when no fresh command arrives within it.
    pub deadman: f64,
    /// Time the link may stay silent or garbled before it is declared lost (s).
    pub link_timeout: f64,
    /// Pause between attempts to re-open a lost port (s).
    pub reconnect_interval: f64,
    /// Fastest plausible wheel speed (m/s): commands are clamped to it and
    /// encoder jumps beyond it are rejected as glitches.
    pub max_wheel_speed: f64,
    /// RoboClaw settings.
    pub roboclaw: RoboClawParams,
    /// Create 2 settings.
    pub create2: Create2Params,
}

impl Default for MotorParams {
    fn default() -> Self {
        Self {
            kind: BaseKind::Roboclaw,
            device: "/dev/sweepline-base".into(),
            baud: 115_200,
            deadman: 0.25,
            link_timeout: 0.3,
            reconnect_interval: 0.5,
            max_wheel_speed: 0.5,
            roboclaw: RoboClawParams::default(),
            create2: Create2Params::default(),
        }
    }
}

/// RoboClaw packet-serial settings.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct RoboClawParams {
    /// Packet-serial address, 128..=135.
    pub address: u8,
    /// Encoder counts per wheel revolution (quadrature counts, after gearing).
    pub counts_per_rev: f64,
    /// Controller-side serial timeout (s, 0.1 s steps, up to 25.5): the
    /// controller stops both motors by itself when no valid packet arrives.
    pub serial_timeout: f64,
    /// How long to wait for a reply (s); the controller answers within ~10 ms.
    pub reply_timeout: f64,
    /// Extra attempts for a request that got no valid reply.
    pub retries: u32,
    /// Whether motor 1 drives the left wheel (else the right one).
    pub m1_is_left: bool,
    /// Wheel acceleration the controller ramps set-points at (m/s², command
    /// 40); 0 sends plain set-points (command 37). Safety stops are always
    /// immediate.
    pub accel: f64,
}

impl Default for RoboClawParams {
    fn default() -> Self {
        Self {
            address: 0x80,
            counts_per_rev: 1024.0,
            serial_timeout: 0.5,
            reply_timeout: 0.02,
            retries: 2,
            m1_is_left: true,
            accel: 1.0,
        }
    }
}

/// Create 2 Open Interface settings.
#[derive(Clone, Debug, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct Create2Params {
    /// Run in Full mode (no robot-side cliff/wheel-drop reflexes) instead of Safe.
    pub(crate) full_mode: bool,
    /// Encoder counts per wheel revolution (508.8 on the Create 2).
    pub counts_per_rev: f64,
}

impl Default for Create2Params {
    fn default() -> Self {
        Self {
            full_mode: false,
            counts_per_rev: 508.8,
        }
    }
}

impl MotorParams {
    /// Checks value ranges the types cannot express.
    pub fn validate(&self) -> Result<(), ParamError> {
        if self.device.is_empty() {
            return Err(invalid("motor.device", "must name a device path"));
        }
        crate::check_keys!(
            self,
            "motor",
            positive: [deadman, link_timeout, reconnect_interval, max_wheel_speed],
        );
        let r = &self.roboclaw;
        if !(0x80..=0x87).contains(&r.address) {
            return Err(invalid(
                "motor.roboclaw.address",
                &format!("must be 128..=135, got {}", r.address),
            ));
        }
        crate::check_keys!(r, "motor.roboclaw", positive: [counts_per_rev, reply_timeout]);
        if !(r.serial_timeout.is_finite() && (0.1..=25.5).contains(&r.serial_timeout)) {
            return Err(invalid(
                "motor.roboclaw.serial_timeout",
                &format!("must be 0.1..=25.5 s, got {}", r.serial_timeout),
            ));
        }
        crate::check_keys!(r, "motor.roboclaw", non_negative: [accel]);
        crate::check_keys!(self.create2, "motor.create2", positive: [counts_per_rev]);
        Ok(())
    }

    /// The RoboClaw serial-timeout byte (100 ms units).
    pub(crate) fn roboclaw_timeout_tenths(&self) -> u8 {
        (self.roboclaw.serial_timeout * 10.0)
            .round()
            .clamp(1.0, 255.0) as u8
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid() {
        MotorParams::default().validate().unwrap();
        assert_eq!(MotorParams::default().roboclaw_timeout_tenths(), 5);
    }

    #[test]
    fn bad_values_are_named() {
        let mut p = MotorParams::default();
        p.roboclaw.address = 0x10;
        assert!(p
            .validate()
            .unwrap_err()
            .to_string()
            .contains("motor.roboclaw.address"));
        let p = MotorParams {
            deadman: 0.0,
            ..MotorParams::default()
        };
        assert!(p
            .validate()
            .unwrap_err()
            .to_string()
            .contains("motor.deadman"));
        let mut p = MotorParams::default();
        p.roboclaw.serial_timeout = 30.0;
        assert!(p
            .validate()
            .unwrap_err()
            .to_string()
            .contains("serial_timeout"));
        let mut p = MotorParams::default();
        p.roboclaw.accel = -1.0;
        let e = p.validate().unwrap_err().to_string();
        assert!(e.contains("motor.roboclaw.accel"), "{e}");
    }

    #[test]
    fn kind_parses_from_toml() {
        let p: MotorParams =
            toml::from_str("kind = \"create2\"\n[create2]\nfull_mode = true\n").unwrap();
        assert_eq!(p.kind, BaseKind::Create2);
        assert!(p.create2.full_mode);
        assert!(toml::from_str::<MotorParams>("kind = \"kobuki\"\n").is_err());
        assert_eq!("Create2".parse::<BaseKind>(), Ok(BaseKind::Create2));
        assert_eq!("roboclaw".parse::<BaseKind>(), Ok(BaseKind::Roboclaw));
        assert!("kobuki".parse::<BaseKind>().unwrap_err().contains("kobuki"));
    }
}
