//! Pipeline edges: bounded `crossbeam-channel` queues, each with a declared
//! overflow policy and counters the supervisor reads.
//!
//! * [`latest`]: the newest-wins hand-over (`Latest<T>`): capacity 1; a send
//!   onto a full slot drops the stale message and counts it. For pose → plan,
//!   plan → control, control → motor: only the newest value matters.
//! * [`queue`] with [`Overflow::DropOldest`]: a short queue that keeps the
//!   newest `n` messages, counting each drop (scanner → localise: a drop is a
//!   lost scan, so it must show in the report).
//! * [`queue`] with [`Overflow::RejectNewest`]: the incoming message is
//!   dropped and counted when full (producers that must not disturb a backlog).
//! * [`queue`] with [`Overflow::Block`]: the producer waits for room (only off
//!   the real-time path, e.g. writing logs).
//!
//! Newest-wins uses crossbeam's bounded channel with the producer holding a
//! receiver clone: on `Full` it takes the oldest message out and retries
//! (race-free for one producer; with several it retries a bounded number of
//! times). Nothing here allocates after construction, and no lock is taken.

use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Duration;

use crossbeam_channel::{bounded, RecvTimeoutError, SendTimeoutError, TryRecvError, TrySendError};
use serde::{Deserialize, Serialize};

/// What a producer does when the edge is full.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Overflow {
    /// Drop the oldest queued message (counted) and enqueue the new one.
    DropOldest,
    /// Drop the incoming message (counted); the queue keeps its backlog.
    RejectNewest,
    /// Wait until the consumer makes room (never on the real-time path).
    Block,
}

impl std::fmt::Display for Overflow {
    /// The policy in plain words, as reports show it.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Overflow::DropOldest => "newest wins",
            Overflow::RejectNewest => "oldest kept",
            Overflow::Block => "waits",
        })
    }
}

/// Counters of one edge, shared by both ends and the supervisor.
#[derive(Debug)]
pub struct EdgeStats {
    name: String,
    capacity: usize,
    policy: Overflow,
    sent: AtomicU64,
    received: AtomicU64,
    dropped: AtomicU64,
    max_depth: AtomicUsize,
    consumer_alive: AtomicBool,
}

impl EdgeStats {
    fn new(name: &str, capacity: usize, policy: Overflow) -> Self {
        Self {
            name: name.to_string(),
            capacity,
            policy,
            sent: AtomicU64::new(0),
            received: AtomicU64::new(0),
            dropped: AtomicU64::new(0),
            max_depth: AtomicUsize::new(0),
            consumer_alive: AtomicBool::new(true),
        }
    }

    /// The edge's name, e.g. `scan`.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Capacity in messages.
    pub fn capacity(&self) -> usize {
        self.capacity
    }

    /// Declared overflow policy.
    pub fn policy(&self) -> Overflow {
        self.policy
    }

    /// Messages accepted onto the edge.
    pub fn sent(&self) -> u64 {
        self.sent.load(Ordering::Relaxed)
    }

    /// Messages the consumer took.
    pub fn received(&self) -> u64 {
        self.received.load(Ordering::Relaxed)
    }

    /// Messages dropped by the overflow policy.
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }

    /// Deepest the queue has been right after a send.
    pub fn max_depth(&self) -> usize {
        self.max_depth.load(Ordering::Relaxed)
    }
}

/// Why a send failed: the consumer is gone. Carries the message back.
#[derive(Debug, PartialEq, Eq)]
pub struct Closed<T>(pub T);

impl<T> std::fmt::Display for Closed<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("the receiving stage has stopped")
    }
}

impl<T: std::fmt::Debug> std::error::Error for Closed<T> {}

/// What a send did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Sent {
    /// Enqueued without dropping anything.
    Clean,
    /// Enqueued after dropping the oldest message.
    DroppedOldest,
    /// The new message itself was dropped (queue full, `RejectNewest`).
    Rejected,
}

/// The producing end of an edge.
#[derive(Debug)]
pub struct Tx<T> {
    tx: crossbeam_channel::Sender<T>,
    drain: crossbeam_channel::Receiver<T>,
    stats: Arc<EdgeStats>,
}

impl<T> Clone for Tx<T> {
    fn clone(&self) -> Self {
        Self {
            tx: self.tx.clone(),
            drain: self.drain.clone(),
            stats: Arc::clone(&self.stats),
        }
    }
}

/// The consuming end of an edge.
#[derive(Debug)]
pub struct Rx<T> {
    rx: crossbeam_channel::Receiver<T>,
    stats: Arc<EdgeStats>,
}

/// A newest-wins edge (`Latest<T>`): capacity 1, a send replaces a message the
/// consumer has not taken yet, and the replaced message is counted as dropped.
pub fn latest<T>(name: &str) -> (Tx<T>, Rx<T>) {
    queue(name, 1, Overflow::DropOldest)
}

/// A bounded queue of `capacity` messages (at least 1) with the given overflow policy.
pub fn queue<T>(name: &str, capacity: usize, policy: Overflow) -> (Tx<T>, Rx<T>) {
    let capacity = capacity.max(1);
    let (tx, rx) = bounded(capacity);
    let stats = Arc::new(EdgeStats::new(name, capacity, policy));
    (
        Tx {
            tx,
            drain: rx.clone(),
            stats: Arc::clone(&stats),
        },
        Rx { rx, stats },
    )
}

/// How many times a newest-wins send retries against concurrent producers.
const SEND_RETRIES: usize = 8;

/// How often a blocked send re-checks that the consumer still exists.
const BLOCK_RECHECK: Duration = Duration::from_millis(50);

impl<T> Tx<T> {
    /// Sends `msg` under the edge's policy. Never blocks unless the policy is
    /// [`Overflow::Block`]. Fails only when the consumer has gone.
    pub fn send(&self, msg: T) -> Result<Sent, Closed<T>> {
        // The producer holds a receiver clone (to drain stale messages), so
        // crossbeam cannot see the consumer go: the consumer's drop flags it.
        if !self.stats.consumer_alive.load(Ordering::Acquire) {
            return Err(Closed(msg));
        }
        let outcome = match self.stats.policy {
            Overflow::Block => self.send_blocking(msg)?,
            Overflow::RejectNewest => match self.tx.try_send(msg) {
                Ok(()) => Sent::Clean,
                Err(TrySendError::Full(_)) => {
                    self.stats.dropped.fetch_add(1, Ordering::Relaxed);
                    return Ok(Sent::Rejected);
                }
                Err(TrySendError::Disconnected(m)) => return Err(Closed(m)),
            },
            Overflow::DropOldest => self.send_newest(msg)?,
        };
        self.stats.sent.fetch_add(1, Ordering::Relaxed);
        self.stats
            .max_depth
            .fetch_max(self.tx.len(), Ordering::Relaxed);
        Ok(outcome)
    }

    fn send_blocking(&self, mut msg: T) -> Result<Sent, Closed<T>> {
        loop {
            match self.tx.send_timeout(msg, BLOCK_RECHECK) {
                Ok(()) => return Ok(Sent::Clean),
                Err(SendTimeoutError::Disconnected(m)) => return Err(Closed(m)),
                Err(SendTimeoutError::Timeout(m)) => {
                    if !self.stats.consumer_alive.load(Ordering::Acquire) {
                        return Err(Closed(m));
                    }
                    msg = m;
                }
            }
        }
    }

    fn send_newest(&self, mut msg: T) -> Result<Sent, Closed<T>> {
        let mut dropped_any = false;
        for _ in 0..SEND_RETRIES {
            match self.tx.try_send(msg) {
                Ok(()) => {
                    return Ok(if dropped_any {
                        Sent::DroppedOldest
                    } else {
                        Sent::Clean
                    })
                }
                Err(TrySendError::Disconnected(m)) => return Err(Closed(m)),
                Err(TrySendError::Full(m)) => {
                    msg = m;
                    if self.drain.try_recv().is_ok() {
                        self.stats.dropped.fetch_add(1, Ordering::Relaxed);
                        dropped_any = true;
                    }
                }
            }
        }
        // Other producers kept refilling the slot: the message we hold is as
        // new as theirs, so dropping it keeps newest-wins semantics.
        self.stats.dropped.fetch_add(1, Ordering::Relaxed);
        Ok(Sent::Rejected)
    }

    /// Messages currently queued.
    pub fn depth(&self) -> usize {
        self.tx.len()
    }

    /// The edge's counters.
    pub fn stats(&self) -> &Arc<EdgeStats> {
        &self.stats
    }

    /// A function returning the current queue depth, for the supervisor. It
    /// holds a receiver clone, so it never keeps the consumer's end open.
    pub(crate) fn depth_probe(&self) -> impl Fn() -> usize + Send + 'static
    where
        T: Send + 'static,
    {
        let rx = self.drain.clone();
        move || rx.len()
    }
}

/// What a receive got.
#[derive(Debug, PartialEq, Eq)]
pub enum Recv<T> {
    /// A message.
    Msg(T),
    /// Nothing arrived within the timeout (or nothing queued, for `try_recv`).
    Empty,
    /// Every producer has gone and the queue is empty.
    Closed,
}

impl<T> Rx<T> {
    /// Waits at most `timeout` for a message.
    pub fn recv_timeout(&self, timeout: Duration) -> Recv<T> {
        match self.rx.recv_timeout(timeout) {
            Ok(m) => self.took(m),
            Err(RecvTimeoutError::Timeout) => Recv::Empty,
            Err(RecvTimeoutError::Disconnected) => Recv::Closed,
        }
    }

    /// Takes a message if one is queued.
    pub fn try_recv(&self) -> Recv<T> {
        match self.rx.try_recv() {
            Ok(m) => self.took(m),
            Err(TryRecvError::Empty) => Recv::Empty,
            Err(TryRecvError::Disconnected) => Recv::Closed,
        }
    }

    /// Takes the newest queued message, dropping (and counting) older ones:
    /// for a consumer that only ever wants the latest state.
    pub(crate) fn try_recv_newest(&self) -> Recv<T> {
        let mut last = self.try_recv();
        if !matches!(last, Recv::Msg(_)) {
            return last;
        }
        loop {
            match self.try_recv() {
                Recv::Msg(m) => {
                    self.stats.dropped.fetch_add(1, Ordering::Relaxed);
                    last = Recv::Msg(m);
                }
                _ => return last,
            }
        }
    }

    fn took(&self, m: T) -> Recv<T> {
        self.stats.received.fetch_add(1, Ordering::Relaxed);
        Recv::Msg(m)
    }

    /// Messages currently queued.
    pub fn depth(&self) -> usize {
        self.rx.len()
    }

    /// The underlying receiver, for `crossbeam_channel::select!` over several
    /// inputs. Messages taken through it directly are not counted as received.
    pub fn inner(&self) -> &crossbeam_channel::Receiver<T> {
        &self.rx
    }

    /// The edge's counters.
    pub fn stats(&self) -> &Arc<EdgeStats> {
        &self.stats
    }
}

impl<T> Drop for Rx<T> {
    fn drop(&mut self) {
        self.stats.consumer_alive.store(false, Ordering::Release);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn latest_keeps_only_the_newest() {
        let (tx, rx) = latest::<u32>("pose");
        assert_eq!(tx.send(1), Ok(Sent::Clean));
        assert_eq!(tx.send(2), Ok(Sent::DroppedOldest));
        assert_eq!(tx.send(3), Ok(Sent::DroppedOldest));
        assert_eq!(rx.try_recv(), Recv::Msg(3));
        assert_eq!(rx.try_recv(), Recv::Empty);
        assert_eq!(tx.stats().dropped(), 2);
        assert_eq!(tx.stats().sent(), 3);
        assert_eq!(rx.stats().received(), 1);
        assert_eq!(tx.stats().max_depth(), 1);
    }

    #[test]
    fn drop_oldest_queue_keeps_the_last_n_in_order() {
        let (tx, rx) = queue::<u32>("scan", 3, Overflow::DropOldest);
        for i in 0..10 {
            tx.send(i).unwrap();
        }
        let got: Vec<u32> = std::iter::from_fn(|| match rx.try_recv() {
            Recv::Msg(m) => Some(m),
            _ => None,
        })
        .collect();
        assert_eq!(got, vec![7, 8, 9]);
        assert_eq!(rx.stats().dropped(), 7);
        assert_eq!(rx.stats().max_depth(), 3);
    }

    #[test]
    fn reject_newest_keeps_the_backlog() {
        let (tx, rx) = queue::<u32>("log", 2, Overflow::RejectNewest);
        assert_eq!(tx.send(1), Ok(Sent::Clean));
        assert_eq!(tx.send(2), Ok(Sent::Clean));
        assert_eq!(tx.send(3), Ok(Sent::Rejected));
        assert_eq!(rx.try_recv(), Recv::Msg(1));
        assert_eq!(rx.try_recv(), Recv::Msg(2));
        assert_eq!(rx.stats().dropped(), 1);
    }

    #[test]
    fn closed_ends_are_reported() {
        let (tx, rx) = latest::<u32>("cmd");
        drop(rx);
        assert_eq!(tx.send(5), Err(Closed(5)));
        let (tx, rx) = queue::<u32>("cmd", 1, Overflow::Block);
        tx.send(1).unwrap();
        let (tx2, rx2) = queue::<u32>("blocked", 1, Overflow::Block);
        tx2.send(1).unwrap();
        let t = std::thread::spawn(move || tx2.send(2));
        std::thread::sleep(Duration::from_millis(20));
        drop(rx2);
        assert_eq!(t.join().unwrap(), Err(Closed(2)));
        drop(tx);
        assert_eq!(rx.recv_timeout(Duration::from_millis(1)), Recv::Msg(1));
        assert_eq!(rx.recv_timeout(Duration::from_millis(1)), Recv::Closed);
    }

    #[test]
    fn try_recv_newest_counts_what_it_skips() {
        let (tx, rx) = queue::<u32>("odom", 4, Overflow::DropOldest);
        for i in 0..4 {
            tx.send(i).unwrap();
        }
        assert_eq!(rx.try_recv_newest(), Recv::Msg(3));
        assert_eq!(rx.stats().dropped(), 3);
        assert_eq!(rx.try_recv_newest(), Recv::Empty);
    }
}
