//! The counting global allocator of the allocation tests: it forwards to the
//! system allocator and counts the allocations and reallocations made by a
//! thread while that thread has counting switched on, so the test harness's
//! other threads (and emulator threads) can neither disturb nor hide a
//! measurement. Each test binary installs it itself:
//!
//! ```ignore
//! mod alloc_support;
//! #[global_allocator]
//! static GLOBAL: alloc_support::Counting = alloc_support::Counting;
//! ```
#![allow(dead_code)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

/// The counting allocator (install with `#[global_allocator]`).
pub struct Counting;

thread_local! {
    static ON: Cell<bool> = const { Cell::new(false) };
    static COUNT: Cell<usize> = const { Cell::new(0) };
}

fn note() {
    if ON.try_with(Cell::get).unwrap_or(false) {
        let _ = COUNT.try_with(|c| c.set(c.get() + 1));
    }
}

// SAFETY: forwards every call to the system allocator; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        note();
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        note();
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

/// Switches counting on or off for the calling thread.
pub fn set_counting(on: bool) {
    ON.with(|c| c.set(on));
}

/// Allocations counted on the calling thread so far.
pub fn allocs() -> usize {
    COUNT.with(Cell::get)
}

/// Runs `f` with counting on for the calling thread; returns its result and
/// the allocations it made.
pub fn count_allocs<R>(f: impl FnOnce() -> R) -> (R, usize) {
    let before = allocs();
    set_counting(true);
    let r = f();
    set_counting(false);
    (r, allocs() - before)
}
