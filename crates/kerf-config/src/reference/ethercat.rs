//! The reference rows of `[ethercat]`, `[[ethercat.drives]]` and `[[ethercat.io]]`, from
//! the constants and default mappings the checker uses.

use crate::ethercat::{DriveMode, Pdo};
use crate::*;

use super::{KeyDoc, k, ri};

/// A PDO's entries in words: `0x6040:0 (16), 0x607A:0 (32)` in the mapping object.
fn pdo_words(pdo: &Pdo) -> String {
    let entries: Vec<String> = pdo
        .entries
        .iter()
        .map(|e| format!("0x{:04X}:{} ({})", e.index, e.subindex, e.bits))
        .collect();
    format!("{} in 0x{:04X}", entries.join(", "), pdo.index)
}

fn hex(r: std::ops::RangeInclusive<u32>) -> String {
    format!("0x{:X} to 0x{:X}", r.start(), r.end())
}

/// The `[ethercat]` rows, in the order of docs/CONFIG.md.
pub(super) fn keys() -> Vec<KeyDoc> {
    let req = || "required".to_string();
    let timeout = |d: u32| (d.to_string(), ri(BRING_UP_TIMEOUT_RANGE_MS));
    let (state_d, state_r) = timeout(DEFAULT_STATE_TIMEOUT_MS);
    let (sdo_d, sdo_r) = timeout(DEFAULT_SDO_TIMEOUT_MS);
    let (dc_d, dc_r) = timeout(DEFAULT_DC_SETTLE_TIMEOUT_MS);
    let id = || hex(0..=u32::MAX);
    vec![
        k(
            "ethercat",
            "none: simulated drives".into(),
            "table".into(),
            "The EtherCAT bus the axes' servo drives are on. With it, every configured axis is driven by its `[[ethercat.drives]]` and every subdevice on the ring is listed, drives and `[[ethercat.io]]`, at positions 0 to N-1; without it the simulated drives run.",
        ),
        k(
            "ethercat.interface",
            req(),
            "a network interface name, 1 to 15 characters".into(),
            "The network interface the bus is on (its own NIC, no other traffic).",
        ),
        k(
            "ethercat.dc",
            DEFAULT_ETHERCAT_DC.to_string(),
            "true or false".into(),
            "Distributed clocks: the subdevices' SYNC0 fires every period and the cycle thread follows the bus clock.",
        ),
        k(
            "ethercat.sync0_shift_ns",
            "half the period".into(),
            "0 to the period minus 1 ns".into(),
            "SYNC0's shift after the cycle start: the time the frame has to reach every subdevice before the drives latch it. Only with `dc = true`.",
        ),
        k(
            "ethercat.max_missed_cycles",
            DEFAULT_MAX_MISSED_CYCLES.to_string(),
            ri(MAX_MISSED_CYCLES_RANGE),
            "Bad cycles tolerated in a row (a working-counter mismatch, a lost or late frame); one more latches the fault \"EtherCAT: …\".",
        ),
        k(
            "ethercat.watchdog_us",
            DEFAULT_WATCHDOG_US.to_string(),
            format!(
                "{MIN_WATCHDOG_PERIODS} periods to {MAX_WATCHDOG_US}, a multiple of {WATCHDOG_UNIT_US}"
            ),
            "The drives' process-data (SyncManager) watchdog: a drive that gets no frame for this long stops itself by its fault reaction.",
        ),
        k(
            "ethercat.state_timeout_ms",
            state_d,
            state_r,
            "Time each subdevice may take for each state change at bring-up (INIT, PRE-OP, SAFE-OP, OP).",
        ),
        k(
            "ethercat.sdo_timeout_ms",
            sdo_d,
            sdo_r,
            "Time a subdevice may take to answer one SDO request.",
        ),
        k(
            "ethercat.dc_settle_timeout_ms",
            dc_d,
            dc_r,
            "Time the distributed clocks may take to settle at bring-up.",
        ),
        k(
            "ethercat.drives",
            "required with [ethercat]".into(),
            "array of tables".into(),
            "One CiA 402 servo drive per configured axis (`[[ethercat.drives]]`), and the spindle's when `[spindle]` is a \"drive\". An axis's scale is its `[axes.*.drive]` `counts_per_mm` (`counts_per_deg`) and `direction` (the simulated drive's tuning keys are refused), the spindle's `spindle.counts_per_rev`.",
        ),
        k(
            "ethercat.drives.axis",
            req(),
            "x, y, z, a, b, c (either case): a configured axis, once; or s: the spindle, once"
                .into(),
            "The axis the drive moves, or `s` for the spindle's drive (cyclic synchronous velocity; `spindle.kind` must be \"drive\").",
        ),
        k(
            "ethercat.drives.position",
            req(),
            ri(RING_POSITION_RANGE),
            "Ring position, 0-based, in the order the frame passes the subdevices; unique over drives and I/O.",
        ),
        k(
            "ethercat.drives.vendor_id",
            req(),
            id(),
            "Expected vendor ID (`kerf ethercat scan`); a different one refuses the bring-up.",
        ),
        k(
            "ethercat.drives.product_code",
            req(),
            id(),
            "Expected product code.",
        ),
        k(
            "ethercat.drives.revision",
            "any".into(),
            id(),
            "Expected revision number, when given.",
        ),
        k(
            "ethercat.drives.mode",
            format!(
                "\"{}\"; \"{}\" for the spindle",
                DriveMode::Csp.name(),
                DriveMode::Csv.name()
            ),
            "\"csp\" for an axis, \"csv\" for the spindle".into(),
            "\"csp\": cyclic synchronous position (0x6060 = 8), the axis's setpoints as target positions; every axis's. \"csv\": cyclic synchronous velocity (0x6060 = 9, target velocity 0x60FF), the spindle's (`axis = \"s\"`) only.",
        ),
        k(
            "ethercat.drives.rx_pdo_index",
            format!("0x{:X}", Pdo::default_rx(DriveMode::Csp).index),
            hex(RX_PDO_INDEX_RANGE),
            "The RxPDO mapping object `rx_pdo` is written to and assigned alone in 0x1C12.",
        ),
        k(
            "ethercat.drives.tx_pdo_index",
            format!("0x{:X}", Pdo::default_tx().index),
            hex(TX_PDO_INDEX_RANGE),
            "The TxPDO mapping object `tx_pdo` is written to and assigned alone in 0x1C13.",
        ),
        k(
            "ethercat.drives.rx_pdo",
            format!(
                "csp: {}; csv: {}",
                pdo_words(&Pdo::default_rx(DriveMode::Csp)),
                pdo_words(&Pdo::default_rx(DriveMode::Csv))
            ),
            format!("1 to {MAX_PDO_ENTRIES} entries, at most {MAX_PDO_BYTES} bytes"),
            "The outputs mapping, an array of `{ index, subindex, bits }`: it must map the controlword 0x6040:0 (16 bits) and the target (32 bits), and for an axis homed by its drive (`[axes.*.homing] kind = \"drive\"`) the modes of operation 0x6060:0 (8 bits), which the homing switches; entries of 8 bits or more start on a whole byte, the whole is whole bytes; index 0 is a gap. An object is in `rx_pdo` or `tx_pdo`, once. For an axis homed by its drive, the default mapping ends with 0x6060:0 (8 bits) and the default `tx_pdo` with the modes of operation display 0x6061:0 (8 bits); its homing objects (0x6098, 0x6099, 0x609A, 0x607C) are written after the mapping from `[axes.*.homing]`, not from `sdo`.",
        ),
        k(
            "ethercat.drives.rx_pdo.index",
            req(),
            "0x0 to 0xFFFF".into(),
            "Object index of an entry (0: a gap, subindex 0).",
        ),
        k(
            "ethercat.drives.rx_pdo.subindex",
            req(),
            "0 to 255".into(),
            "Object subindex of an entry.",
        ),
        k(
            "ethercat.drives.rx_pdo.bits",
            req(),
            "1, 8, 16, 32, 64 (a gap: 1 to 64)".into(),
            "Size of an entry.",
        ),
        k(
            "ethercat.drives.tx_pdo",
            pdo_words(&Pdo::default_tx()),
            format!("1 to {MAX_PDO_ENTRIES} entries, at most {MAX_PDO_BYTES} bytes"),
            "The inputs mapping, entries as in `rx_pdo`: it must map the statusword 0x6041:0 (16 bits) and the position actual value 0x6064:0 (32 bits), for the spindle the velocity actual value 0x606C:0 (32 bits) instead.",
        ),
        k(
            "ethercat.drives.sdo",
            "[]".into(),
            "array of tables".into(),
            "Start-up writes `{ index, subindex, type, value }`, done in PRE-OP in the order listed (as linuxcnc-ethercat's sdoConfig). 0x6060, 0x60C2, 0x1C12, 0x1C13 and the PDO mapping objects are set from `mode`, `period_us` and the PDO keys and are refused here.",
        ),
        k(
            "ethercat.drives.sdo.index",
            req(),
            "0x1000 to 0xFFFF".into(),
            "Object index.",
        ),
        k(
            "ethercat.drives.sdo.subindex",
            req(),
            "0 to 255".into(),
            "Object subindex.",
        ),
        k(
            "ethercat.drives.sdo.type",
            req(),
            "u8, u16, u32, i8, i16, i32".into(),
            "The object's data type.",
        ),
        k(
            "ethercat.drives.sdo.value",
            req(),
            "within the type".into(),
            "The value written.",
        ),
        k(
            "ethercat.io",
            "no I/O".into(),
            "array of tables".into(),
            "Every subdevice that is not a drive (`[[ethercat.io]]`): digital I/O, and couplers (listed without bits).",
        ),
        k(
            "ethercat.io.position",
            req(),
            ri(RING_POSITION_RANGE),
            "Ring position, as for a drive.",
        ),
        k("ethercat.io.vendor_id", req(), id(), "Expected vendor ID."),
        k(
            "ethercat.io.product_code",
            req(),
            id(),
            "Expected product code.",
        ),
        k(
            "ethercat.io.revision",
            "any".into(),
            id(),
            "Expected revision number, when given.",
        ),
        k(
            "ethercat.io.sdo",
            "[]".into(),
            "as `ethercat.drives.sdo`".into(),
            "Start-up writes in PRE-OP, keys as for a drive (no object reserved).",
        ),
        k(
            "ethercat.io.inputs",
            "no inputs".into(),
            format!("NAME = bit, bits {}", ri(IO_BIT_RANGE)),
            "Named input bits, bit 0 the first bit of the subdevice's inputs. Names (ASCII letters, digits, `_`, `-`, from a letter) are unique on the bus, bits within the subdevice's inputs.",
        ),
        k(
            "ethercat.io.outputs",
            "no outputs".into(),
            format!("NAME = bit, bits {}", ri(IO_BIT_RANGE)),
            "Named output bits, as `inputs`.",
        ),
    ]
}
