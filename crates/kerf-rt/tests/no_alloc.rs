//! `PeriodicClock::wait_next` must not allocate: it runs in the real-time cycle.

use kerf_rt::PeriodicClock;

use kerf_testkit::alloc::{Count, CountingAllocator};

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

#[test]
fn wait_next_does_not_allocate() {
    let mut clock = PeriodicClock::new(100_000).expect("valid period");
    // The counter works: an allocation while counting is seen.
    let count = Count::start();
    let probe = std::hint::black_box(vec![1u8; 16]);
    let probed = count.stop();
    drop(probe);
    assert_eq!(probed, 1);

    let count = Count::start();
    let mut latency_sum_ns = 0u64;
    for _ in 0..2_000 {
        let tick = clock.wait_next();
        latency_sum_ns = latency_sum_ns.wrapping_add(tick.latency_ns);
    }
    let allocations = count.stop();
    std::hint::black_box(latency_sum_ns);
    assert_eq!(clock.cycles(), 2_000);
    assert_eq!(allocations, 0);
}
