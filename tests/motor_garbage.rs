//! Drivers fed pure noise: whatever bytes the "device" sends, the drivers
//! neither panic nor produce wild odometry, and count what they rejected.

use std::io::{self, Write};
use std::os::unix::net::UnixStream;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sweepline::clock::{MonotonicClock, SharedClock};
use sweepline::config::Config;
use sweepline::motor::link::{ByteLink, LinkOpener};
use sweepline::motor::{base_driver, BaseKind, DiffDriveBase, WheelSpeeds};

/// Hands out one end of a socket pair once.
struct Once(Mutex<Option<UnixStream>>);

impl LinkOpener for Once {
    fn open(&mut self, read_timeout: Duration) -> io::Result<Box<dyn ByteLink>> {
        let s = self
            .0
            .lock()
            .unwrap()
            .take()
            .ok_or_else(|| io::Error::new(io::ErrorKind::NotFound, "gone"))?;
        s.set_read_timeout(Some(read_timeout))?;
        Ok(Box::new(s))
    }
    fn describe(&self) -> String {
        "noise socket".into()
    }
}

#[test]
fn noise_never_panics_nor_fakes_a_link() {
    for (kind, seed) in [(BaseKind::Roboclaw, 1u64), (BaseKind::Create2, 2)] {
        let (host, mut dev) = UnixStream::pair().unwrap();
        let stop = Arc::new(AtomicBool::new(false));
        let st = stop.clone();
        let noise = std::thread::spawn(move || {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let mut buf = [0u8; 64];
            while !st.load(Ordering::SeqCst) {
                rng.fill(&mut buf[..]);
                // Sprinkle in the bytes that start frames, to exercise resync.
                buf[rng.random_range(0..64)] = 19;
                buf[rng.random_range(0..64)] = 0xFF;
                if dev.write_all(&buf).is_err() {
                    break;
                }
                std::thread::sleep(Duration::from_millis(2));
            }
        });
        let clock: SharedClock = Arc::new(MonotonicClock::new());
        let cfg = Config::default();
        let opener = Box::new(Once(Mutex::new(Some(host))));
        let mut base: Box<dyn DiffDriveBase> =
            base_driver(kind, &cfg.motor, &cfg.robot, opener, clock.clone());
        let mut travel = 0.0;
        let ahead = WheelSpeeds {
            left: 0.1,
            right: 0.1,
        };
        for _ in 0..40 {
            let now = clock.now();
            base.set_wheels(ahead, now).unwrap();
            let fb = base.poll(now).unwrap();
            if let Some(o) = fb.odometry {
                travel += o.delta.translation.vector.norm();
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        let h = base.health();
        stop.store(true, Ordering::SeqCst);
        drop(base);
        noise.join().unwrap();
        // Noise may by chance pass an 8-bit checksum (Create 2) now and then,
        // but the plausibility filter keeps odometry from jumping.
        assert!(
            travel < 0.5,
            "{kind:?}: noise produced {travel} m of odometry"
        );
        // ...and the noise was seen for what it is.
        assert!(
            h.checksum_errors + h.nacks + h.discarded_bytes > 0,
            "{kind:?}: {h:?}"
        );
    }
}
