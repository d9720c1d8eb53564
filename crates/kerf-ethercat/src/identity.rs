//! The comparison of the subdevices found on the bus with the ones configured, reported
//! as a machine builder reads it: one line per position, found against expected.

use kerf_config::ethercat::Identity;

/// A subdevice the configuration expects: its position, a name for messages ("X drive",
/// "I/O") and its identity.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Expected {
    /// Ring position.
    pub position: u16,
    /// Name for messages.
    pub name: String,
    /// Identity.
    pub identity: Identity,
}

/// A subdevice as found by the scan.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Found {
    /// Ring position.
    pub position: u16,
    /// Name from its SII.
    pub name: String,
    /// Vendor ID.
    pub vendor_id: u32,
    /// Product code.
    pub product_code: u32,
    /// Revision.
    pub revision: u32,
    /// Serial number.
    pub serial: u32,
}

fn matches(found: &Found, expected: &Identity) -> bool {
    found.vendor_id == expected.vendor_id
        && found.product_code == expected.product_code
        && expected.revision.is_none_or(|r| r == found.revision)
}

fn describe_found(f: &Found) -> String {
    format!(
        "{:?} vendor {:#010x} product {:#010x} revision {:#010x}",
        f.name, f.vendor_id, f.product_code, f.revision
    )
}

fn describe_expected(e: &Expected) -> String {
    let revision = match e.identity.revision {
        Some(r) => format!("revision {r:#010x}"),
        None => "any revision".to_owned(),
    };
    format!(
        "{} vendor {:#010x} product {:#010x} {revision}",
        e.name, e.identity.vendor_id, e.identity.product_code
    )
}

/// Compares the bus with the configuration; `Err` holds one line per position that
/// differs (missing, extra, or another identity), in ring order.
pub fn compare(found: &[Found], expected: &[Expected]) -> Result<(), Vec<String>> {
    let last = found
        .iter()
        .map(|f| f.position)
        .chain(expected.iter().map(|e| e.position))
        .max();
    let Some(last) = last else { return Ok(()) };
    let mut lines = Vec::new();
    for position in 0..=last {
        let f = found.iter().find(|f| f.position == position);
        let e = expected.iter().find(|e| e.position == position);
        match (f, e) {
            (Some(f), Some(e)) if matches(f, &e.identity) => {}
            (Some(f), Some(e)) => lines.push(format!(
                "position {position}: found {}, expected {}",
                describe_found(f),
                describe_expected(e)
            )),
            (None, Some(e)) => lines.push(format!(
                "position {position}: nothing found, expected {}",
                describe_expected(e)
            )),
            (Some(f), None) => lines.push(format!(
                "position {position}: found {}, not in the configuration",
                describe_found(f)
            )),
            (None, None) => {}
        }
    }
    if lines.is_empty() { Ok(()) } else { Err(lines) }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn found(position: u16, vendor_id: u32, product_code: u32, revision: u32) -> Found {
        Found {
            position,
            name: format!("dev{position}"),
            vendor_id,
            product_code,
            revision,
            serial: 0,
        }
    }

    fn expected(
        position: u16,
        vendor_id: u32,
        product_code: u32,
        revision: Option<u32>,
    ) -> Expected {
        Expected {
            name: format!("S{position}"),
            position,
            identity: Identity {
                vendor_id,
                product_code,
                revision,
            },
        }
    }

    #[test]
    fn the_same_bus_is_accepted_and_any_revision_matches_where_none_is_given() {
        let bus = [found(0, 1, 2, 3), found(1, 1, 5, 7)];
        assert_eq!(
            compare(&bus, &[expected(0, 1, 2, Some(3)), expected(1, 1, 5, None)]),
            Ok(())
        );
    }

    #[test]
    fn each_difference_is_one_line_naming_the_position() {
        let bus = [found(0, 1, 2, 3), found(1, 9, 5, 7), found(3, 1, 2, 3)];
        let config = [
            expected(0, 1, 2, Some(4)),
            expected(1, 1, 5, None),
            expected(2, 1, 2, None),
        ];
        let lines = compare(&bus, &config).unwrap_err();
        assert_eq!(lines.len(), 4, "{lines:#?}");
        assert!(lines[0].starts_with("position 0: found \"dev0\" vendor 0x00000001 product 0x00000002 revision 0x00000003, expected S0"), "{}", lines[0]);
        assert!(lines[0].ends_with("revision 0x00000004"), "{}", lines[0]);
        assert!(
            lines[1].starts_with("position 1: found \"dev1\" vendor 0x00000009"),
            "{}",
            lines[1]
        );
        assert!(
            lines[2].starts_with("position 2: nothing found, expected S2"),
            "{}",
            lines[2]
        );
        assert!(
            lines[3].starts_with("position 3: found \"dev3\"")
                && lines[3].ends_with("not in the configuration"),
            "{}",
            lines[3]
        );
    }
}
