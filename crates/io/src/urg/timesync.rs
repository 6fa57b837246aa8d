//! Sensor-to-host clock estimation from TM1 round trips, and scan-sequence
//! checks (dropped scans from timestamp gaps, stuck sensor clock).
//!
//! Each TM1 exchange gives a sample: host time when the request left, the
//! sensor's (unwrapped) millisecond clock, host time when the reply arrived.
//! In time-adjust mode the sensor answers at the next edge of its
//! millisecond clock with the value it has just reached (the UXM-30LX-E
//! capture in `../shared/datasets/hokuyo-captures/`: every TM1 reply leaves
//! 0.9-1.0 ms after its request and the values step by one), so the value
//! is exact at the end of the round trip, less the transfer back. Samples
//! with the smallest round trip carry the least transfer and queueing: we
//! keep the better half by round-trip time and fit `sensor = a + b·host`
//! through their arrival times (b = 1 until the samples span long enough
//! to see drift). *Assumed*: the URG-04LX, of which no TM capture exists,
//! answers TM1 the same way.
//! Periodic re-syncs add their best sample to a short history so drift is
//! measured over a long baseline.

use heapless::Deque;

/// One TM1 round trip.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct TimeSample {
    /// Host clock when the request was written (s).
    pub(crate) host_send: f64,
    /// Host clock when the reply was complete (s).
    pub(crate) host_recv: f64,
    /// Sensor clock in the reply (s, unwrapped).
    pub sensor: f64,
}

impl TimeSample {
    /// Round-trip time (s).
    pub fn rtt(&self) -> f64 {
        self.host_recv - self.host_send
    }
}

/// `sensor = sensor0 + rate · (host − host0)`: maps sensor time to host time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClockModel {
    /// Host time of the reference point (s).
    pub(crate) host0: f64,
    /// Sensor time at the reference point (s).
    pub(crate) sensor0: f64,
    /// Sensor seconds per host second (1 = no drift).
    pub rate: f64,
    /// Round-trip time of the best sample (s): the offset's uncertainty bound.
    pub rtt: f64,
}

impl ClockModel {
    /// The host time at which the sensor clock read `sensor` (s).
    pub(crate) fn host_of(&self, sensor: f64) -> f64 {
        self.host0 + (sensor - self.sensor0) / self.rate
    }
    /// Sensor minus host at the reference point (s).
    pub fn offset(&self) -> f64 {
        self.sensor0 - self.host0
    }
    /// Rate error in parts per million.
    pub fn drift_ppm(&self) -> f64 {
        (self.rate - 1.0) * 1e6
    }
}

/// Shortest host span over which a rate is estimated (s); below it b = 1.
pub(crate) const MIN_DRIFT_SPAN: f64 = 5.0;
/// Largest believable rate error (a crystal is within ~100 ppm; beyond
/// 1000 ppm the fit is rejected as noise).
pub(crate) const MAX_DRIFT: f64 = 1e-3;

/// Fits a clock model through the better half (by round trip) of `samples`
/// plus earlier anchors. `None` when there are no usable samples.
pub fn fit(samples: &[TimeSample], anchors: &[TimeSample]) -> Option<ClockModel> {
    let mut best: heapless::Vec<TimeSample, 64> = heapless::Vec::new();
    for s in samples
        .iter()
        .filter(|s| s.rtt() >= 0.0 && s.rtt().is_finite())
    {
        if best.push(*s).is_err() {
            break;
        }
    }
    if best.is_empty() {
        return None;
    }
    best.sort_unstable_by(|a, b| a.rtt().total_cmp(&b.rtt()));
    let keep = best.len().div_ceil(2);
    best.truncate(keep);
    let min_rtt = best[0].rtt();
    // The value was reached at a clock edge, just before the reply left.
    let pts = best
        .iter()
        .chain(anchors.iter())
        .map(|s| (s.host_recv, s.sensor));
    let n = (keep + anchors.len()) as f64;
    let (mut sh, mut ss) = (0.0, 0.0);
    for (h, s) in pts.clone() {
        sh += h;
        ss += s;
    }
    let (mh, ms) = (sh / n, ss / n);
    let (mut hmin, mut hmax) = (f64::INFINITY, f64::NEG_INFINITY);
    let (mut sxx, mut sxy) = (0.0, 0.0);
    for (h, s) in pts {
        hmin = hmin.min(h);
        hmax = hmax.max(h);
        sxx += (h - mh) * (h - mh);
        sxy += (h - mh) * (s - ms);
    }
    let mut rate = 1.0;
    if hmax - hmin >= MIN_DRIFT_SPAN && sxx > 0.0 {
        let r = sxy / sxx;
        if (r - 1.0).abs() <= MAX_DRIFT {
            rate = r;
        }
    }
    Some(ClockModel {
        host0: mh,
        sensor0: ms,
        rate,
        rtt: min_rtt,
    })
}

/// Keeps the best sample of each sync round (up to 8) for drift over a long
/// baseline.
#[derive(Debug, Default)]
pub(crate) struct SyncHistory {
    anchors: Deque<TimeSample, 8>,
}

impl SyncHistory {
    /// Adds one round's samples and returns the model fitted with history.
    pub(crate) fn add_round(&mut self, samples: &[TimeSample]) -> Option<ClockModel> {
        let model = fit(samples, self.anchors.as_slices().0)?;
        let best = samples
            .iter()
            .copied()
            .min_by(|a, b| a.rtt().total_cmp(&b.rtt()))?;
        if self.anchors.is_full() {
            self.anchors.pop_front();
        }
        let _ = self.anchors.push_back(best);
        // Contiguous slice for the next fit.
        self.anchors.make_contiguous();
        Some(model)
    }

    /// Forgets history (the sensor was reset: its clock restarted).
    pub fn clear(&mut self) {
        self.anchors.clear();
    }
}

/// What a new scan timestamp says about the sequence.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Continuity {
    /// The first scan, or exactly one period after the previous.
    Ok,
    /// This many scans are missing before this one.
    Dropped(u64),
    /// Same or earlier timestamp than the previous scan: the clock is stuck.
    Stuck,
}

/// Judges the gap between consecutive unwrapped sensor timestamps (ms)
/// against the expected scan interval (ms).
pub(crate) fn continuity(prev_ms: Option<u64>, now_ms: u64, interval_ms: f64) -> Continuity {
    let Some(prev) = prev_ms else {
        return Continuity::Ok;
    };
    if now_ms <= prev {
        return Continuity::Stuck;
    }
    if interval_ms <= 0.0 {
        return Continuity::Ok;
    }
    let periods = ((now_ms - prev) as f64 / interval_ms).round() as u64;
    if periods >= 2 {
        Continuity::Dropped(periods - 1)
    } else {
        Continuity::Ok
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A TM1 round trip whose reply left at a clock edge `read_at` of the
    /// way through it (the rest is the transfer back).
    fn sample(host: f64, rtt: f64, offset: f64, rate: f64, read_at: f64) -> TimeSample {
        let read = host + rtt * read_at;
        TimeSample {
            host_send: host,
            host_recv: host + rtt,
            sensor: offset + read * rate,
        }
    }

    #[test]
    fn min_rtt_samples_win_over_slow_ones() {
        // Fast round trips come back at once; slow ones spend a long time
        // on the way back (a queued reply).
        let mut v = Vec::new();
        for i in 0..10 {
            let slow = i % 2 == 0;
            let rtt = if slow { 0.050 } else { 0.001 };
            v.push(sample(
                10.0 + i as f64 * 0.01,
                rtt,
                123.4,
                1.0,
                if slow { 0.5 } else { 0.9 },
            ));
        }
        let m = fit(&v, &[]).unwrap();
        assert!((m.offset() - 123.4).abs() < 0.0015, "{}", m.offset());
        assert_eq!(m.rate, 1.0);
        assert!((m.rtt - 0.001).abs() < 1e-9);
        assert!((m.host_of(123.4 + 20.0) - 20.0).abs() < 0.0015);
    }

    #[test]
    fn drift_is_measured_over_a_long_baseline() {
        let mut h = SyncHistory::default();
        let rate = 1.0 + 50e-6;
        for round in 0..4 {
            let t0 = round as f64 * 30.0;
            let v: Vec<_> = (0..6)
                .map(|i| sample(t0 + i as f64 * 0.01, 0.001, 5.0, rate, 0.9))
                .collect();
            h.add_round(&v).unwrap();
        }
        let v: Vec<_> = (0..6)
            .map(|i| sample(120.0 + i as f64 * 0.01, 0.001, 5.0, rate, 0.9))
            .collect();
        let m = h.add_round(&v).unwrap();
        assert!((m.drift_ppm() - 50.0).abs() < 10.0, "{}", m.drift_ppm());
        assert!(fit(&[], &[]).is_none());
    }

    #[test]
    fn gaps_and_stuck_clock() {
        assert_eq!(continuity(None, 5, 100.0), Continuity::Ok);
        assert_eq!(continuity(Some(100), 201, 100.0), Continuity::Ok);
        assert_eq!(continuity(Some(100), 400, 100.0), Continuity::Dropped(2));
        assert_eq!(continuity(Some(100), 100, 100.0), Continuity::Stuck);
        assert_eq!(continuity(Some(100), 90, 100.0), Continuity::Stuck);
    }
}
