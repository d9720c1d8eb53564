//! `[ethercat]`'s tests of the CoE objects: PDO mapping overrides, SDO start-up lists and
//! the I/O subdevices' named bits.

use crate::ethercat::*;
use crate::tests_ethercat::{at, bus, bus_config, refused, spindle_drive};

fn rx(entries: &str) -> String {
    format!("rx_pdo = [{entries}]\n")
}

fn tx(entries: &str) -> String {
    format!("tx_pdo = [{entries}]\n")
}

const CW: &str = "{ index = 0x6040, subindex = 0, bits = 16 }";
const TP: &str = "{ index = 0x607A, subindex = 0, bits = 32 }";
const SW: &str = "{ index = 0x6041, subindex = 0, bits = 16 }";
const PA: &str = "{ index = 0x6064, subindex = 0, bits = 32 }";

fn triples(pdo: &Pdo) -> Vec<(u16, u8, u8)> {
    pdo.entries
        .iter()
        .map(|e| (e.index, e.subindex, e.bits))
        .collect()
}

#[test]
fn a_pdo_override_replaces_the_default_mapping() {
    // Touch probe status and two digital bits with a gap, in a second mapping object.
    let x = format!(
        "rx_pdo_index = 0x1601\ntx_pdo_index = 0x1A01\n{}{}",
        rx(&format!(
            "{CW}, {TP}, {{ index = 0x60B8, subindex = 0, bits = 16 }}"
        )),
        tx(&format!(
            "{SW}, {PA}, {{ index = 0x2001, subindex = 1, bits = 1 }}, {{ index = 0x2001, subindex = 2, bits = 1 }}, {{ index = 0, subindex = 0, bits = 6 }}, {{ index = 0x60B9, subindex = 0, bits = 16 }}"
        ))
    );
    let b = bus_config(&bus("", &x, ""));
    let d = &b.drives[0];
    assert_eq!((d.rx_pdo.index, d.tx_pdo.index), (0x1601, 0x1A01));
    assert_eq!(
        triples(&d.rx_pdo),
        [(0x6040, 0, 16), (0x607A, 0, 32), (0x60B8, 0, 16)]
    );
    assert_eq!(
        triples(&d.tx_pdo),
        [
            (0x6041, 0, 16),
            (0x6064, 0, 32),
            (0x2001, 1, 1),
            (0x2001, 2, 1),
            (0, 0, 6),
            (0x60B9, 0, 16)
        ]
    );
    // 16 + 32 bits, then the two bits at 48 and 49, the gap to 56, 0x60B9 at 56.
    assert_eq!(d.tx_pdo.bit_offset(0x2001, 2), Some((49, 1)));
    assert_eq!(d.tx_pdo.bit_offset(0x60B9, 0), Some((56, 16)));
    assert_eq!(d.tx_pdo.size_bytes(), 9);
    // The gap is not an object.
    assert_eq!(d.tx_pdo.bit_offset(0, 0), None);
    // The other drives keep the default.
    assert_eq!(b.drives[1].rx_pdo, Pdo::default_rx(DriveMode::Csp));
    assert_eq!(b.drives[1].tx_pdo, Pdo::default_tx());
}

#[test]
fn a_pdo_override_must_map_what_the_control_needs() {
    let cases = [
        (
            rx(TP),
            "`ethercat.drives[0].rx_pdo` must map the controlword 0x6040:0 (16 bits): the daemon cannot run the drive without it",
        ),
        (
            rx(CW),
            "`ethercat.drives[0].rx_pdo` must map the target position 0x607A:0 (32 bits): the daemon cannot run the drive without it",
        ),
        (
            tx(PA),
            "`ethercat.drives[0].tx_pdo` must map the statusword 0x6041:0 (16 bits): the daemon cannot run the drive without it",
        ),
        (
            tx(SW),
            "`ethercat.drives[0].tx_pdo` must map the position actual value 0x6064:0 (32 bits): the daemon cannot run the drive without it",
        ),
        (
            rx(&format!(
                "{CW}, {{ index = 0x607A, subindex = 0, bits = 16 }}"
            )),
            "`ethercat.drives[0].rx_pdo` maps the target position 0x607A:0 with 16 bits; it is 32 bits",
        ),
    ];
    for (x, message) in cases {
        let text = bus("", &x, "");
        assert_eq!(
            refused(&text),
            format!("{}{message}", at(&text, "[{ index")),
            "{x}"
        );
    }
    // The spindle's drive (csv) needs the target velocity out and the velocity actual
    // value in; the position is not needed.
    let text = format!(
        "{}{}",
        bus("", "", ""),
        spindle_drive(&rx(&format!("{CW}, {TP}")))
    );
    assert_eq!(
        refused(&text),
        format!(
            "{}`ethercat.drives[3].rx_pdo` must map the target velocity 0x60FF:0 (32 bits): the daemon cannot run the drive without it",
            at(&text, "[{ index")
        )
    );
    let text = format!("{}{}", bus("", "", ""), spindle_drive(&tx(PA)));
    assert!(refused(&text).ends_with("`ethercat.drives[3].tx_pdo` must map the statusword 0x6041:0 (16 bits): the daemon cannot run the drive without it"), "{}", refused(&text));
    let text = format!("{}{}", bus("", "", ""), spindle_drive(&tx(SW)));
    assert!(refused(&text).ends_with("`ethercat.drives[3].tx_pdo` must map the velocity actual value 0x606C:0 (32 bits): the daemon cannot run the drive without it"), "{}", refused(&text));
    let vel = "{ index = 0x606C, subindex = 0, bits = 32 }";
    let text = format!(
        "{}{}",
        bus("", "", ""),
        spindle_drive(&tx(&format!("{SW}, {vel}")))
    );
    let b = bus_config(&text);
    assert_eq!(
        b.spindle_drive().unwrap().tx_pdo.bit_offset(0x606C, 0),
        Some((16, 32))
    );
}

#[test]
fn pdo_entries_are_sized_aligned_and_listed_once() {
    let cases: Vec<(String, &str, String)> = vec![
        (
            rx(&format!("{CW}, {TP}, {{ index = 0x2000, subindex = 0, bits = 12 }}")),
            "12 }",
            "`ethercat.drives[0].rx_pdo[2].bits` must be 1, 8, 16, 32 or 64, found 12".into(),
        ),
        (
            rx(&format!("{CW}, {TP}, {{ index = 0, subindex = 0, bits = 65 }}")),
            "65 }",
            "`ethercat.drives[0].rx_pdo[2].bits` of a gap must be 1 to 64, found 65".into(),
        ),
        (
            rx(&format!("{CW}, {TP}, {{ index = 0, subindex = 3, bits = 8 }}")),
            "3, bits = 8",
            "`ethercat.drives[0].rx_pdo[2]` is a gap (index 0): its subindex must be 0, found 3".into(),
        ),
        (
            rx(&format!("{CW}, {{ index = 0x2000, subindex = 0, bits = 1 }}, {TP}, {{ index = 0, subindex = 0, bits = 7 }}")),
            "32 }, { index = 0, subindex = 0, bits = 7",
            "`ethercat.drives[0].rx_pdo[2]` (0x607A:0, 32 bits) starts at bit 17: an entry of 8 bits or more must start on a whole byte; put a gap { index = 0, subindex = 0, bits = 7 } before it".into(),
        ),
        (
            rx(&format!("{CW}, {TP}, {{ index = 0x6040, subindex = 0, bits = 16 }}")),
            "0x6040, subindex = 0, bits = 16 }]",
            "`ethercat.drives[0].rx_pdo[2]` maps 0x6040:0 again (it is `ethercat.drives[0].rx_pdo[0]`)".into(),
        ),
        (
            rx(&format!("{CW}, {TP}, {{ index = 0x10000, subindex = 0, bits = 8 }}")),
            "0x10000",
            "`ethercat.drives[0].rx_pdo[2].index` must be an object index (0: a gap) from 0x0 to 0xFFFF, found 0x10000".into(),
        ),
        (
            rx(&format!("{CW}, {TP}, {{ index = 0x2000, subindex = 256, bits = 8 }}")),
            "256",
            "`ethercat.drives[0].rx_pdo[2].subindex` must be a subindex from 0 to 255, found 256".into(),
        ),
        (
            "rx_pdo_index = 0x1A00\n".to_string(),
            "0x1A00",
            "`ethercat.drives[0].rx_pdo_index` must be a PDO mapping object from 0x1600 to 0x17FF, found 0x1A00".into(),
        ),
        (
            "tx_pdo_index = 0x1C00\n".to_string(),
            "0x1C00",
            "`ethercat.drives[0].tx_pdo_index` must be a PDO mapping object from 0x1A00 to 0x1BFF, found 0x1C00".into(),
        ),
    ];
    for (x, needle, message) in cases {
        let text = bus("", &x, "");
        assert_eq!(
            refused(&text),
            format!("{}{message}", at(&text, needle)),
            "{x}"
        );
    }
}

#[test]
fn a_pdo_is_whole_bytes_within_its_bounds() {
    // 49 bits: one bit too many for whole bytes.
    let x = rx(&format!(
        "{CW}, {TP}, {{ index = 0x2000, subindex = 0, bits = 1 }}"
    ));
    let text = bus("", &x, "");
    assert_eq!(
        refused(&text),
        format!(
            "{}`ethercat.drives[0].rx_pdo` maps 49 bits; a PDO must be a whole number of bytes; end it with a gap {{ index = 0, subindex = 0, bits = 7 }}",
            at(&text, "[{ index")
        )
    );
    let text = bus("", "rx_pdo = []\n", "");
    assert_eq!(
        refused(&text),
        format!(
            "{}`ethercat.drives[0].rx_pdo` must list 1 to 64 entries, found 0",
            at(&text, "[]")
        )
    );
    // 64 entries are accepted (62 bytes of vendor objects after the two needed), 65 not.
    let fill = |n: usize| {
        (0..n)
            .map(|i| format!("{{ index = 0x2000, subindex = {}, bits = 8 }}", i + 1))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let b = bus_config(&bus("", &rx(&format!("{CW}, {TP}, {}", fill(62))), ""));
    assert_eq!(b.drives[0].rx_pdo.entries.len(), 64);
    assert_eq!(b.drives[0].rx_pdo.size_bytes(), 68);
    let text = bus("", &rx(&format!("{CW}, {TP}, {}", fill(63))), "");
    assert!(
        refused(&text).ends_with("`ethercat.drives[0].rx_pdo` must list 1 to 64 entries, found 65"),
        "{}",
        refused(&text)
    );
    // 256 bytes are accepted, 264 not: 64-bit objects, 6 + 31 × 8 = 254 bytes, then a gap.
    let wide = |n: usize| {
        (0..n)
            .map(|i| format!("{{ index = 0x2100, subindex = {}, bits = 64 }}", i + 1))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let b = bus_config(&bus(
        "",
        &rx(&format!(
            "{CW}, {TP}, {}, {{ index = 0, subindex = 0, bits = 16 }}",
            wide(31)
        )),
        "",
    ));
    assert_eq!(b.drives[0].rx_pdo.size_bytes(), 256);
    let text = bus(
        "",
        &rx(&format!(
            "{CW}, {TP}, {}, {{ index = 0, subindex = 0, bits = 16 }}",
            wide(32)
        )),
        "",
    );
    assert!(
        refused(&text).ends_with("maps 2112 bits; a PDO must be at most 256 bytes"),
        "{}",
        refused(&text)
    );
}

#[test]
fn an_object_is_either_output_or_input() {
    let x = rx(&format!(
        "{CW}, {TP}, {{ index = 0x6064, subindex = 0, bits = 32 }}"
    ));
    let text = bus("", &x, "");
    assert_eq!(
        refused(&text),
        format!(
            "{}`ethercat.drives[0]` maps 0x6064:0 both in `rx_pdo` and in `tx_pdo`",
            at(&text, "[{ index")
        )
    );
}

/// Every SDO type accepts its least and greatest value and refuses one past either.
#[test]
fn sdo_values_are_checked_against_their_type_at_every_boundary() {
    let types: [(&str, i64, i64); 6] = [
        ("u8", 0, 255),
        ("u16", 0, 65_535),
        ("u32", 0, 4_294_967_295),
        ("i8", -128, 127),
        ("i16", -32_768, 32_767),
        ("i32", -2_147_483_648, 2_147_483_647),
    ];
    for (ty, lo, hi) in types {
        for v in [lo, hi, (lo + hi) / 2] {
            let x = format!(
                "sdo = [{{ index = 0x2000, subindex = 1, type = \"{ty}\", value = {v} }}]\n"
            );
            let b = bus_config(&bus("", &x, ""));
            let w = b.drives[0].sdo[0];
            assert_eq!((w.index, w.subindex), (0x2000, 1));
            let bytes = w.value.to_le_bytes();
            let width = ty[1..].parse::<usize>().unwrap() / 8;
            assert_eq!(bytes.len(), width, "{ty}");
            // The bytes read back as the value, little-endian, sign-extended for iN.
            let mut wide = [if v < 0 { 0xFF } else { 0 }; 8];
            wide[..width].copy_from_slice(&bytes);
            assert_eq!(i64::from_le_bytes(wide), v, "{ty} {v}");
        }
        for v in [lo - 1, hi + 1] {
            let x = format!(
                "sdo = [{{ index = 0x2000, subindex = 1, type = \"{ty}\", value = {v} }}]\n"
            );
            let text = bus("", &x, "");
            assert_eq!(
                refused(&text),
                format!(
                    "{}`ethercat.drives[0].sdo[0].value` must be a {ty} from {lo} to {hi}, found {v}",
                    at(&text, &format!("{v} }}"))
                )
            );
        }
    }
    // The writes keep their order, on drives and I/O alike.
    let x = "sdo = [{ index = 0x2000, subindex = 2, type = \"u8\", value = 7 }, { index = 0x2000, subindex = 1, type = \"i8\", value = -7 }]\n";
    let b = bus_config(&bus("", x, x));
    for list in [&b.drives[0].sdo, &b.io[0].sdo] {
        assert_eq!(
            list[0],
            SdoWrite {
                index: 0x2000,
                subindex: 2,
                value: SdoValue::U8(7)
            }
        );
        assert_eq!(
            list[1],
            SdoWrite {
                index: 0x2000,
                subindex: 1,
                value: SdoValue::I8(-7)
            }
        );
    }
}

#[test]
fn sdo_entries_name_a_type_an_object_and_not_what_the_bring_up_sets() {
    let sdo = |index: &str, sub: &str, ty: &str| {
        format!("sdo = [{{ index = {index}, subindex = {sub}, type = \"{ty}\", value = 1 }}]\n")
    };
    let cases = [
        (
            sdo("0x2000", "0", "u64"),
            "\"u64\"",
            "`ethercat.drives[0].sdo[0].type` must be one of u8, u16, u32, i8, i16, i32, found `u64`",
        ),
        (
            sdo("0x0FFF", "0", "u8"),
            "0x0FFF",
            "`ethercat.drives[0].sdo[0].index` must be an object index from 0x1000 to 0xFFFF, found 0xFFF",
        ),
        (
            sdo("0x2000", "256", "u8"),
            "256",
            "`ethercat.drives[0].sdo[0].subindex` must be a subindex from 0 to 255, found 256",
        ),
        (
            sdo("0x6060", "0", "i8"),
            "0x6060",
            "`ethercat.drives[0].sdo[0]` writes 0x6060, which the bring-up sets from `mode`; set it there",
        ),
        (
            sdo("0x60C2", "1", "u8"),
            "0x60C2",
            "`ethercat.drives[0].sdo[0]` writes 0x60C2, which the bring-up sets from `period_us`; set it there",
        ),
        (
            sdo("0x1C12", "0", "u8"),
            "0x1C12",
            "`ethercat.drives[0].sdo[0]` writes 0x1C12, which the bring-up sets from `rx_pdo_index`; set it there",
        ),
        (
            sdo("0x1C13", "0", "u8"),
            "0x1C13",
            "`ethercat.drives[0].sdo[0]` writes 0x1C13, which the bring-up sets from `tx_pdo_index`; set it there",
        ),
        (
            sdo("0x1600", "1", "u32"),
            "0x1600",
            "`ethercat.drives[0].sdo[0]` writes 0x1600, which the bring-up sets from `rx_pdo`; set it there",
        ),
        (
            sdo("0x1A00", "0", "u8"),
            "0x1A00",
            "`ethercat.drives[0].sdo[0]` writes 0x1A00, which the bring-up sets from `tx_pdo`; set it there",
        ),
    ];
    for (x, needle, message) in cases {
        let text = bus("", &x, "");
        assert_eq!(
            refused(&text),
            format!("{}{message}", at(&text, needle)),
            "{x}"
        );
    }
    // A mapping object the drive does not use is the user's to write; on an I/O
    // subdevice the PDO assignment is too (a terminal's PDO selection).
    bus_config(&bus(
        "",
        &sdo("0x1601", "0", "u8"),
        &sdo("0x1C12", "0", "u8"),
    ));
}

#[test]
fn io_bits_are_named_once_on_the_bus_and_numbered_once_per_direction() {
    let b = bus_config(&bus(
        "",
        "",
        "inputs = { in_b = 5, in_a = 2047, in_c = 0 }\noutputs = { out_a = 0, out_b = 2047 }\n",
    ));
    let names: Vec<(&str, u16)> = b.io[0]
        .inputs
        .iter()
        .map(|b| (b.name.as_str(), b.bit))
        .collect();
    assert_eq!(names, [("in_c", 0), ("in_b", 5), ("in_a", 2047)]);
    let names: Vec<(&str, u16)> = b.io[0]
        .outputs
        .iter()
        .map(|b| (b.name.as_str(), b.bit))
        .collect();
    assert_eq!(names, [("out_a", 0), ("out_b", 2047)]);
    let cases = [
        (
            "inputs = { a = 2048 }\n",
            "2048",
            "`ethercat.io[0].inputs.a` must be a bit number from 0 to 2047, found 2048",
        ),
        (
            "inputs = { a = -1 }\n",
            "-1 }",
            "`ethercat.io[0].inputs.a` must be a bit number from 0 to 2047, found -1",
        ),
        (
            "inputs = { a = 3, b = 3 }\n",
            "3 }",
            "`ethercat.io[0].inputs.b` and `ethercat.io[0].inputs.a` are both bit 3",
        ),
        (
            "inputs = { a = 3 }\noutputs = { a = 4 }\n",
            "4 }",
            "the bit name `a` is used twice on the bus: `ethercat.io[0].inputs.a` and `ethercat.io[0].outputs.a`",
        ),
        (
            "inputs = { 1a = 3 }\n",
            "3 }",
            "`ethercat.io[0].inputs.1a`: a bit's name must be 1 to 64 ASCII letters, digits, `_` or `-`, starting with a letter",
        ),
        (
            "inputs = { \"door open\" = 3 }\n",
            "3 }",
            "`ethercat.io[0].inputs.door open`: a bit's name must be 1 to 64 ASCII letters, digits, `_` or `-`, starting with a letter",
        ),
    ];
    for (io, needle, message) in cases {
        let text = bus("", "", io);
        assert_eq!(
            refused(&text),
            format!("{}{message}", at(&text, needle)),
            "{io}"
        );
    }
    // Input bit 3 and output bit 3 are different bits.
    bus_config(&bus("", "", "inputs = { a = 3 }\noutputs = { b = 3 }\n"));
}

#[test]
fn names_are_unique_across_io_subdevices_and_a_coupler_has_no_bits() {
    let text = bus("", "", "inputs = { probe = 0 }\n").replace(
        "[[ethercat.io]]\nposition = 3",
        "[[ethercat.io]]\nposition = 4",
    ) + "[[ethercat.io]]\nposition = 3\nvendor_id = 0x2\nproduct_code = 0x044C2C52\n";
    let b = bus_config(&text);
    // The coupler (EK1100) has no bits.
    assert!(b.io[1].inputs.is_empty() && b.io[1].outputs.is_empty());
    let text = text
        + "[[ethercat.io]]\nposition = 5\nvendor_id = 0x2\nproduct_code = 0x07433052\noutputs = { probe = 1 }\n";
    assert_eq!(
        refused(&text),
        format!(
            "{}the bit name `probe` is used twice on the bus: `ethercat.io[0].inputs.probe` and `ethercat.io[2].outputs.probe`",
            at(&text, "1 }")
        )
    );
}
