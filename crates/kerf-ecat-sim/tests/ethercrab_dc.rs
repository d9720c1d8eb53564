//! Distributed clocks through ethercrab 0.7.1: the clocks' offsets written at
//! initialisation make every subdevice's system time agree with the reference's (their
//! local clocks start 0.5–3 ms apart), `configure_dc_sync` programs SYNC0, and `tx_rx_dc`
//! runs cyclically with the reference's system time; with `--dc-drift-ppm`, the
//! reference's system time gains on the host's monotonic clock at that rate.

mod netns;

use std::time::{Duration, Instant};

use ethercrab::subdevice_group::DcConfiguration;
use ethercrab::{DcSync, PduStorage, RegisterAddress, std::ethercat_now};
use futures_lite::future::block_on;
use netns::Netns;

const MAX_SUBDEVICES: usize = 8;
const PDI_LEN: usize = 256;
const SYNC0_PERIOD_NS: u64 = 1_000_000;

static STORAGE: PduStorage<16, { PduStorage::element_size(1100) }> = PduStorage::new();

#[derive(Debug, Default)]
struct Seen {
    /// (reference before, subdevice, reference after) system times, ns.
    sandwiches: Vec<(u64, u64, u64)>,
    /// (SYNC0 cycle time, sync active, start time) per subdevice.
    sync: Vec<(u32, u8, u64)>,
    /// dc_system_time of consecutive tx_rx_dc cycles.
    cycle_times: Vec<u64>,
    /// next_cycle_wait of each cycle, ns.
    waits_ns: Vec<u64>,
    /// System time difference (0x092C) of each subdevice after the cycles.
    differences: Vec<u32>,
    /// The last subdevice's 0x092C after a write of its own system time + 10 ms.
    difference_ahead: u32,
}

fn run() -> Seen {
    let md = netns::maindevice(&STORAGE);
    let mut group = block_on(md.init_single_group::<MAX_SUBDEVICES, PDI_LEN>(ethercat_now))
        .expect("init to PRE-OP");
    let mut seen = Seen::default();
    let system_time = |index: usize| -> u64 {
        let sd = group.subdevice(&md, index).expect("subdevice");
        block_on(sd.register_read::<u64>(RegisterAddress::DcSystemTime)).expect("system time")
    };
    for index in 0..group.len() {
        let before = system_time(0);
        let own = system_time(index);
        let after = system_time(0);
        seen.sandwiches.push((before, own, after));
    }
    for mut sd in group.iter_mut(&md) {
        sd.set_dc_sync(DcSync::Sync0);
    }
    let group = block_on(group.into_pre_op_pdi(&md)).expect("PDI");
    let group = block_on(group.configure_dc_sync(
        &md,
        DcConfiguration {
            start_delay: Duration::from_millis(100),
            sync0_period: Duration::from_nanos(SYNC0_PERIOD_NS),
            sync0_shift: Duration::ZERO,
        },
    ))
    .expect("configure DC");
    let group = block_on(group.into_safe_op(&md)).expect("SAFE-OP");
    let group = block_on(group.into_op(&md)).expect("OP");
    for sd in group.iter(&md) {
        let cycle = block_on(sd.register_read::<u32>(RegisterAddress::DcSync0CycleTime));
        let active = block_on(sd.register_read::<u8>(RegisterAddress::DcSyncActive));
        let start = block_on(sd.register_read::<u64>(RegisterAddress::DcSyncStartTime));
        seen.sync.push((
            cycle.expect("cycle"),
            active.expect("active"),
            start.expect("start"),
        ));
    }
    for _ in 0..50 {
        let response = block_on(group.tx_rx_dc(&md)).expect("tx_rx_dc");
        seen.cycle_times.push(response.extra.dc_system_time);
        seen.waits_ns
            .push(response.extra.next_cycle_wait.as_nanos() as u64);
    }
    for sd in group.iter(&md) {
        let difference = block_on(sd.register_read::<u32>(0x092Cu16));
        seen.differences
            .push(difference.expect("system time difference"));
    }
    let last = group
        .subdevice(&md, group.len() - 1)
        .expect("last subdevice");
    let own =
        block_on(last.register_read::<u64>(RegisterAddress::DcSystemTime)).expect("system time");
    block_on(last.register_write(RegisterAddress::DcSystemTime, own + 10_000_000))
        .expect("write system time");
    seen.difference_ahead =
        block_on(last.register_read::<u32>(0x092Cu16)).expect("system time difference");
    seen
}

#[test]
fn ethercrab_aligns_the_clocks_and_runs_cyclic_exchanges_with_dc() {
    let mut ns = Netns::new();
    ns.start_emulator(&["--drives", "3", "--io", "1"]);
    let seen = ns.run_inside(run);
    // Every subdevice's system time lies between two reads of the reference's, give or
    // take the transmission delays (0.5 µs per subdevice, 4 µs for the line).
    for (index, (before, own, after)) in seen.sandwiches.iter().enumerate() {
        assert!(
            before.saturating_sub(4_000) <= *own && *own <= after + 4_000,
            "subdevice {index}: reference {before}..{after}, own {own}"
        );
    }
    // Each subdevice was programmed for SYNC0 at 1 ms: sync active = cyclic operation
    // (bit 0) + SYNC0 (bit 1); the start time on a SYNC0 edge.
    assert_eq!(seen.sync.len(), 4);
    for (cycle, active, start) in &seen.sync {
        assert_eq!((*cycle, *active), (1_000_000, 0x03));
        assert_eq!(start % SYNC0_PERIOD_NS, 0);
    }
    // The reference's system time advances from cycle to cycle; the next wait is within
    // one SYNC0 period.
    assert!(
        seen.cycle_times.windows(2).all(|w| w[1] > w[0]),
        "{:?}",
        seen.cycle_times
    );
    assert!(
        seen.waits_ns.iter().all(|w| *w <= SYNC0_PERIOD_NS),
        "{:?}",
        seen.waits_ns
    );
    // The subdevices behind the reference receive its system time in every cycle's FRMW
    // and have followed it: their system time difference (0x092C, bits 30:0 the
    // magnitude) is within 100 ns. (The reference itself last received ethercrab's reset,
    // a broadcast write of 0 to 0x0910, at initialisation.)
    assert_eq!(seen.differences.len(), 4);
    // A received time 10 ms ahead of the own copy (less the time between the read and the
    // write, plus the delay): the own copy is smaller, bit 31.
    let ahead = seen.difference_ahead;
    assert!(
        ahead & 0x8000_0000 != 0 && (5_000_000..=10_010_000).contains(&(ahead & 0x7FFF_FFFF)),
        "0x092C after a write 10 ms ahead: {ahead:#010x}"
    );
    for (index, difference) in seen.differences.iter().enumerate().skip(1) {
        assert!(
            difference & 0x7FFF_FFFF <= 100,
            "subdevice {index}: system time difference {difference:#010x}"
        );
    }
    assert!(ns.stop_emulator(), "the emulator exits cleanly on SIGTERM");
}

static STORAGE_DRIFT: PduStorage<16, { PduStorage::element_size(1100) }> = PduStorage::new();

/// The emulator's drift in the test below, ppm.
const DRIFT_PPM: f64 = 500.0;
/// Host time between the two reads.
const DRIFT_INTERVAL: Duration = Duration::from_secs(2);
/// The longest round trip of a read that is kept (a slower one is read again).
const MAX_ROUND_TRIP: Duration = Duration::from_micros(300);

/// A read of the reference's system time, with the host's time just before and just
/// after it: (before, system time ns, after).
type Sandwich = (Instant, u64, Instant);

fn run_drift() -> (Sandwich, Sandwich) {
    let md = netns::maindevice(&STORAGE_DRIFT);
    let group = block_on(md.init_single_group::<MAX_SUBDEVICES, PDI_LEN>(ethercat_now))
        .expect("init to PRE-OP");
    let reference = group.subdevice(&md, 0).expect("the reference clock");
    let read = || -> Sandwich {
        let mut fastest: Option<Sandwich> = None;
        for _ in 0..50 {
            let before = Instant::now();
            let time = block_on(reference.register_read::<u64>(RegisterAddress::DcSystemTime))
                .expect("system time");
            let after = Instant::now();
            if fastest.is_none_or(|(b, _, a)| after - before < a - b) {
                fastest = Some((before, time, after));
            }
            if after - before <= MAX_ROUND_TRIP {
                break;
            }
        }
        fastest.expect("at least one read")
    };
    let first = read();
    std::thread::sleep(DRIFT_INTERVAL);
    let second = read();
    (first, second)
}

#[test]
fn the_reference_clock_gains_its_drift_on_the_host_monotonic_clock() {
    let mut ns = Netns::new();
    let drift = DRIFT_PPM.to_string();
    ns.start_emulator(&["--drives", "2", "--dc-drift-ppm", &drift]);
    let ((before1, time1, after1), (before2, time2, after2)) = ns.run_inside(run_drift);
    let ns_of = |d: Duration| d.as_nanos() as f64;
    // The two reads happened between these host intervals apart (both processes read the
    // same CLOCK_MONOTONIC).
    let shortest_ns = ns_of(before2 - after1);
    let longest_ns = ns_of(after2 - before1);
    let rate = 1.0 + DRIFT_PPM * 1e-6;
    let elapsed_ns = (time2 - time1) as f64;
    assert!(
        shortest_ns * rate <= elapsed_ns && elapsed_ns <= longest_ns * rate,
        "system time advanced {elapsed_ns} ns over {shortest_ns}..{longest_ns} ns of host \
         time; at {DRIFT_PPM} ppm it should advance {}..{} ns",
        shortest_ns * rate,
        longest_ns * rate
    );
    // And the gain is more than the uncertainty of the host interval: the clock is fast,
    // not merely within the reads' round trips of the host's time.
    assert!(
        elapsed_ns > longest_ns,
        "system time advanced {elapsed_ns} ns, no more than the host's {longest_ns} ns \
         (round trips {:?} and {:?})",
        after1 - before1,
        after2 - before2
    );
    assert!(ns.stop_emulator(), "the emulator exits cleanly on SIGTERM");
}
