//! The cyclic exchange of kerf-ethercat allocates nothing: after bring-up, thousands of
//! exchanges with the emulator over veth are counted by a counting allocator on the
//! exchanging thread (its own test binary, so that nothing else installs an allocator).

mod netns;

use kerf_config::ethercat::{DriveMode, EthercatConfig, EthercatDrive, EthercatIo, Identity, Pdo};
use kerf_ethercat::bus::Bus;
use kerf_testkit::alloc::{Count, CountingAllocator};
use netns::{MAIN_IF, Netns};

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

const VENDOR: u32 = 0x0000_4B52;

/// The claim on the bus's interface, taken inside the namespace (abstract socket names are
/// per network namespace).
fn claim() -> kerf_ethercat::claim::Claim {
    kerf_ethercat::claim::Claim::take(MAIN_IF, kerf_ethercat::claim::Holder::Commissioning)
        .expect("claim")
}

#[test]
fn ten_thousand_exchanges_allocate_nothing() {
    exchanges_allocate_nothing(false);
}

/// With distributed clocks every exchange also reads the reference's system time and the
/// phase lock takes it; the reads and requests of a reset's recovery run beside it.
#[test]
fn ten_thousand_exchanges_with_distributed_clocks_and_the_recoverys_requests_allocate_nothing() {
    exchanges_allocate_nothing(true);
}

fn exchanges_allocate_nothing(dc: bool) {
    let mut ns = Netns::new();
    ns.start_emulator(&["--drives", "3", "--io", "1"]);
    let identity = |product_code| Identity {
        vendor_id: VENDOR,
        product_code,
        revision: None,
    };
    let config = EthercatConfig {
        interface: MAIN_IF.to_owned(),
        dc,
        sync0_shift_ns: if dc { 500_000 } else { 0 },
        max_missed_cycles: 2,
        watchdog_us: 20_000,
        state_timeout_ms: 5_000,
        sdo_timeout_ms: 1_000,
        dc_settle_timeout_ms: 5_000,
        drives: (0..3)
            .map(|i| EthercatDrive {
                axis_index: i,
                position: i as u16,
                identity: identity(0x0402),
                mode: DriveMode::Csp,
                rx_pdo: Pdo::default_rx(DriveMode::Csp),
                tx_pdo: Pdo::default_tx(),
                sdo: Vec::new(),
                homing: None,
            })
            .collect(),
        io: vec![EthercatIo {
            position: 3,
            identity: identity(0x0010),
            sdo: Vec::new(),
            inputs: Vec::new(),
            outputs: Vec::new(),
        }],
    };
    let (allocations, wkcs, expected) = ns.run_inside(move || {
        let mut bus =
            Bus::bring_up(&config, 1_000_000, &claim()).unwrap_or_else(|e| panic!("bring-up: {e}"));
        let mut images = Bus::drive_images(&config).expect("layouts");
        // The machine's I/O on the terminal at position 3: outputs 0 and 9 on its bits 0
        // and 1, inputs 4 and 5 on its bits 0 and 1.
        let bit = |bit| kerf_config::BusBit { position: 3, bit };
        let io = kerf_ethercat::iomap::IoMap::new(
            [(0, bit(0)), (9, bit(1))].into_iter(),
            [(4, bit(0)), (5, bit(1))].into_iter(),
        );
        let expected = bus.expected_working_counter();
        // Warm up: the first exchanges may touch lazily made state.
        for _ in 0..100 {
            bus.exchange(&mut images, std::time::Duration::from_millis(100))
                .expect("exchange");
        }
        let mut wkcs = [0u16; 10_000];
        let count = Count::start();
        for (i, wkc) in wkcs.iter_mut().enumerate() {
            bus.write_io(&io, i as u64);
            *wkc = bus
                .exchange(&mut images, std::time::Duration::from_millis(100))
                .expect("exchange");
            assert_eq!(bus.read_io(&io) & !(0b11 << 4), 0);
            if dc && i % 100 == 0 {
                // A reset's recovery: a subdevice's status read, then a request (for the
                // state it is in: nothing changes).
                let position = (i / 100 % 4) as u16;
                let timeout = std::time::Duration::from_millis(100);
                let (state, _) = bus.status_of(position, timeout).expect("status");
                assert!(bus.request_state(position, state & 0x0F, timeout));
            }
        }
        (count.stop(), wkcs.to_vec(), expected)
    });
    assert_eq!(allocations, 0, "allocations in 10 000 exchanges");
    assert_eq!(expected, 12);
    assert!(
        wkcs.iter().all(|&w| w == expected),
        "a working counter other than {expected}"
    );
}
