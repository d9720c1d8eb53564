//! A counting global allocator for the allocation tests.
//!
//! A test binary installs it:
//!
//! ```ignore
//! #[global_allocator]
//! static ALLOCATOR: kerf_testkit::alloc::CountingAllocator = kerf_testkit::alloc::CountingAllocator;
//! ```
//!
//! and counts a stretch of code on its own thread with [`Count::start`] and
//! [`Count::stop`]: only threads that armed themselves count, so the test harness and the
//! other tests of the binary, running in parallel, are never counted. Allocations,
//! zeroed allocations and reallocations count as allocations; frees are counted apart.
//! For code that runs on another thread (the daemon's cycle), that thread sets a phase
//! ([`set_phase`]) and the test reads the phase's totals ([`allocations`], [`frees`]).
//!
//! Counting only touches atomics and a const-initialised thread-local, so the counter
//! itself never allocates.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicU64, Ordering};

/// Phases a thread can count in (0 is "not counting").
pub const PHASES: usize = 4;

/// The phase of a thread that does not count.
pub const NOT_COUNTING: u8 = 0;

/// The phase [`Count`] uses.
pub const COUNTED: u8 = 1;

static ALLOCATIONS: [AtomicU64; PHASES] = [const { AtomicU64::new(0) }; PHASES];
static FREES: [AtomicU64; PHASES] = [const { AtomicU64::new(0) }; PHASES];

thread_local! {
    static PHASE: Cell<u8> = const { Cell::new(NOT_COUNTING) };
    static THREAD_ALLOCATIONS: Cell<u64> = const { Cell::new(0) };
}

fn phase() -> usize {
    usize::from(PHASE.try_with(Cell::get).unwrap_or(NOT_COUNTING)) % PHASES
}

fn on_allocation() {
    let p = phase();
    if p != usize::from(NOT_COUNTING) {
        ALLOCATIONS[p].fetch_add(1, Ordering::Relaxed);
        let _ = THREAD_ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
    }
}

/// The system allocator, counting on the threads that asked for it.
#[derive(Clone, Copy, Debug)]
pub struct CountingAllocator;

// SAFETY: every call is forwarded unchanged to the system allocator; the counting only
// touches atomics and const thread-locals, which neither allocate nor fail.
unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        on_allocation();
        // SAFETY: the caller upholds `GlobalAlloc::alloc`'s contract, passed on unchanged.
        unsafe { System.alloc(layout) }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        on_allocation();
        // SAFETY: as `alloc`.
        unsafe { System.alloc_zeroed(layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        on_allocation();
        // SAFETY: `ptr` came from this allocator, that is from `System`, with `layout`.
        unsafe { System.realloc(ptr, layout, new_size) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        let p = phase();
        if p != usize::from(NOT_COUNTING) {
            FREES[p].fetch_add(1, Ordering::Relaxed);
        }
        // SAFETY: `ptr` came from this allocator, that is from `System`, with `layout`.
        unsafe { System.dealloc(ptr, layout) }
    }
}

/// Makes the current thread count its allocations and frees in `phase` (1 to
/// [`PHASES`] − 1), or stop counting ([`NOT_COUNTING`]).
pub fn set_phase(phase: u8) {
    PHASE.with(|p| p.set(phase));
}

/// Allocations counted in `phase` by every thread so far.
pub fn allocations(phase: u8) -> u64 {
    ALLOCATIONS[usize::from(phase) % PHASES].load(Ordering::Relaxed)
}

/// Frees counted in `phase` by every thread so far.
pub fn frees(phase: u8) -> u64 {
    FREES[usize::from(phase) % PHASES].load(Ordering::Relaxed)
}

/// A count of the current thread's allocations over a stretch of code.
// Started once and read once: a copy could be read twice.
#[allow(missing_copy_implementations)]
#[derive(Debug)]
#[must_use = "a count is read with `stop`"]
pub struct Count {
    start: u64,
}

impl Count {
    /// Starts counting the current thread's allocations.
    pub fn start() -> Count {
        set_phase(COUNTED);
        Count {
            start: THREAD_ALLOCATIONS.with(Cell::get),
        }
    }

    /// Stops counting; the allocations the current thread made since [`Count::start`].
    pub fn stop(self) -> u64 {
        set_phase(NOT_COUNTING);
        THREAD_ALLOCATIONS.with(Cell::get) - self.start
    }
}
