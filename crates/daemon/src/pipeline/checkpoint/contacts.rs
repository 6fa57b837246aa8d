//! Bumper contact marks as checkpoint section `daemon.contacts`: the marks
//! are written into the map grid only while a run lasts, and later rays
//! could clear them there, so a resumed run needs the list itself to keep
//! them occupied.
//!
//! Payload, version 1: [`ContactArcs`] in postcard: the number of marks (at
//! most `MAX_CONTACTS`; the oldest are written when there are more), then
//! per mark the robot centre (x, y), the contact point (x, y) and the half
//! length of the marked arc, all f64 in metres, map frame.
//!
//! Section `daemon.contacts_tried` ([`TriedPlaces`]), version 1: where marks
//! were taken out to try the floor they walled off, so that a resumed run
//! does not try one place again. Payload: the number of places (at most
//! `MAX_CONTACTS`), then per place (x, y), f64 in metres, map frame.

use nalgebra::Point2;

use serde::{Deserialize, Serialize, Serializer};

use super::checks::finite;
use super::Section;
use crate::daemon::contact::ContactMark;

/// Most marks a checkpoint may hold (a run bumps a few dozen times at most).
pub(crate) const MAX_CONTACTS: u32 = 4096;
/// Longest half arc accepted (m).
pub(crate) const MAX_HALF_LENGTH: f64 = 0.5;
/// Farthest a contact point may lie from the robot centre (m).
pub(crate) const MAX_REACH: f64 = 2.0;

/// Writes at most the first [`MAX_CONTACTS`] records of `v`, so that a run
/// with more still writes its checkpoints.
fn capped<T: Serialize, S: Serializer>(v: &[T], s: S) -> Result<S::Ok, S::Error> {
    v[..v.len().min(MAX_CONTACTS as usize)].serialize(s)
}

/// A record count checked against [`MAX_CONTACTS`].
fn check_count(n: usize, what: &str) -> Result<(), String> {
    if n > MAX_CONTACTS as usize {
        return Err(format!("{n} {what}, more than {MAX_CONTACTS}"));
    }
    Ok(())
}

/// One contact mark: an arc of the body shell around `at`, centred on the
/// robot centre `centre`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ContactArc {
    /// Robot centre when the bumper closed (map frame, m).
    pub centre: Point2<f64>,
    /// The contact point (map frame, m).
    pub at: Point2<f64>,
    /// Half length of the marked arc (m).
    pub half_length: f64,
}

impl From<ContactArc> for ContactMark {
    fn from(a: ContactArc) -> Self {
        Self {
            centre: a.centre,
            at: a.at,
            half_length: a.half_length,
        }
    }
}

impl From<&ContactMark> for ContactArc {
    fn from(m: &ContactMark) -> Self {
        Self {
            centre: m.centre,
            at: m.at,
            half_length: m.half_length,
        }
    }
}

/// The contact marks of a run.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ContactArcs {
    /// The marks, oldest first.
    #[serde(serialize_with = "capped")]
    pub arcs: Vec<ContactArc>,
}

impl Section for ContactArcs {
    const NAME: &'static str = "daemon.contacts";
    const VERSION: u16 = 1;

    fn restored(self) -> Result<Self, String> {
        check_count(self.arcs.len(), "contact marks")?;
        for (i, a) in self.arcs.iter().enumerate() {
            finite("centre x", a.centre.x)?;
            finite("centre y", a.centre.y)?;
            finite("contact x", a.at.x)?;
            finite("contact y", a.at.y)?;
            let half_length = finite("arc half length", a.half_length)?;
            if !(half_length > 0.0 && half_length <= MAX_HALF_LENGTH) {
                return Err(format!(
                    "mark #{i}: arc half length {half_length} m is outside (0, {MAX_HALF_LENGTH}]"
                ));
            }
            let reach = (a.at - a.centre).norm();
            if !(reach > 0.0 && reach <= MAX_REACH) {
                return Err(format!(
                    "mark #{i}: contact {reach} m from the robot centre, outside (0, {MAX_REACH}]"
                ));
            }
        }
        Ok(self)
    }
}

/// Where contact marks were taken out to try the floor behind them (the
/// plan stage's [`crate::daemon::stages::MarkProbe`]): a mark near one of
/// these places stays, so an obstacle costs at most one more bump, across a
/// restart too.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TriedPlaces {
    /// The places (map frame, m), oldest first.
    #[serde(serialize_with = "capped")]
    pub places: Vec<Point2<f64>>,
}

impl Section for TriedPlaces {
    const NAME: &'static str = "daemon.contacts_tried";
    const VERSION: u16 = 1;

    fn restored(self) -> Result<Self, String> {
        check_count(self.places.len(), "tried places")?;
        for p in &self.places {
            finite("place x", p.x)?;
            finite("place y", p.y)?;
        }
        Ok(self)
    }
}

#[cfg(test)]
mod tests {
    use nalgebra::Point2;

    use super::*;
    use crate::pipeline::checkpoint::testing::{payload, read, refusal, round_trips};
    use crate::pipeline::checkpoint::Checkpoint;

    fn marks() -> ContactArcs {
        ContactArcs {
            arcs: vec![
                ContactArc {
                    centre: Point2::new(1.0, 2.0),
                    at: Point2::new(1.18, 2.0),
                    half_length: 0.02,
                },
                ContactArc {
                    centre: Point2::new(-3.5, 0.25),
                    at: Point2::new(-3.5, 0.07),
                    half_length: 0.04,
                },
            ],
        }
    }

    #[test]
    fn marks_survive_save_and_load() {
        let mut cp = Checkpoint::new();
        cp.put(&marks()).unwrap();
        let back = Checkpoint::from_bytes(&cp.to_bytes()).unwrap();
        assert_eq!(back.require::<ContactArcs>().unwrap(), marks());
        let mut cp = Checkpoint::new();
        cp.put(&ContactArcs::default()).unwrap();
        let back = Checkpoint::from_bytes(&cp.to_bytes()).unwrap();
        assert!(back.require::<ContactArcs>().unwrap().arcs.is_empty());
    }

    #[test]
    fn tried_places_survive_save_and_load_and_bad_ones_are_clear_errors() {
        let tried = TriedPlaces {
            places: vec![Point2::new(1.1, 2.27), Point2::new(-0.5, 3.0)],
        };
        let mut cp = Checkpoint::new();
        cp.put(&marks()).unwrap();
        cp.put(&tried).unwrap();
        let back = Checkpoint::from_bytes(&cp.to_bytes()).unwrap();
        assert_eq!(back.require::<TriedPlaces>().unwrap(), tried);
        assert_eq!(back.require::<ContactArcs>().unwrap(), marks());
        round_trips(&tried);
        let many = TriedPlaces {
            places: vec![Point2::new(0.0, 0.0); MAX_CONTACTS as usize + 1],
        };
        assert_eq!(
            read::<TriedPlaces>(&payload(&many)).unwrap().places.len(),
            MAX_CONTACTS as usize,
            "the oldest are written"
        );
        let inf = TriedPlaces {
            places: vec![Point2::new(f64::INFINITY, 0.0)],
        };
        let err = refusal(&inf);
        assert!(err.contains("place x"), "{err}");
        assert!(err.contains("daemon.contacts_tried"), "{err}");
    }

    #[test]
    fn bad_records_are_clear_errors() {
        round_trips(&marks());
        // A count far beyond the bytes present allocates nothing.
        assert!(read::<ContactArcs>(&[0x80, 0x20]).is_err());
        let too_many = [&[0x81, 0x20][..], &[0; 40 * 4097]].concat();
        let err = read::<ContactArcs>(&too_many).unwrap_err().to_string();
        assert!(err.contains("more than"), "{err}");
        for (field, value, want) in [
            (4, 9.0, "half length"),
            (4, 0.0, "half length"),
            (2, 50.0, "from the robot centre"),
            (0, f64::NAN, "centre x"),
        ] {
            let mut v = [1.0, 2.0, 1.18, 2.0, 0.02];
            v[field] = value;
            let bad = ContactArcs {
                arcs: vec![ContactArc {
                    centre: Point2::new(v[0], v[1]),
                    at: Point2::new(v[2], v[3]),
                    half_length: v[4],
                }],
            };
            let err = refusal(&bad);
            assert!(err.contains(want), "{want}: {err}");
            assert!(err.contains("daemon.contacts"), "{err}");
        }
    }
}
