//! Kerf's own EtherCAT MainDevice side (`kerf-ethercat`) against the emulator, over a veth
//! pair in a private network namespace: the scan, the identity check, and bring-up.
//! Expected identities are the emulator's documented defaults, written out here.

mod netns;

use kerf_config::ethercat::{DriveMode, EthercatConfig, EthercatDrive, EthercatIo, Identity, Pdo};
use kerf_ethercat::bus::{BringUpError, Bus, scan};
use netns::{MAIN_IF, Netns};

const VENDOR: u32 = 0x0000_4B52;
const DRIVE_PRODUCT: u32 = 0x0000_0402;
const IO_PRODUCT: u32 = 0x0000_0010;

fn drive(axis_index: usize, position: u16, product_code: u32) -> EthercatDrive {
    EthercatDrive {
        axis_index,
        position,
        identity: Identity {
            vendor_id: VENDOR,
            product_code,
            revision: None,
        },
        mode: DriveMode::Csp,
        rx_pdo: Pdo::default_rx(DriveMode::Csp),
        tx_pdo: Pdo::default_tx(),
        sdo: Vec::new(),
        homing: None,
    }
}

fn bus(drives: Vec<EthercatDrive>, io_positions: &[u16]) -> EthercatConfig {
    EthercatConfig {
        interface: MAIN_IF.to_owned(),
        dc: false,
        sync0_shift_ns: 0,
        max_missed_cycles: 2,
        watchdog_us: 20_000,
        state_timeout_ms: 5_000,
        sdo_timeout_ms: 1_000,
        dc_settle_timeout_ms: 5_000,
        drives,
        io: io_positions
            .iter()
            .map(|&position| EthercatIo {
                position,
                identity: Identity {
                    vendor_id: VENDOR,
                    product_code: IO_PRODUCT,
                    revision: None,
                },
                sdo: Vec::new(),
                inputs: Vec::new(),
                outputs: Vec::new(),
            })
            .collect(),
    }
}

/// The claim on the bus's interface, taken inside the namespace (abstract socket names are
/// per network namespace).
fn claim() -> kerf_ethercat::claim::Claim {
    kerf_ethercat::claim::Claim::take(MAIN_IF, kerf_ethercat::claim::Holder::Commissioning)
        .expect("claim")
}

#[test]
fn the_scan_lists_every_subdevice_with_its_identity_in_ring_order() {
    let mut ns = Netns::new();
    ns.start_emulator(&["--drives", "3", "--io", "1"]);
    let found = ns.run_inside(|| scan(&claim())).expect("scan");
    let seen: Vec<(u16, &str, u32, u32, u32, u32)> = found
        .iter()
        .map(|f| {
            (
                f.position,
                f.name.as_str(),
                f.vendor_id,
                f.product_code,
                f.revision,
                f.serial,
            )
        })
        .collect();
    assert_eq!(
        seen,
        vec![
            (
                0,
                "Kerf CiA402 drive",
                VENDOR,
                DRIVE_PRODUCT,
                0x0001_0000,
                0x1001
            ),
            (
                1,
                "Kerf CiA402 drive",
                VENDOR,
                DRIVE_PRODUCT,
                0x0001_0000,
                0x1002
            ),
            (
                2,
                "Kerf CiA402 drive",
                VENDOR,
                DRIVE_PRODUCT,
                0x0001_0000,
                0x1003
            ),
            (
                3,
                "Kerf digital I/O",
                VENDOR,
                IO_PRODUCT,
                0x0001_0000,
                0x2001
            ),
        ]
    );
}

#[test]
fn another_identity_and_a_missing_subdevice_are_refused_position_by_position() {
    let mut ns = Netns::new();
    ns.start_emulator(&["--drives", "2", "--io", "1"]);
    // Position 1 is configured as another product; position 3 is configured but absent;
    // the I/O at 2 is as found.
    let config = bus(
        vec![
            drive(0, 0, DRIVE_PRODUCT),
            drive(1, 1, 0x0403),
            drive(2, 3, DRIVE_PRODUCT),
        ],
        &[2],
    );
    let error = ns
        .run_inside(move || Bus::bring_up(&config, 1_000_000, &claim()))
        .unwrap_err();
    let BringUpError::Mismatch { lines } = &error else {
        panic!("not a mismatch: {error}")
    };
    assert_eq!(
        lines,
        &vec![
            "position 1: found \"Kerf CiA402 drive\" vendor 0x00004b52 product 0x00000402 revision 0x00010000, expected Y drive vendor 0x00004b52 product 0x00000403 any revision".to_owned(),
            "position 3: nothing found, expected Z drive vendor 0x00004b52 product 0x00000402 any revision".to_owned(),
        ]
    );
    assert!(
        error
            .to_string()
            .starts_with("the EtherCAT bus differs from the configuration:\n  position 1"),
        "{error}"
    );
}

#[test]
fn an_extra_subdevice_on_the_bus_is_refused() {
    let mut ns = Netns::new();
    ns.start_emulator(&["--drives", "2", "--io", "1"]);
    let config = bus(
        vec![drive(0, 0, DRIVE_PRODUCT), drive(1, 1, DRIVE_PRODUCT)],
        &[],
    );
    let error = ns
        .run_inside(move || Bus::bring_up(&config, 1_000_000, &claim()))
        .unwrap_err();
    let BringUpError::Mismatch { lines } = &error else {
        panic!("not a mismatch: {error}")
    };
    assert_eq!(
        lines,
        &vec!["position 2: found \"Kerf digital I/O\" vendor 0x00004b52 product 0x00000010 revision 0x00010000, not in the configuration".to_owned()]
    );
}

#[test]
fn three_drives_and_an_io_subdevice_come_up_to_op_and_exchange_process_data() {
    let mut ns = Netns::new();
    ns.start_emulator(&["--drives", "3", "--io", "1"]);
    let config = bus(
        vec![
            drive(0, 0, DRIVE_PRODUCT),
            drive(1, 1, DRIVE_PRODUCT),
            drive(2, 2, DRIVE_PRODUCT),
        ],
        &[3],
    );
    let (wkc, expected_wkc, statuswords) = ns.run_inside(move || {
        let mut bus =
            Bus::bring_up(&config, 1_000_000, &claim()).unwrap_or_else(|e| panic!("bring-up: {e}"));
        let mut images = Bus::drive_images(&config).expect("layouts");
        let mut wkc = 0;
        for _ in 0..10 {
            wkc = bus
                .exchange(&mut images, std::time::Duration::from_millis(100))
                .expect("exchange");
        }
        let statuswords: Vec<u16> = images
            .iter()
            .flatten()
            .map(kerf_drive::cia402::Drive::statusword)
            .collect();
        (wkc, bus.expected_working_counter(), statuswords)
    });
    // Three drives with inputs and outputs (3 each) and the I/O with both (3): 12.
    assert_eq!(expected_wkc, 12);
    assert_eq!(wkc, 12);
    // A CiA 402 drive after power-up: Switch on disabled (xxxx xxxx x1xx 0000).
    for sw in statuswords {
        assert_eq!(sw & 0x004F, 0x0040, "statusword {sw:#06x}");
    }
}
