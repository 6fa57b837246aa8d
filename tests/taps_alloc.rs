//! The recorder's copies cost the scan path no allocation: the scanner
//! stage's copy of a scan (the message and the sensor's raw values) moves
//! through a tap edge into preallocated slots, and the telemetry thread
//! turns it into its record reusing the record's buffers. Proven with the
//! counting allocator of `alloc_support` (this thread's allocations only).

mod alloc_support;

use alloc_support::{count_allocs, Counting};
use sweepline::daemon::taps::{ScanRecord, SensorScan};
use sweepline::pipeline::{queue, Overflow, Recv};
use sweepline::scip::Reading;
use sweepline::urg::UrgScan;

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn copying_a_scan_onto_a_tap_and_recording_it_allocate_nothing() {
    // A full URG-04LX scan: 682 beams, a few of them error codes.
    let n = 682;
    let record = ScanRecord {
        stamp: 12.5,
        seq: 7,
        odom: [1.0, 2.0, 0.3],
        interval: 0.1,
        angles: (0..n).map(|i| -2.08 + i as f64 * 0.006_135_923).collect(),
        ranges: (0..n).map(|i| 0.5 + (i % 97) as f64 * 0.031).collect(),
        intensities: vec![0.0; n],
        invalid: vec![3, 400],
        raw: (0..n as u32).collect(),
        ..Default::default()
    };
    let tap = record.to_tap().unwrap();
    let mut urg = UrgScan::default();
    for i in 0..n as u32 {
        urg.readings.push(Reading::Range(500 + i)).unwrap();
    }
    let (tx, rx) = queue("tap_scans", 32, Overflow::RejectNewest);
    let mut out = ScanRecord::default();
    // One copy: the scanner stage's side, then the telemetry thread's.
    let mut copy = || {
        let _ = tx.send(sweepline::daemon::TapScan {
            msg: tap.msg.clone(),
            sensor: SensorScan::of(&urg),
        });
        if let Recv::Msg(t) = rx.try_recv() {
            out.fill_from(&t);
        }
    };
    // Warm-up: the record's buffers grow to a scan's size once.
    for _ in 0..3 {
        copy();
    }
    let ((), allocs) = count_allocs(|| {
        for _ in 0..200 {
            copy();
        }
    });
    assert_eq!(allocs, 0, "allocations in 200 copies");
    assert_eq!(out.ranges, record.ranges);
    assert_eq!(out.invalid, record.invalid);
    assert_eq!(out.raw.len(), n);
}
