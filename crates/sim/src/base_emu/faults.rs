//! Fault schedules for an emulated wheel base, written as the scanner
//! emulator's `--faults` are: comma-separated `name=EVERY:AMOUNT`, where
//! EVERY is the period in seconds of emulator clock and AMOUNT is how long
//! (seconds) or how many bytes. `bump=20:0.5,corrupt-out=7:3` closes the
//! bumper for half a second every 20 s and flips a bit in each of three
//! reply bytes every 7 s.

use std::str::FromStr;

use crate::base_emu::Fault;

/// A fault injected periodically.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Periodic {
    /// Seconds of emulator clock between two injections.
    pub every: f64,
    /// What is injected.
    pub fault: Fault,
}

/// A set of periodic faults (empty: none).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FaultPlan {
    /// The faults, in the order given.
    pub faults: Vec<Periodic>,
    next: Vec<f64>,
}

/// The names the plan accepts, for error messages and `--help`.
pub(crate) const NAMES: &str =
    "silence=EVERY:SECS, corrupt-in=EVERY:BYTES, corrupt-out=EVERY:BYTES, bump=EVERY:SECS, wheel-drop=EVERY:SECS, unplug=EVERY:SECS";

impl FromStr for FaultPlan {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let mut faults = Vec::new();
        for item in s.split(',').map(str::trim).filter(|i| !i.is_empty()) {
            faults.push(parse_one(item)?);
        }
        let next = faults.iter().map(|f| f.every).collect();
        Ok(Self { faults, next })
    }
}

fn parse_one(item: &str) -> Result<Periodic, String> {
    let bad = |why: &str| format!("fault `{item}`: {why} (expected one of {NAMES})");
    let (name, value) = item.split_once('=').ok_or_else(|| bad("no `=`"))?;
    let (every, amount) = value
        .split_once(':')
        .ok_or_else(|| bad("no `:` between the period and the amount"))?;
    let every: f64 = every
        .trim()
        .parse()
        .ok()
        .filter(|e: &f64| e.is_finite() && *e > 0.0)
        .ok_or_else(|| bad("the period must be a positive number of seconds"))?;
    let secs = || {
        amount
            .trim()
            .parse::<f64>()
            .ok()
            .filter(|a| a.is_finite() && *a > 0.0)
            .ok_or_else(|| bad("the duration must be a positive number of seconds"))
    };
    let bytes = || {
        amount
            .trim()
            .parse::<u32>()
            .ok()
            .filter(|&b| b > 0)
            .ok_or_else(|| bad("the byte count must be a positive whole number"))
    };
    let fault = match name.trim() {
        "silence" => Fault::Silence { secs: secs()? },
        "corrupt-in" => Fault::CorruptIn { bytes: bytes()? },
        "corrupt-out" => Fault::CorruptOut { bytes: bytes()? },
        "bump" => Fault::Bump { secs: secs()? },
        "wheel-drop" => Fault::WheelDrop { secs: secs()? },
        "unplug" => Fault::Unplug { secs: secs()? },
        _ => return Err(bad("unknown fault")),
    };
    Ok(Periodic { every, fault })
}

/// The timed motion faults `sweepline sim --fault` takes, for `--help`.
pub const MOTION_NAMES: &str = "slip=AT:SECS:LEFT:RIGHT, kidnap=AT:DX:DY:DEG, knock=AT:DEG";

/// One motion fault at a simulated time: `slip=AT:SECS:LEFT:RIGHT` (each
/// wheel covers that share less floor than its encoder counts for SECS),
/// `kidnap=AT:DX:DY:DEG` (the robot put down DX m ahead and DY m to the
/// left, turned DEG), `knock=AT:DEG` (turned in place). Returns the time (s
/// from the start) and the fault.
pub fn parse_motion(item: &str) -> Result<(f64, Fault), String> {
    let bad = |why: &str| format!("fault `{item}`: {why} (expected one of {MOTION_NAMES})");
    let (name, value) = item.split_once('=').ok_or_else(|| bad("no `=`"))?;
    let v: Vec<f64> = value
        .split(':')
        .map(|x| x.trim().parse::<f64>().ok().filter(|x| x.is_finite()))
        .collect::<Option<_>>()
        .ok_or_else(|| bad("every field must be a number"))?;
    let at = *v
        .first()
        .filter(|a| **a >= 0.0)
        .ok_or_else(|| bad("the time must be >= 0 s"))?;
    let share = |x: f64| {
        (0.0..=1.0)
            .contains(&x)
            .then_some(x)
            .ok_or_else(|| bad("a wheel's lost share must be in 0..=1"))
    };
    let fault = match (name.trim(), v.len()) {
        ("slip", 4) if v[1] > 0.0 => Fault::Slip {
            secs: v[1],
            left: share(v[2])?,
            right: share(v[3])?,
        },
        ("kidnap", 4) => Fault::Displace {
            dx: v[1],
            dy: v[2],
            turn: v[3].to_radians(),
        },
        ("knock", 2) => Fault::Displace {
            dx: 0.0,
            dy: 0.0,
            turn: v[1].to_radians(),
        },
        ("slip" | "kidnap" | "knock", _) => return Err(bad("wrong number of fields")),
        _ => return Err(bad("unknown fault")),
    };
    Ok((at, fault))
}

impl FaultPlan {
    /// Whether the plan injects nothing.
    pub fn is_empty(&self) -> bool {
        self.faults.is_empty()
    }

    /// The faults due at clock time `now` (seconds since the emulator
    /// started), each handed to `inject` once per period.
    pub fn due(&mut self, now: f64, mut inject: impl FnMut(Fault)) {
        for (f, next) in self.faults.iter().zip(self.next.iter_mut()) {
            if now >= *next {
                inject(f.fault);
                *next += f.every * ((now - *next) / f.every).floor().max(0.0) + f.every;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_motion_faults_and_refuses_nonsense_naming_it() {
        assert_eq!(
            parse_motion("slip=120:1:0.45:0"),
            Ok((
                120.0,
                Fault::Slip {
                    secs: 1.0,
                    left: 0.45,
                    right: 0.0
                }
            ))
        );
        let (at, f) = parse_motion("kidnap=200:1:0:30").unwrap();
        assert_eq!(at, 200.0);
        assert!(
            matches!(f, Fault::Displace { dx, dy, turn } if dx == 1.0 && dy == 0.0 && (turn - 30f64.to_radians()).abs() < 1e-9)
        );
        assert!(matches!(
            parse_motion("knock=5:-10"),
            Ok((5.0, Fault::Displace { .. }))
        ));
        for bad in [
            "slip=1:1:1.5:0",
            "slip=1:0:0.5:0",
            "kidnap=1:1",
            "knock=-1:10",
            "fly=1:1",
            "knock",
        ] {
            let e = parse_motion(bad).unwrap_err();
            assert!(e.contains(bad) && e.contains("kidnap=AT"), "{e}");
        }
    }

    #[test]
    fn parses_every_fault_and_refuses_nonsense_naming_it() {
        let p: FaultPlan =
            "bump=20:0.5, corrupt-out=7:3,silence=9:1,corrupt-in=4:2,wheel-drop=30:1,unplug=60:2"
                .parse()
                .unwrap();
        assert_eq!(p.faults.len(), 6);
        assert_eq!(
            p.faults[1],
            Periodic {
                every: 7.0,
                fault: Fault::CorruptOut { bytes: 3 }
            }
        );
        assert!("".parse::<FaultPlan>().unwrap().is_empty());
        for bad in [
            "bump",
            "bump=1",
            "bump=-1:1",
            "bump=1:0",
            "corrupt-in=1:0.5",
            "fly=1:1",
        ] {
            let e = bad.parse::<FaultPlan>().unwrap_err();
            assert!(e.contains(bad), "{e}");
        }
    }

    #[test]
    fn each_fault_comes_once_per_period() {
        let mut p: FaultPlan = "bump=2:0.5".parse().unwrap();
        let mut n = 0;
        let mut t = 0.0;
        while t < 10.0 {
            p.due(t, |_| n += 1);
            t += 0.05;
        }
        assert_eq!(n, 4, "at 2, 4, 6 and 8 s");
    }
}
