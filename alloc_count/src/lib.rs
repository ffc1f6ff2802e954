//! A counting global allocator, shared by every no-allocation test and the memory figures of
//! the benches. A test binary installs it with
//!
//! ```ignore
//! #[global_allocator]
//! static ALLOC: alloc_count::Counting = alloc_count::Counting;
//! ```
//!
//! Allocations are counted **per thread**: a test asks how many allocations *its own* thread
//! made ([`allocations`]), so the test harness or any other thread allocating meanwhile cannot
//! change the result (a process-wide counter made the no-allocation tests flaky on a loaded
//! machine). Live and peak bytes ([`live_bytes`], [`mark_peak`], [`peak_bytes`]) are
//! process-wide, for the benches' memory figures (a pass may use several threads; bytes freed on
//! another thread than the one that allocated them would make per-thread bytes meaningless).
//!
//! The allocator itself must not allocate nor recurse: the counter is a `const`-initialised
//! `Cell<usize>` (no lazy initialisation, no destructor registered), read with `try_with` so an
//! allocation during thread-local teardown is simply not counted.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};

/// The counting allocator (forwards to the system allocator).
pub struct Counting;

thread_local! {
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

static LIVE_BYTES: AtomicUsize = AtomicUsize::new(0);
static PEAK_BYTES: AtomicUsize = AtomicUsize::new(0);

fn count_one() {
    let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
}

fn grow(bytes: usize) {
    let now = LIVE_BYTES.fetch_add(bytes, Relaxed) + bytes;
    PEAK_BYTES.fetch_max(now, Relaxed);
}

fn shrink(bytes: usize) {
    LIVE_BYTES.fetch_sub(bytes, Relaxed);
}

// SAFETY: every call forwards to `System` with the caller's arguments; the bookkeeping neither
// allocates nor touches the memory.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count_one();
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            grow(layout.size());
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        count_one();
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() {
            grow(layout.size());
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) };
        shrink(layout.size());
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count_one();
        let q = unsafe { System.realloc(ptr, layout, new_size) };
        if !q.is_null() {
            if new_size >= layout.size() {
                grow(new_size - layout.size());
            } else {
                shrink(layout.size() - new_size);
            }
        }
        q
    }
}

/// Allocations (including reallocations) made so far by the calling thread.
pub fn allocations() -> usize {
    ALLOCATIONS.with(Cell::get)
}

/// Runs `f` and returns its result with the number of allocations the calling thread made in it.
pub fn count<T>(f: impl FnOnce() -> T) -> (T, usize) {
    let before = allocations();
    let out = f();
    (out, allocations() - before)
}

/// Bytes allocated and not yet freed, whole process.
pub fn live_bytes() -> usize {
    LIVE_BYTES.load(Relaxed)
}

/// Resets the peak to the live level and returns that level (start of a measured pass).
pub fn mark_peak() -> usize {
    let now = LIVE_BYTES.load(Relaxed);
    PEAK_BYTES.store(now, Relaxed);
    now
}

/// Highest live level since the last [`mark_peak`], bytes, whole process.
pub fn peak_bytes() -> usize {
    PEAK_BYTES.load(Relaxed)
}
