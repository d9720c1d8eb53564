//! ethercrab 0.7.1, unmodified, against the emulator over a veth pair in a private
//! network namespace: discovery and identities, PRE-OP, SAFE-OP and OP with process data.

mod netns;

use ethercrab::{PduStorage, std::ethercat_now};
use futures_lite::future::block_on;
use netns::Netns;

const MAX_SUBDEVICES: usize = 8;
const PDI_LEN: usize = 256;

static STORAGE_IDENTITY: PduStorage<16, { PduStorage::element_size(1100) }> = PduStorage::new();

#[test]
fn ethercrab_discovers_three_drives_and_one_io_with_their_identities_and_reaches_pre_op() {
    let mut ns = Netns::new();
    ns.start_emulator(&["--drives", "3", "--io", "1"]);
    let found = ns.run_inside(|| {
        let maindevice = netns::maindevice(&STORAGE_IDENTITY);
        let group = block_on(maindevice.init_single_group::<MAX_SUBDEVICES, PDI_LEN>(ethercat_now))
            .expect("init to PRE-OP");
        let mut found = Vec::new();
        for sd in group.iter(&maindevice) {
            let id = sd.identity();
            let (state, code) = block_on(sd.status()).expect("status");
            found.push((
                sd.name().to_owned(),
                id.vendor_id,
                id.product_id,
                id.revision,
                id.serial,
                format!("{state:?}"),
                u16::from(code),
            ));
        }
        found
    });
    let drive = |serial: u32| {
        (
            "Kerf CiA402 drive".to_owned(),
            0x0000_4B52,
            0x0000_0402,
            0x0001_0000,
            serial,
            "PreOp".to_owned(),
            0u16,
        )
    };
    assert_eq!(
        found,
        vec![
            drive(0x1001),
            drive(0x1002),
            drive(0x1003),
            (
                "Kerf digital I/O".to_owned(),
                0x0000_4B52,
                0x0000_0010,
                0x0001_0000,
                0x2001,
                "PreOp".to_owned(),
                0
            ),
        ]
    );
    assert!(ns.stop_emulator(), "the emulator exits cleanly on SIGTERM");
}

static STORAGE_OPTIONS: PduStorage<16, { PduStorage::element_size(1100) }> = PduStorage::new();

#[test]
fn identity_options_are_seen_by_ethercrab_and_a_refused_safe_op_names_its_code() {
    let mut ns = Netns::new();
    ns.start_emulator(&[
        "--drives",
        "3",
        "--vendor-id",
        "0x12345678",
        "--product-code",
        "0xCAFE",
        "--revision",
        "7",
        "--refuse-safe-op",
        "1",
        "--refuse-safe-op",
        "2:0x0035",
    ]);
    let (identities, op_result, codes) = ns.run_inside(|| {
        let maindevice = netns::maindevice(&STORAGE_OPTIONS);
        let group = block_on(maindevice.init_single_group::<MAX_SUBDEVICES, PDI_LEN>(ethercat_now))
            .expect("init to PRE-OP");
        let identities: Vec<(u32, u32, u32)> = group
            .iter(&maindevice)
            .map(|sd| {
                let id = sd.identity();
                (id.vendor_id, id.product_id, id.revision)
            })
            .collect();
        let addresses: Vec<u16> = group
            .iter(&maindevice)
            .map(|sd| sd.configured_address())
            .collect();
        let op_result = block_on(group.into_op(&maindevice))
            .map(|_| ())
            .map_err(|e| format!("{e:?}"));
        // Each subdevice's AL status and code, read as ethercrab's register read gives
        // them.
        let codes: Vec<(u16, u16)> = addresses
            .iter()
            .map(|address| {
                // The first read after the refused transition may time out: ethercrab
                // dropped the transition's last frame in flight when its own timeout fired,
                // and the answer to it can take the next frame's place (the harness's pump
                // ignores it and goes on). A read is idempotent; three tries.
                let read = |register: u16| {
                    let once = || {
                        block_on(
                            ethercrab::Command::fprd(*address, register)
                                .receive::<u16>(&maindevice),
                        )
                    };
                    once()
                        .or_else(|_| once())
                        .or_else(|_| once())
                        .unwrap_or_else(|e| panic!("register {register:#06x}: {e}"))
                };
                (read(0x0130), read(0x0134))
            })
            .collect();
        (identities, op_result, codes)
    });
    assert_eq!(identities, vec![(0x1234_5678, 0xCAFE, 7); 3]);
    assert_eq!(
        op_result,
        Err("Timeout(StateTransition)".to_owned()),
        "OP must be refused"
    );
    // The drive at 0 went to SAFE-OP (4); the drive at 1 refused it with the default
    // 0x001D, invalid output configuration, the one at 2 with the code asked for, 0x0035
    // (invalid sync cycle time): both stayed in PRE-OP with the error indicator (0x12).
    assert_eq!(codes, vec![(0x04, 0x0000), (0x12, 0x001D), (0x12, 0x0035)]);
    assert!(ns.stop_emulator(), "the emulator exits cleanly on SIGTERM");
}
