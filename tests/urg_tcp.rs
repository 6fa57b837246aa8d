//! The same driver over TCP (Ethernet models): a UTM-30LX emulated on a
//! loopback socket, opened with `TcpConnector`; streaming, then a pulled
//! cable (the emulator drops the connection and reboots) and a reconnect.

mod urg_support;

use std::sync::Arc;
use std::time::Duration;

use sweepline::serial::TcpConnector;
use sweepline::sim::urg_emu::{Emulator, EmulatorConfig, Model, RectRoom};
use sweepline::urg::{ScaledClock, UrgDriver};
use urg_support::*;

#[test]
fn utm_over_tcp_streams_and_reconnects_after_a_pulled_cable() {
    let clock = Arc::new(ScaledClock::new(2.0));
    let cfg = EmulatorConfig {
        model: Model::Utm30lx,
        faults: "unplug=30:0.3".parse().unwrap(),
        ..EmulatorConfig::default()
    };
    let (emu, addr) = Emulator::spawn_tcp(
        cfg,
        Box::new(RectRoom::bench(4)),
        clock.clone(),
        "127.0.0.1:0".parse().unwrap(),
    )
    .unwrap();
    let conn = TcpConnector {
        addr,
        connect_timeout: Duration::from_millis(500),
    };
    let driver = UrgDriver::start(Box::new(conn), test_params(), clock).unwrap();
    let mut got = Vec::new();
    while got.len() < 50 {
        got.push(
            driver
                .scans()
                .recv_timeout(Duration::from_secs(10))
                .expect("scan"),
        );
    }
    let h = driver.health().snapshot();
    driver.shutdown();
    let log = emu.log();
    drop(emu);
    assert_eq!(got[0].scan.beams.len(), 1081);
    assert!(log.unplugs >= 1);
    assert!(h.reconnects >= 1, "{h}");
    check_no_loss(&log, &got);
}
