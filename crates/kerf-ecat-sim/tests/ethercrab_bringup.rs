//! ethercrab 0.7.1, unmodified, against the emulator over a veth pair in a private
//! network namespace: discovery and identities, PRE-OP, SAFE-OP and OP with process data.

#[allow(dead_code)]
mod netns;

use std::time::Duration;

use ethercrab::{MainDevice, MainDeviceConfig, PduStorage, Timeouts, std::ethercat_now};
use futures_lite::future::block_on;
use netns::{MAIN_IF, Netns};

const MAX_SUBDEVICES: usize = 8;
const PDI_LEN: usize = 256;

fn timeouts() -> Timeouts {
    Timeouts {
        state_transition: Duration::from_secs(10),
        pdu: Duration::from_millis(200),
        eeprom: Duration::from_millis(500),
        wait_loop_delay: Duration::from_millis(1),
        mailbox_echo: Duration::from_millis(500),
        mailbox_response: Duration::from_millis(1000),
    }
}

static STORAGE_IDENTITY: PduStorage<16, { PduStorage::element_size(1100) }> = PduStorage::new();

#[test]
fn ethercrab_discovers_three_drives_and_one_io_with_their_identities_and_reaches_pre_op() {
    let mut ns = Netns::new();
    ns.start_emulator(&["--drives", "3", "--io", "1"]);
    let found = ns.run_inside(|| {
        let (tx, rx, pdu_loop) = STORAGE_IDENTITY.try_split().expect("split once");
        let maindevice = MainDevice::new(pdu_loop, timeouts(), MainDeviceConfig::default());
        std::thread::spawn(move || {
            let task = ethercrab::std::tx_rx_task(MAIN_IF, tx, rx).expect("TX/RX task");
            let _ = block_on(task);
        });
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
