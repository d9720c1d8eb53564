//! ethercrab 0.7.1, unmodified, takes the emulator to OP: cyclic process data with the
//! working counter ETG.1000 gives, SDO read and write with the abort codes of CiA 301
//! (object or subindex missing, read-only, length mismatch) as ethercrab reports them, a
//! CiA 402 drive enabled through its process data and moved.

mod netns;

use std::io::Write;
use std::time::Duration;

use ethercrab::error::{Error, MailboxError};
use ethercrab::{PduStorage, std::ethercat_now};
use futures_lite::future::block_on;
use netns::Netns;

const MAX_SUBDEVICES: usize = 8;
const PDI_LEN: usize = 256;

static STORAGE: PduStorage<16, { PduStorage::element_size(1100) }> = PduStorage::new();

/// What the test measured inside the namespace.
#[derive(Debug, Default)]
struct Seen {
    wkc: u16,
    io_sizes: Vec<(usize, usize)>,
    sdo_vendor: u32,
    sdo_mode: i8,
    /// Each abort as (code, address, subindex, Display text).
    aborts: Vec<(u32, u16, u8, String)>,
    statusword: u16,
    position: i32,
    io_input_byte: u8,
    muted_error: Option<bool>,
}

fn run(mut control: std::process::ChildStdin) -> Seen {
    let maindevice = netns::maindevice(&STORAGE);
    let group = block_on(maindevice.init_single_group::<MAX_SUBDEVICES, PDI_LEN>(ethercat_now))
        .expect("init to PRE-OP");
    let mut seen = Seen::default();
    {
        let drive = group.subdevice(&maindevice, 0).expect("drive 0");
        seen.sdo_vendor = block_on(drive.sdo_read::<u32>(0x1018, 1)).expect("read 0x1018:01");
        block_on(drive.sdo_write(0x6060, 0, 8i8)).expect("write 0x6060");
        seen.sdo_mode = block_on(drive.sdo_read::<i8>(0x6061, 0)).expect("read 0x6061");
        let abort = |e: Error| match e {
            Error::Mailbox(MailboxError::Aborted {
                code,
                address,
                sub_index,
            }) => (u32::from(code), address, sub_index, e.to_string()),
            other => panic!("expected an SDO abort, got {other:?}"),
        };
        // An object that does not exist, read and written.
        seen.aborts.push(abort(
            block_on(drive.sdo_read::<u32>(0x2345, 0)).unwrap_err(),
        ));
        seen.aborts.push(abort(
            block_on(drive.sdo_write(0x2345, 0, 1u8)).unwrap_err(),
        ));
        // A subindex that does not exist in an object that does (0x1018 has 1..=4).
        seen.aborts.push(abort(
            block_on(drive.sdo_read::<u32>(0x1018, 9)).unwrap_err(),
        ));
        seen.aborts.push(abort(
            block_on(drive.sdo_write(0x1018, 9, 1u32)).unwrap_err(),
        ));
        // A read-only object written.
        seen.aborts.push(abort(
            block_on(drive.sdo_write(0x6041, 0, 1u16)).unwrap_err(),
        ));
        // Four bytes written to the 1-byte mode of operation.
        seen.aborts.push(abort(
            block_on(drive.sdo_write(0x6060, 0, 8u32)).unwrap_err(),
        ));
        // None of them changed anything.
        assert_eq!(
            block_on(drive.sdo_read::<i8>(0x6061, 0)).expect("0x6061"),
            8
        );
    }
    let group = block_on(group.into_op(&maindevice)).expect("PRE-OP -> OP");
    for sd in group.iter(&maindevice) {
        let io = sd.io_raw();
        seen.io_sizes.push((io.outputs().len(), io.inputs().len()));
    }
    // Enable drive 0 (0x00 lets it finish initialising, then Shutdown, Switch on, Enable
    // operation), then ramp its target to 2000 counts and hold it.
    let mut target = 0i32;
    for cycle in 0..800 {
        let controlword: u16 = match cycle {
            0..=1 => 0x0000,
            2..=3 => 0x0006,
            4..=5 => 0x0007,
            _ => 0x000F,
        };
        if (10..210).contains(&cycle) {
            target += 10;
        }
        {
            let drive = group.subdevice(&maindevice, 0).expect("drive 0");
            let mut out = drive.outputs_raw_mut();
            out[0..2].copy_from_slice(&controlword.to_le_bytes());
            out[2..6].copy_from_slice(&target.to_le_bytes());
        }
        let response = block_on(group.tx_rx(&maindevice)).expect("tx_rx");
        seen.wkc = response.working_counter;
    }
    {
        // The PDI guards must be gone before the next exchange, which writes the PDI.
        let drive = group.subdevice(&maindevice, 0).expect("drive 0");
        let inputs = drive.inputs_raw();
        seen.statusword = u16::from_le_bytes([inputs[0], inputs[1]]);
        seen.position = i32::from_le_bytes([inputs[2], inputs[3], inputs[4], inputs[5]]);
        let io = group.subdevice(&maindevice, 3).expect("I/O");
        seen.io_input_byte = io.inputs_raw()[0];
    }
    // A pulled cable: the emulator stops answering, ethercrab's exchange times out.
    writeln!(control, "mute").expect("send mute");
    let deadline = std::time::Instant::now() + Duration::from_secs(10);
    while std::time::Instant::now() < deadline {
        if let Err(e) = block_on(group.tx_rx(&maindevice)) {
            seen.muted_error = Some(matches!(e, Error::Timeout(_)));
            break;
        }
    }
    seen
}

#[test]
fn ethercrab_reaches_op_exchanges_process_data_serves_sdos_and_moves_a_drive() {
    let mut ns = Netns::new();
    ns.start_emulator(&["--drives", "3", "--io", "1"]);
    let control = ns.take_emulator_stdin();
    let seen = ns.run_inside(move || run(control));
    // 4 subdevices with inputs and outputs in one LRW: 3 each (ETG.1000.4).
    assert_eq!(seen.wkc, 12);
    // Drive: outputs controlword + target (6 bytes), inputs 2+4+4+4+2+4 = 20 bytes;
    // I/O: 8 bits each way.
    assert_eq!(seen.io_sizes, vec![(6, 20), (6, 20), (6, 20), (1, 1)]);
    assert_eq!(seen.sdo_vendor, 0x0000_4B52);
    assert_eq!(seen.sdo_mode, 8);
    let missing = "The object does not exist in the object directory";
    let no_sub = "Subindex does not exist";
    let read_only = "Attempt to write to a read only object";
    let length = "Data type does not match, length of service parameter does not match";
    let expected: Vec<(u32, u16, u8, String)> = [
        (0x0602_0000, 0x2345, 0, missing),
        (0x0602_0000, 0x2345, 0, missing),
        (0x0609_0011, 0x1018, 9, no_sub),
        (0x0609_0011, 0x1018, 9, no_sub),
        (0x0601_0002, 0x6041, 0, read_only),
        (0x0607_0010, 0x6060, 0, length),
    ]
    .into_iter()
    .map(|(code, index, sub, words)| {
        let text = format!("mailbox: {index:#06x}:{sub} aborted: {code:#010x}: {words}");
        (code, index, sub, text)
    })
    .collect();
    assert_eq!(seen.aborts, expected);
    // Operation enabled per CiA 402's decoding table: bits 0-3, 5, 6 = 0x27.
    assert_eq!(
        seen.statusword & 0x006F,
        0x0027,
        "statusword {:#06x}",
        seen.statusword
    );
    assert!(
        (seen.position - 2000).abs() <= 2,
        "position actual {} after holding target 2000 for 590 cycles",
        seen.position
    );
    assert_eq!(seen.io_input_byte, 0);
    assert_eq!(seen.muted_error, Some(true), "after `mute`, a timeout");
    assert!(ns.stop_emulator(), "the emulator exits cleanly on SIGTERM");
}
