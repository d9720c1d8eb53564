//! `[ethercat]`'s tests: the example file's typed view, the bus settings, the drives'
//! axes and ring positions, the axes' drive tables with a bus. The values expected are
//! the file's, written out by hand, and the CiA 402 / CoE numbers from the standards.

use std::path::Path;

use crate::ethercat::*;
use crate::*;

/// Three linear axes at a 1 ms period.
pub(crate) const AXES: &str = r#"period_us = 1000
[axes.x]
velocity_mm_s = 100.0
acceleration_mm_s2 = 1000.0
jerk_mm_s3 = 10000.0
min_mm = -10.0
max_mm = 10.0
[axes.y]
velocity_mm_s = 100.0
acceleration_mm_s2 = 1000.0
jerk_mm_s3 = 10000.0
min_mm = -10.0
max_mm = 10.0
[axes.z]
velocity_mm_s = 100.0
acceleration_mm_s2 = 1000.0
jerk_mm_s3 = 10000.0
min_mm = -10.0
max_mm = 10.0
"#;

/// A bus of three drives (X, Y, Z at 0, 1, 2) and an I/O subdevice (3), with `top`
/// added to `[ethercat]`, `x` to the X drive and `io` to the I/O subdevice.
pub(crate) fn bus(top: &str, x: &str, io: &str) -> String {
    format!(
        "{AXES}[ethercat]\ninterface = \"eth0\"\n{top}\
         [[ethercat.drives]]\naxis = \"x\"\nposition = 0\nvendor_id = 0x2\nproduct_code = 0x402\n{x}\
         [[ethercat.drives]]\naxis = \"y\"\nposition = 1\nvendor_id = 0x2\nproduct_code = 0x402\n\
         [[ethercat.drives]]\naxis = \"z\"\nposition = 2\nvendor_id = 0x2\nproduct_code = 0x402\n\
         [[ethercat.io]]\nposition = 3\nvendor_id = 0x2\nproduct_code = 0x07433052\n{io}"
    )
}

/// A spindle drive (`axis = "s"`) at position 4, after [`bus`]'s subdevices, with
/// `extra` keys.
pub(crate) fn spindle_drive(extra: &str) -> String {
    format!(
        "[[ethercat.drives]]\naxis = \"s\"\nposition = 4\nvendor_id = 0x2\nproduct_code = 0x402\n{extra}"
    )
}

pub(crate) fn load(text: &str) -> Result<Config, String> {
    Config::from_toml_str(text, "m.toml").map_err(|e| e.to_string())
}

pub(crate) fn bus_config(text: &str) -> EthercatConfig {
    match load(text) {
        Ok(c) => c.ethercat.expect("an [ethercat] table"),
        Err(e) => panic!("refused: {e}\n{text}"),
    }
}

pub(crate) fn refused(text: &str) -> String {
    match load(text) {
        Ok(_) => panic!("accepted:\n{text}"),
        Err(e) => e,
    }
}

/// The error prefix for the `nth` (0-based) occurrence of `needle` in `text`, its line
/// and column counted here by hand.
pub(crate) fn at_nth(text: &str, needle: &str, nth: usize) -> String {
    let offset = text
        .match_indices(needle)
        .nth(nth)
        .unwrap_or_else(|| panic!("`{needle}` not in the text"))
        .0;
    let before = &text[..offset];
    let line = before.lines().count() + usize::from(before.ends_with('\n') || before.is_empty());
    let col = offset - before.rfind('\n').map_or(0, |i| i + 1) + 1;
    format!("m.toml:{line}:{col}: error: ")
}

pub(crate) fn at(text: &str, needle: &str) -> String {
    at_nth(text, needle, 0)
}

fn example() -> Config {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/ethercat-example.toml");
    Config::load(&path).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn the_example_file_loads_into_the_bus_it_describes() {
    let c = example();
    assert_eq!(c.check_drives(), Ok(()));
    let bus = c.ethercat().expect("[ethercat]");
    assert_eq!(bus.interface, "eth1");
    assert!(bus.dc);
    assert_eq!(bus.sync0_shift_ns, 500_000);
    assert_eq!(bus.max_missed_cycles, 2);
    assert_eq!(bus.watchdog_us, 20_000);
    // 20 ms in the ESC's 100 µs watchdog units.
    assert_eq!(bus.watchdog_intervals(), 200);
    assert_eq!(bus.subdevices(), 5);
    let axes: Vec<(usize, u16)> = bus
        .drives
        .iter()
        .map(|d| (d.axis_index, d.position))
        .collect();
    assert_eq!(axes, [(0, 0), (1, 1), (2, 2), (SPINDLE_AXIS_INDEX, 3)]);
    let spindle = bus.spindle_drive().expect("the spindle's drive");
    assert_eq!(spindle.mode, DriveMode::Csv);
    assert_eq!(
        (spindle.identity.vendor_id, spindle.identity.product_code),
        (0xECA, 0x402)
    );
    for d in &bus.drives[..3] {
        assert_eq!(
            (d.identity.vendor_id, d.identity.product_code),
            (0xECA, 0x402)
        );
        assert_eq!(d.mode, DriveMode::Csp);
        assert_eq!(d.mode.mode_of_operation(), 8);
        // The CiA 402 CSP mapping of issue 27, in 0x1600 / 0x1A00.
        let rx: Vec<(u16, u8, u8)> = d
            .rx_pdo
            .entries
            .iter()
            .map(|e| (e.index, e.subindex, e.bits))
            .collect();
        assert_eq!(rx, [(0x6040, 0, 16), (0x607A, 0, 32)]);
        assert_eq!(d.rx_pdo.index, 0x1600);
        let tx: Vec<(u16, u8, u8)> = d
            .tx_pdo
            .entries
            .iter()
            .map(|e| (e.index, e.subindex, e.bits))
            .collect();
        assert_eq!(
            tx,
            [
                (0x6041, 0, 16),
                (0x6064, 0, 32),
                (0x606C, 0, 32),
                (0x60F4, 0, 32),
                (0x603F, 0, 16),
                (0x60FD, 0, 32)
            ]
        );
        assert_eq!(d.tx_pdo.index, 0x1A00);
        assert_eq!((d.rx_pdo.size_bytes(), d.tx_pdo.size_bytes()), (6, 20));
        // statusword bits 0..16, position actual 16..48, velocity 48..80, following error
        // 80..112, error code 112..128, digital inputs 128..160.
        assert_eq!(d.tx_pdo.bit_offset(0x6064, 0), Some((16, 32)));
        assert_eq!(d.tx_pdo.bit_offset(0x603F, 0), Some((112, 16)));
        assert_eq!(d.tx_pdo.bit_offset(0x60FD, 0), Some((128, 32)));
        assert_eq!(d.rx_pdo.bit_offset(0x607A, 0), Some((16, 32)));
        assert_eq!(d.rx_pdo.bit_offset(0x6041, 0), None);
    }
    assert_eq!(bus.drives[2].identity.revision, Some(0x0001_0000));
    assert_eq!(bus.drives[0].identity.revision, None);
    // CoE mapping value: index << 16 | subindex << 8 | bits.
    assert_eq!(bus.drives[0].rx_pdo.entries[0].mapping_value(), 0x6040_0010);
    assert_eq!(bus.drives[0].rx_pdo.entries[1].mapping_value(), 0x607A_0020);
    let sdo: Vec<(u16, u8, Vec<u8>)> = bus.drives[0]
        .sdo
        .iter()
        .map(|s| (s.index, s.subindex, s.value.to_le_bytes()))
        .collect();
    assert_eq!(
        sdo,
        [
            (0x6065, 0, vec![0xA0, 0x86, 0x01, 0x00]),
            (0x605A, 0, vec![2, 0]),
            (0x6007, 0, vec![3, 0]),
        ]
    );
    assert!(bus.drives[1].sdo.is_empty());
    let io = &bus.io[0];
    assert_eq!((io.position, io.identity.product_code), (4, 0x1001));
    let bits = |b: &[IoBit]| {
        b.iter()
            .map(|b| (b.name.clone(), b.bit))
            .collect::<Vec<_>>()
    };
    assert_eq!(
        bits(&io.inputs),
        [
            ("estop_ok".to_string(), 0),
            ("door_closed".to_string(), 1),
            ("probe".to_string(), 2)
        ]
    );
    assert_eq!(
        bits(&io.outputs),
        [
            ("coolant".to_string(), 0),
            ("spindle_enable".to_string(), 1)
        ]
    );
    // Every axis's drive is on the bus, with the axis's scale.
    for (i, d) in c.drive.axes.iter().take(3).enumerate() {
        let d = d.expect("axis");
        assert_eq!(d.kind, DriveKind::Ethercat, "axis {i}");
        assert!(d.kind.keeps_time());
    }
    assert_eq!(c.drive.axes[0].unwrap().scale.counts_per_unit(), 10_000.0);
    assert_eq!(c.drive.axes[2].unwrap().scale.direction(), -1);
    assert_eq!(bus.drive_of_axis(2).map(|d| d.position), Some(2));
    assert_eq!(bus.drive_of_axis(3), None);
}

#[test]
fn without_an_ethercat_table_the_drives_are_simulated_as_before() {
    for c in [Config::builtin(), load(AXES).unwrap()] {
        assert_eq!(c.ethercat(), None);
        for d in c.drive.axes.iter().flatten() {
            assert_eq!(d.kind, DriveKind::Sim);
            assert!(!d.kind.keeps_time());
        }
    }
}

#[test]
fn bus_settings_take_their_documented_defaults() {
    let b = bus_config(&bus("", "", ""));
    assert_eq!(b.interface, "eth0");
    assert!(b.dc);
    // Half of the 1 ms period.
    assert_eq!(b.sync0_shift_ns, 500_000);
    assert_eq!(b.max_missed_cycles, 2);
    assert_eq!(b.watchdog_us, 20_000);
    assert_eq!(
        (b.state_timeout_ms, b.sdo_timeout_ms, b.dc_settle_timeout_ms),
        (5000, 1000, 5000)
    );
    let doc: std::collections::HashMap<&str, String> = reference::keys()
        .into_iter()
        .map(|k| (k.key, k.default))
        .collect();
    assert_eq!(doc["ethercat.max_missed_cycles"], "2");
    assert_eq!(doc["ethercat.watchdog_us"], "20000");
    assert_eq!(doc["ethercat.state_timeout_ms"], "5000");
    assert_eq!(doc["ethercat.sdo_timeout_ms"], "1000");
    assert_eq!(doc["ethercat.dc_settle_timeout_ms"], "5000");
    assert_eq!(doc["ethercat.dc"], "true");
    assert_eq!(
        doc["ethercat.drives.mode"],
        "\"csp\"; \"csv\" for the spindle"
    );
    // At a 125 µs period the default shift is 62.5 µs.
    let b = bus_config(&bus("", "", "").replace("period_us = 1000", "period_us = 125"));
    assert_eq!(b.sync0_shift_ns, 62_500);
    let b = bus_config(&bus("dc = false\n", "", ""));
    assert!(!b.dc);
    // Without distributed clocks there is no SYNC0 to shift.
    let text = bus("dc = false\nsync0_shift_ns = 1000\n", "", "");
    assert_eq!(
        refused(&text),
        format!(
            "{}`ethercat.sync0_shift_ns` shifts SYNC0, which runs only with distributed clocks: remove it or set `ethercat.dc = true`",
            at(&text, "1000\n[[")
        )
    );
}

/// Each integer setting accepted at both ends of its range and refused one past them,
/// the message naming the key, the range and the value at its place.
#[test]
fn bus_settings_are_range_checked_on_both_sides() {
    // (key, accepted, refused, the message's range)
    let cases: &[(&str, &[&str], &[&str], &str)] = &[
        (
            "sync0_shift_ns",
            &["0", "999999"],
            &["1000000", "-1"],
            "a time in ns below the period from 0 to 999999",
        ),
        (
            "max_missed_cycles",
            &["1", "1000"],
            &["0", "1001"],
            "a number of cycles from 1 to 1000",
        ),
        (
            "watchdog_us",
            &["2000", "6553500"],
            &["1900", "6553600"],
            "a time in µs (2 periods or more) from 2000 to 6553500",
        ),
        (
            "state_timeout_ms",
            &["1", "60000"],
            &["0", "60001"],
            "a time in ms from 1 to 60000",
        ),
        (
            "sdo_timeout_ms",
            &["1", "60000"],
            &["0", "60001"],
            "a time in ms from 1 to 60000",
        ),
        (
            "dc_settle_timeout_ms",
            &["1", "60000"],
            &["0", "60001"],
            "a time in ms from 1 to 60000",
        ),
    ];
    for (key, good, bad, range) in cases {
        for v in *good {
            bus_config(&bus(&format!("{key} = {v}\n"), "", ""));
        }
        for v in *bad {
            let text = bus(&format!("{key} = {v}\n"), "", "");
            assert_eq!(
                refused(&text),
                format!(
                    "{}`ethercat.{key}` must be {range}, found {v}",
                    at(&text, &format!("{v}\n[[ethercat.drives]]"))
                )
            );
        }
    }
}

#[test]
fn the_watchdog_is_whole_units_and_at_least_two_periods() {
    let text = bus("watchdog_us = 2050\n", "", "");
    assert_eq!(
        refused(&text),
        format!(
            "{}`ethercat.watchdog_us` must be a multiple of 100 µs (the subdevices' watchdog unit), found 2050",
            at(&text, "2050")
        )
    );
    // At a 4 ms period the least is 8 ms.
    let slow = bus("watchdog_us = 7900\n", "", "").replace("period_us = 1000", "period_us = 4000");
    assert!(
        refused(&slow).contains("from 8000 to 6553500, found 7900"),
        "{}",
        refused(&slow)
    );
    // A period so long that the default watchdog is under two periods: the file must say.
    let text = bus("", "", "").replace("period_us = 1000", "period_us = 10050");
    assert_eq!(
        refused(&text),
        "m.toml: error: the default `ethercat.watchdog_us` (20000 µs) is shorter than 2 periods (`period_us` = 10050): set `ethercat.watchdog_us` to at least 20100"
    );
    let text =
        bus("watchdog_us = 20100\n", "", "").replace("period_us = 1000", "period_us = 10050");
    assert_eq!(bus_config(&text).watchdog_intervals(), 201);
}

#[test]
fn the_interface_is_required_and_a_network_interface_name() {
    let text = bus("", "", "").replace("interface = \"eth0\"\n", "");
    assert!(
        refused(&text).contains("missing key `ethercat.interface`"),
        "{}",
        refused(&text)
    );
    for bad in ["", "a/b", "eth 0", "enp3s0f1.100xyzw", ".", "eth0:1"] {
        let text = bus("", "", "").replace("\"eth0\"", &format!("\"{bad}\""));
        assert_eq!(
            refused(&text),
            format!(
                "{}`ethercat.interface` must be a network interface name (1 to 15 characters, no `/`, `:` or spaces), found `{bad}`",
                at(&text, &format!("\"{bad}\""))
            )
        );
    }
    for good in ["e", "enp3s0f1.100xyz", "veth-kerf_1"] {
        let text = bus("", "", "").replace("\"eth0\"", &format!("\"{good}\""));
        assert_eq!(bus_config(&text).interface, good);
    }
}

#[test]
fn unknown_and_mistyped_keys_are_named_in_the_bus_tables() {
    let text = bus("period_ms = 1\n", "", "");
    assert!(
        refused(&text).contains("unknown key `ethercat.period_ms`"),
        "{}",
        refused(&text)
    );
    let text = bus("", "scale = 2\n", "");
    assert!(
        refused(&text).contains("unknown key `ethercat.drives[0].scale`"),
        "{}",
        refused(&text)
    );
    let text = bus("", "", "name = \"in\"\n");
    assert!(
        refused(&text).contains("unknown key `ethercat.io[0].name`"),
        "{}",
        refused(&text)
    );
    let text = bus("dc = 1\n", "", "");
    assert_eq!(
        refused(&text),
        format!(
            "{}`ethercat.dc` must be true or false, found 1",
            at(&text, "1\n[[ethercat")
        )
    );
    let text = bus("", "", "").replacen("product_code = 0x402\n", "", 1);
    assert!(
        refused(&text).contains("missing key `ethercat.drives[0].product_code`"),
        "{}",
        refused(&text)
    );
}

#[test]
fn every_configured_axis_has_exactly_one_drive() {
    // An axis that does not exist at all.
    let text = bus("", "", "").replace("axis = \"x\"", "axis = \"w\"");
    assert_eq!(
        refused(&text),
        format!(
            "{}`ethercat.drives[0].axis` must be one of the configured axes x, y, z, or s for the spindle, found `w`",
            at(&text, "\"w\"")
        )
    );
    // A rotary axis the machine does not have.
    let text = bus("", "", "").replace("axis = \"x\"", "axis = \"a\"");
    assert_eq!(
        refused(&text),
        format!(
            "{}`ethercat.drives[0].axis` must be one of the configured axes x, y, z, or s for the spindle, found `a` (the file has no [axes.a])",
            at(&text, "\"a\"")
        )
    );
    // Two drives for Y, none for X.
    let text = bus("", "", "").replace("axis = \"x\"", "axis = \"y\"");
    assert_eq!(
        refused(&text),
        format!(
            "{}axis y has two drives: `ethercat.drives[1]` and `ethercat.drives[0]`; each axis has one",
            at_nth(&text, "\"y\"", 1)
        )
    );
    // No drive for Z: three subdevices listed, Z's drive is not among them.
    let text = bus("", "", "").replace(
        "[[ethercat.drives]]\naxis = \"z\"\nposition = 2\nvendor_id = 0x2\nproduct_code = 0x402\n",
        "",
    ).replace("position = 3", "position = 2");
    assert_eq!(
        refused(&text),
        format!(
            "{}axis z has no drive: with [ethercat], every configured axis needs a [[ethercat.drives]] with `axis = \"z\"`",
            at(&text, "[ethercat]")
        )
    );
    // Upper case names the same axis.
    let b = bus_config(&bus("", "", "").replace("axis = \"x\"", "axis = \"X\""));
    assert_eq!(b.drives[0].axis_index, 0);
}

#[test]
fn a_rotary_axis_needs_its_drive_on_the_bus_too() {
    let rotary = "[axes.c]\nvelocity_deg_s = 360.0\nacceleration_deg_s2 = 3600.0\njerk_deg_s3 = 90000.0\nmin_deg = -720.0\nmax_deg = 720.0\n";
    let text = bus("", "", "").replace("[ethercat]\n", &format!("{rotary}[ethercat]\n"));
    assert!(
        refused(&text).contains("axis c has no drive"),
        "{}",
        refused(&text)
    );
    let text = text.replace("position = 3", "position = 4")
        + "[[ethercat.drives]]\naxis = \"c\"\nposition = 3\nvendor_id = 0x2\nproduct_code = 0x402\n";
    let b = bus_config(&text);
    assert_eq!(b.drive_of_axis(5).map(|d| d.position), Some(3));
}

#[test]
fn ring_positions_are_unique_and_without_gaps() {
    let text = bus("", "", "").replace("position = 3", "position = 1");
    assert_eq!(
        refused(&text),
        format!(
            "{}`ethercat.io[0].position` = 1 is also the position of `ethercat.drives[1]`; each subdevice has its own",
            at(&text, "1\nvendor_id = 0x2\nproduct_code = 0x07433052")
        )
    );
    let text = bus("", "", "").replace("position = 3", "position = 4");
    assert_eq!(
        refused(&text),
        format!(
            "{}`ethercat.io[0].position` = 4 but the bus lists 4 subdevices, so positions are 0 to 3: nothing is at position 3. List every subdevice on the ring (a coupler as an [[ethercat.io]] without bits)",
            at(&text, "4\nvendor_id")
        )
    );
    for bad in ["-1", "65535"] {
        let text = bus("", "", "").replace("position = 3", &format!("position = {bad}"));
        assert_eq!(
            refused(&text),
            format!(
                "{}`ethercat.io[0].position` must be a ring position from 0 to 65534, found {bad}",
                at(&text, &format!("{bad}\n"))
            )
        );
    }
}

/// Every assignment of the four ring positions to the three drives and the I/O
/// subdevice is accepted as written; every assignment with a position beyond 3 is
/// refused.
#[test]
fn every_permutation_of_positions_is_accepted_and_every_gap_refused() {
    let base = bus("", "", "");
    let mut perm = [0u16, 1, 2, 3];
    let mut seen = 0;
    // Heap's algorithm over the 24 permutations.
    let mut c = [0usize; 4];
    let mut check = |p: &[u16; 4]| {
        let text = base
            .replacen("position = 0", "position = P0", 1)
            .replacen("position = 1", "position = P1", 1)
            .replacen("position = 2", "position = P2", 1)
            .replacen("position = 3", "position = P3", 1);
        let text = (0..4).fold(text, |t, i| t.replace(&format!("P{i}"), &p[i].to_string()));
        let b = bus_config(&text);
        let got: Vec<u16> = b
            .drives
            .iter()
            .map(|d| d.position)
            .chain(b.io.iter().map(|io| io.position))
            .collect();
        assert_eq!(got, p.to_vec());
        for gap in 4..7u16 {
            let bad = text.replacen(
                &format!("position = {}", p[3]),
                &format!("position = {gap}"),
                1,
            );
            assert!(
                refused(&bad).contains("nothing is at position"),
                "{}",
                refused(&bad)
            );
        }
        seen += 1;
    };
    check(&perm);
    let mut i = 0;
    while i < 4 {
        if c[i] < i {
            if i % 2 == 0 {
                perm.swap(0, i)
            } else {
                perm.swap(c[i], i)
            }
            check(&perm);
            c[i] += 1;
            i = 0;
        } else {
            c[i] = 0;
            i += 1;
        }
    }
    assert_eq!(seen, 24);
}

#[test]
fn identities_are_32_bit_numbers_written_in_hex_or_decimal() {
    let b = bus_config(&bus("", "revision = 0xFFFFFFFF\n", "").replace(
        "vendor_id = 0x2\nproduct_code = 0x402\nrevision",
        "vendor_id = 4294967295\nproduct_code = 0\nrevision",
    ));
    assert_eq!(
        b.drives[0].identity,
        Identity {
            vendor_id: u32::MAX,
            product_code: 0,
            revision: Some(u32::MAX)
        }
    );
    for (bad, found) in [("0x100000000", "0x100000000"), ("-1", "-1")] {
        let text = bus("", &format!("revision = {bad}\n"), "");
        assert_eq!(
            refused(&text),
            format!(
                "{}`ethercat.drives[0].revision` must be a 32-bit number from 0x0 to 0xFFFFFFFF, found {found}",
                at(&text, &format!("{bad}\n[["))
            )
        );
    }
    let text = bus("", "", "").replace("product_code = 0x07433052", "product_code = -5");
    assert!(
        refused(&text).contains("`ethercat.io[0].product_code` must be a 32-bit number"),
        "{}",
        refused(&text)
    );
}

#[test]
fn the_axes_drive_tables_agree_with_the_bus() {
    // kind = "ethercat" needs the bus.
    let text = AXES.replace("[axes.y]", "[axes.x.drive]\nkind = \"ethercat\"\n[axes.y]");
    assert_eq!(
        refused(&text),
        format!(
            "{}`axes.x.drive.kind` is \"ethercat\" but the file has no [ethercat] table with a [[ethercat.drives]] for axis x",
            at(&text, "\"ethercat\"")
        )
    );
    // With the bus, "ethercat" is accepted and "sim" refused.
    let with_kind = |kind: &str| {
        bus("", "", "").replace(
            "[axes.y]",
            &format!("[axes.x.drive]\nkind = \"{kind}\"\ncounts_per_mm = 500.0\n[axes.y]"),
        )
    };
    let c = load(&with_kind("ethercat")).unwrap();
    assert_eq!(c.drive.axes[0].unwrap().kind, DriveKind::Ethercat);
    assert_eq!(c.drive.axes[0].unwrap().scale.counts_per_unit(), 500.0);
    let text = with_kind("sim");
    assert_eq!(
        refused(&text),
        format!(
            "{}`axes.x.drive.kind` is \"sim\" but axis x is driven over EtherCAT (the drive at position 0); remove `kind` or make it \"ethercat\"",
            at(&text, "\"sim\"")
        )
    );
    // The simulated drive's tuning has no meaning for a real drive.
    for (key, value) in [
        ("bandwidth_hz", "50.0"),
        ("damping", "1.0"),
        ("inertia_ratio", "1.0"),
        ("velocity_feed_forward", "1.0"),
        ("substeps", "20"),
        ("overcurrent_accel_counts_s2", "1e9"),
        ("quick_stop_decel_counts_s2", "1e6"),
        ("following_error_window_counts", "1000"),
    ] {
        let text = bus("", "", "").replace(
            "[axes.z]",
            &format!("[axes.y.drive]\n{key} = {value}\n[axes.z]"),
        );
        assert_eq!(
            refused(&text),
            format!(
                "{}`axes.y.drive.{key}` tunes the simulated drive, but axis y is driven over EtherCAT (the drive at position 1); remove it",
                at(&text, &format!("{value}\n[axes.z]"))
            )
        );
    }
    // The keys a real drive shares are accepted.
    let text = bus("", "", "").replace(
        "[axes.z]",
        "[axes.y.drive]\ndirection = -1\nenable_timeout_ms = 3000\n[axes.z]",
    );
    let c = load(&text).unwrap();
    assert_eq!(c.drive.axes[1].unwrap().enable_timeout_ms, 3000);
    assert_eq!(c.drive.axes[1].unwrap().scale.direction(), -1);
}

#[test]
fn a_drive_mode_is_csp_for_an_axis_and_csv_for_the_spindle() {
    // The spindle's drive runs in csv whether `mode` says so or not.
    for mode in ["", "mode = \"csv\"\n"] {
        let text = format!("{}{}", bus("", "", ""), spindle_drive(mode));
        let b = bus_config(&text);
        let s = b.spindle_drive().expect("the spindle's drive");
        assert_eq!(s.axis_index, SPINDLE_AXIS_INDEX);
        assert_eq!(s.axis_index, 6);
        assert_eq!(s.position, 4);
        assert_eq!(s.mode, DriveMode::Csv);
        assert_eq!(s.mode.mode_of_operation(), 9);
        // CiA 402: controlword 0x6040, target velocity 0x60FF.
        let rx: Vec<(u16, u8, u8)> = s
            .rx_pdo
            .entries
            .iter()
            .map(|e| (e.index, e.subindex, e.bits))
            .collect();
        assert_eq!(rx, [(0x6040, 0, 16), (0x60FF, 0, 32)]);
        assert_eq!(b.drives[1].mode, DriveMode::Csp);
        assert_eq!(b.subdevices(), 5);
    }
    let b = bus_config(&bus("", "", ""));
    assert_eq!(b.spindle_drive(), None);
    // An axis in csv, the spindle in csp: refused at the mode.
    let text = bus("", "mode = \"csv\"\n", "");
    assert_eq!(
        refused(&text),
        format!(
            "{}`ethercat.drives[0].mode` is \"csv\" (cyclic synchronous velocity), which only the spindle's drive (`axis = \"s\"`) runs; axis x runs in \"csp\"",
            at(&text, "\"csv\"")
        )
    );
    let text = format!("{}{}", bus("", "", ""), spindle_drive("mode = \"csp\"\n"));
    assert_eq!(
        refused(&text),
        format!(
            "{}`ethercat.drives[3].mode` is \"csp\" but the drive is the spindle's (`axis = \"s\"`), which runs in cyclic synchronous velocity: make it \"csv\" or remove it",
            at(&text, "\"csp\"")
        )
    );
    // One spindle drive.
    let text = format!(
        "{}{}{}",
        bus("", "", ""),
        spindle_drive(""),
        spindle_drive("").replace("position = 4", "position = 5")
    );
    assert_eq!(
        refused(&text),
        format!(
            "{}the spindle has two drives: `ethercat.drives[4]` and `ethercat.drives[3]`; it has one",
            at_nth(&text, "\"s\"", 1)
        )
    );
    let text = bus("", "mode = \"pp\"\n", "");
    assert_eq!(
        refused(&text),
        format!(
            "{}`ethercat.drives[0].mode` must be \"csp\" (cyclic synchronous position) or \"csv\" (cyclic synchronous velocity), found `pp`",
            at(&text, "\"pp\"")
        )
    );
}
