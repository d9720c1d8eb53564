//! `PeriodicClock::wait_next` must not allocate: it runs in the real-time cycle.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicU64, Ordering};

use kerf_rt::PeriodicClock;

struct CountingAllocator;

static ALLOCATIONS: AtomicU64 = AtomicU64::new(0);

thread_local! {
    // Only the measuring thread counts, so the test harness's own threads cannot interfere.
    static COUNTING: Cell<bool> = const { Cell::new(false) };
}

// SAFETY: forwards to the system allocator unchanged; counting has no effect on the memory.
unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if COUNTING.with(Cell::get) {
            ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
        }
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if COUNTING.with(Cell::get) {
            ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
        }
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: CountingAllocator = CountingAllocator;

#[test]
fn wait_next_does_not_allocate() {
    let mut clock = PeriodicClock::new(100_000).expect("valid period");
    // The counter works: an allocation while counting is seen.
    COUNTING.with(|c| c.set(true));
    let probe = std::hint::black_box(vec![1u8; 16]);
    COUNTING.with(|c| c.set(false));
    drop(probe);
    assert_eq!(ALLOCATIONS.swap(0, Ordering::SeqCst), 1);

    COUNTING.with(|c| c.set(true));
    let mut latency_sum_ns = 0u64;
    for _ in 0..2_000 {
        let tick = clock.wait_next();
        latency_sum_ns = latency_sum_ns.wrapping_add(tick.latency_ns);
    }
    COUNTING.with(|c| c.set(false));
    std::hint::black_box(latency_sum_ns);
    assert_eq!(clock.cycles(), 2_000);
    assert_eq!(ALLOCATIONS.load(Ordering::SeqCst), 0);
}
