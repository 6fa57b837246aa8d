//! The pipeline machinery allocates nothing in steady state: newest-wins and
//! queue hand-over between real threads, the stage runner's per-item
//! bookkeeping (clocks, histograms, counters, degradation, publishing), and
//! end-to-end recording. Proven with a counting global allocator; this binary
//! holds one test so that nothing else allocates meanwhile.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicU64, Ordering};
use std::thread::sleep;
use std::time::Duration;

use sweepline::pipeline::clock::Stamp;
use sweepline::pipeline::{
    latest, queue, Overflow, Pipeline, PipelineParams, Poll, Recv, Rx, Stage, StageCtx, StageFault,
    Tx,
};

struct Counting;

static ALLOCS: AtomicU64 = AtomicU64::new(0);

// SAFETY: forwards to the system allocator; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        ALLOCS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(l) }
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(p, l) }
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, n: usize) -> *mut u8 {
        ALLOCS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(p, l, n) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// A fixed-size message like a scan: no heap inside.
#[derive(Clone, Copy)]
struct Scan {
    t0: Stamp,
    ranges: [u16; 682],
}

struct Source {
    out: Tx<Scan>,
}

impl Stage for Source {
    type Work = ();
    fn wait(&mut self, _timeout: Duration) -> Poll<()> {
        sleep(Duration::from_micros(500));
        Poll::Work(())
    }
    fn process(&mut self, _: (), _ctx: &mut StageCtx<'_>) -> Result<(), StageFault> {
        let s = Scan {
            t0: Stamp::now(),
            ranges: [1000; 682],
        };
        self.out
            .send(s)
            .map(|_| ())
            .map_err(|_| StageFault::Fatal(String::new()))
    }
}

struct Relay {
    input: Rx<Scan>,
    out: Option<Tx<Scan>>,
}

impl Stage for Relay {
    type Work = Scan;
    fn wait(&mut self, timeout: Duration) -> Poll<Scan> {
        match self.input.recv_timeout(timeout) {
            Recv::Msg(m) => Poll::Work(m),
            Recv::Empty => Poll::Idle,
            Recv::Closed => Poll::Done,
        }
    }
    fn process(&mut self, mut m: Scan, ctx: &mut StageCtx<'_>) -> Result<(), StageFault> {
        ctx.note_age(m.t0);
        m.ranges[ctx.degrade() as usize] += 1;
        match &self.out {
            Some(tx) => {
                let _ = tx.send(m);
            }
            None => ctx.end_to_end(m.t0),
        }
        Ok(())
    }
}

#[test]
fn steady_state_hand_over_and_bookkeeping_allocate_nothing() {
    let params = PipelineParams {
        poll_timeout: 0.005,
        // Tiny budgets: every item overruns, so degradation paths run too.
        ..PipelineParams::default()
    };
    let mut p = Pipeline::new(&params);
    let (tx1, rx1) = queue::<Scan>("scan", 4, Overflow::DropOldest);
    let (tx2, rx2) = latest::<Scan>("pose");
    p.register_edge(&tx1);
    p.register_edge(&tx2);
    let ns = Duration::from_nanos(1);
    p.spawn_with_budget("scanner", ns, Source { out: tx1 })
        .unwrap();
    p.spawn_with_budget(
        "localise",
        ns,
        Relay {
            input: rx1,
            out: Some(tx2),
        },
    )
    .unwrap();
    let sink = p
        .spawn_with_budget(
            "motor",
            Duration::from_secs(1),
            Relay {
                input: rx2,
                out: None,
            },
        )
        .unwrap();

    // Warm up: thread-locals, channel wakers, first publish.
    sleep(Duration::from_millis(700));
    let before_items = sink.iterations();
    let before = ALLOCS.load(Ordering::SeqCst);
    sleep(Duration::from_millis(1500));
    let after = ALLOCS.load(Ordering::SeqCst);
    let items = sink.iterations() - before_items;
    let snap = p.stop();
    assert!(
        items >= 50,
        "the pipeline must have been busy: {items} items"
    );
    assert_eq!(
        after - before,
        0,
        "{} allocations while {items} scans went through",
        after - before
    );
    let loc = snap.stages.iter().find(|s| s.name == "localise").unwrap();
    assert!(loc.degrade_raises >= 1, "the degradation path ran");
}
