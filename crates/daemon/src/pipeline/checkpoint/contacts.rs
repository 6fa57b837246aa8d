//! Bumper contact marks as checkpoint section `daemon.contacts`: the marks
//! are written into the map grid only while a run lasts, and later rays
//! could clear them there, so a resumed run needs the list itself to keep
//! them occupied.
//!
//! Payload, version 1 (little-endian): the number of marks (u32, at most
//! [`MAX_CONTACTS`]), then per mark the robot centre (x, y), the contact
//! point (x, y) and the half length of the marked arc, all f64 in metres,
//! map frame.
//!
//! Section `daemon.contacts_tried` ([`TriedPlaces`]), version 1: where marks
//! were taken out to try the floor they walled off, so that a resumed run
//! does not try one place again. Payload: the number of places (u32, at
//! most [`MAX_CONTACTS`]), then per place (x, y), f64 in metres, map frame.

use nalgebra::Point2;

use super::{CheckpointError, Decoder, Encoder, Section};
use crate::daemon::contact::ContactMark;

/// Most marks a checkpoint may hold (a run bumps a few dozen times at most).
pub const MAX_CONTACTS: u32 = 4096;
/// Longest half arc accepted (m).
pub const MAX_HALF_LENGTH: f64 = 0.5;
/// Farthest a contact point may lie from the robot centre (m).
pub const MAX_REACH: f64 = 2.0;
/// Bytes one mark takes.
const MARK_BYTES: usize = 5 * 8;
/// Bytes one tried place takes.
const PLACE_BYTES: usize = 2 * 8;

/// Reads a record count: at most [`MAX_CONTACTS`] records of `each` bytes,
/// all present (a count beyond the bytes allocates nothing).
fn count(d: &mut Decoder<'_>, what: &str, each: usize) -> Result<u32, CheckpointError> {
    let n = d.u32()?;
    if n > MAX_CONTACTS {
        return Err(d.error(format!("{n} {what}, more than {MAX_CONTACTS}")));
    }
    if d.remaining() < n as usize * each {
        return Err(d.error(format!(
            "{n} {what} need {} bytes, {} remain",
            n as usize * each,
            d.remaining()
        )));
    }
    Ok(n)
}

/// One contact mark: an arc of the body shell around `at`, centred on the
/// robot centre `centre`.
#[derive(Clone, Copy, Debug, PartialEq)]
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
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ContactArcs {
    /// The marks, oldest first.
    pub arcs: Vec<ContactArc>,
}

impl Section for ContactArcs {
    const NAME: &'static str = "daemon.contacts";
    const VERSION: u16 = 1;

    fn encode(&self, e: &mut Encoder) {
        let n = self.arcs.len().min(MAX_CONTACTS as usize);
        e.u32(n as u32);
        for a in &self.arcs[..n] {
            e.f64(a.centre.x);
            e.f64(a.centre.y);
            e.f64(a.at.x);
            e.f64(a.at.y);
            e.f64(a.half_length);
        }
    }

    fn decode(d: &mut Decoder<'_>) -> Result<Self, CheckpointError> {
        let n = count(d, "contact marks", MARK_BYTES)?;
        let mut arcs = Vec::with_capacity(n as usize);
        for i in 0..n {
            let centre = Point2::new(d.finite("centre x")?, d.finite("centre y")?);
            let at = Point2::new(d.finite("contact x")?, d.finite("contact y")?);
            let half_length = d.finite("arc half length")?;
            if !(half_length > 0.0 && half_length <= MAX_HALF_LENGTH) {
                return Err(d.error(format!(
                    "mark #{i}: arc half length {half_length} m is outside (0, {MAX_HALF_LENGTH}]"
                )));
            }
            let reach = (at - centre).norm();
            if !(reach > 0.0 && reach <= MAX_REACH) {
                return Err(d.error(format!(
                    "mark #{i}: contact {reach} m from the robot centre, outside (0, {MAX_REACH}]"
                )));
            }
            arcs.push(ContactArc {
                centre,
                at,
                half_length,
            });
        }
        Ok(Self { arcs })
    }
}

/// Where contact marks were taken out to try the floor behind them (the
/// plan stage's [`crate::daemon::stages::MarkProbe`]): a mark near one of
/// these places stays, so an obstacle costs at most one more bump, across a
/// restart too.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriedPlaces {
    /// The places (map frame, m), oldest first.
    pub places: Vec<Point2<f64>>,
}

impl Section for TriedPlaces {
    const NAME: &'static str = "daemon.contacts_tried";
    const VERSION: u16 = 1;

    fn encode(&self, e: &mut Encoder) {
        let n = self.places.len().min(MAX_CONTACTS as usize);
        e.u32(n as u32);
        for p in &self.places[..n] {
            e.f64(p.x);
            e.f64(p.y);
        }
    }

    fn decode(d: &mut Decoder<'_>) -> Result<Self, CheckpointError> {
        let n = count(d, "tried places", PLACE_BYTES)?;
        let mut places = Vec::with_capacity(n as usize);
        for _ in 0..n {
            places.push(Point2::new(d.finite("place x")?, d.finite("place y")?));
        }
        Ok(Self { places })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
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
        let mut e = Encoder::new();
        tried.encode(&mut e);
        let bytes = e.into_bytes();
        for cut in [0, 3, 4, 12, bytes.len() - 1] {
            let mut d = Decoder::new(TriedPlaces::NAME, &bytes[..cut]);
            assert!(TriedPlaces::decode(&mut d).is_err(), "cut at {cut}");
        }
        let mut e = Encoder::new();
        e.u32(MAX_CONTACTS + 1);
        let b = e.into_bytes();
        let err = TriedPlaces::decode(&mut Decoder::new(TriedPlaces::NAME, &b)).unwrap_err();
        assert!(err.to_string().contains("more than"), "{err}");
        let mut e = Encoder::new();
        e.u32(1);
        e.f64(f64::INFINITY);
        e.f64(0.0);
        let b = e.into_bytes();
        let err = TriedPlaces::decode(&mut Decoder::new(TriedPlaces::NAME, &b)).unwrap_err();
        assert!(err.to_string().contains("place x"), "{err}");
        assert!(err.to_string().contains("daemon.contacts_tried"), "{err}");
    }

    #[test]
    fn bad_records_are_clear_errors() {
        let mut e = Encoder::new();
        marks().encode(&mut e);
        let bytes = e.into_bytes();
        for cut in [0, 3, 4, 20, bytes.len() - 1] {
            let mut d = Decoder::new(ContactArcs::NAME, &bytes[..cut]);
            assert!(ContactArcs::decode(&mut d).is_err(), "cut at {cut}");
        }
        // A count far beyond the bytes present allocates nothing.
        let mut e = Encoder::new();
        e.u32(MAX_CONTACTS);
        let b = e.into_bytes();
        let err = ContactArcs::decode(&mut Decoder::new(ContactArcs::NAME, &b)).unwrap_err();
        assert!(err.to_string().contains("remain"), "{err}");
        let mut e = Encoder::new();
        e.u32(u32::MAX);
        let b = e.into_bytes();
        let err = ContactArcs::decode(&mut Decoder::new(ContactArcs::NAME, &b)).unwrap_err();
        assert!(err.to_string().contains("more than"), "{err}");
        for (field, value, want) in [
            (4, 9.0, "half length"),
            (4, 0.0, "half length"),
            (2, 50.0, "from the robot centre"),
            (0, f64::NAN, "centre x"),
        ] {
            let mut e = Encoder::new();
            e.u32(1);
            let mut v = [1.0, 2.0, 1.18, 2.0, 0.02];
            v[field] = value;
            for x in v {
                e.f64(x);
            }
            let b = e.into_bytes();
            let err = ContactArcs::decode(&mut Decoder::new(ContactArcs::NAME, &b)).unwrap_err();
            assert!(err.to_string().contains(want), "{want}: {err}");
            assert!(err.to_string().contains("daemon.contacts"), "{err}");
        }
    }
}
