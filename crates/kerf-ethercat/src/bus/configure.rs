//! The PRE-OP configuration of a drive: the SDO writes of its PDO mapping, mode of
//! operation and interpolation period, of its homing objects when it homes itself, and an
//! SDO write of any type.

use kerf_config::DriveHomingObjects;
use kerf_config::ethercat::{Pdo, SdoValue, SdoWrite};
use kerf_drive::cia402::{
    HOME_OFFSET_INDEX, HOMING_ACCELERATION_INDEX, HOMING_METHOD_INDEX,
    HOMING_SPEED_SWITCH_SUBINDEX, HOMING_SPEED_ZERO_SUBINDEX, HOMING_SPEEDS_INDEX,
};

use crate::pdo::{INTERPOLATION_PERIOD, MODES_OF_OPERATION, SM2_ASSIGNMENT, SM3_ASSIGNMENT};

/// The SDO writes that configure a drive in PRE-OP: for each direction the assignment
/// cleared, the mapping object's count cleared, its entries, its count, the assignment of
/// that one mapping object; then the mode of operation and the interpolation period.
pub fn drive_writes(rx: &Pdo, tx: &Pdo, mode: i8, period: (u8, i8)) -> Vec<SdoWrite> {
    let mut writes = Vec::new();
    let w = |index, subindex, value| SdoWrite {
        index,
        subindex,
        value,
    };
    for (assignment, pdo) in [(SM2_ASSIGNMENT, rx), (SM3_ASSIGNMENT, tx)] {
        writes.push(w(assignment, 0, SdoValue::U8(0)));
        writes.push(w(pdo.index, 0, SdoValue::U8(0)));
        for (i, entry) in pdo.entries.iter().enumerate() {
            let subindex = u8::try_from(i + 1).unwrap_or(u8::MAX);
            writes.push(w(pdo.index, subindex, SdoValue::U32(entry.mapping_value())));
        }
        let count = u8::try_from(pdo.entries.len()).unwrap_or(u8::MAX);
        writes.push(w(pdo.index, 0, SdoValue::U8(count)));
        writes.push(w(assignment, 1, SdoValue::U16(pdo.index)));
        writes.push(w(assignment, 0, SdoValue::U8(1)));
    }
    writes.push(w(MODES_OF_OPERATION, 0, SdoValue::I8(mode)));
    writes.push(w(INTERPOLATION_PERIOD, 1, SdoValue::U8(period.0)));
    writes.push(w(INTERPOLATION_PERIOD, 2, SdoValue::I8(period.1)));
    writes
}

/// The SDO writes of a drive's homing objects (an axis homed by its drive), after
/// [`drive_writes`]: method 0x6098, the speeds 0x6099:01 and :02 where given (not 0),
/// acceleration 0x609A, home offset 0x607C. None without `homing`.
pub fn homing_writes(homing: Option<&DriveHomingObjects>) -> Vec<SdoWrite> {
    let Some(h) = homing else {
        return Vec::new();
    };
    let w = |index, subindex, value| SdoWrite {
        index,
        subindex,
        value,
    };
    let mut writes = vec![w(HOMING_METHOD_INDEX, 0, SdoValue::I8(h.method))];
    for (subindex, speed) in [
        (HOMING_SPEED_SWITCH_SUBINDEX, h.search_speed_counts_s),
        (HOMING_SPEED_ZERO_SUBINDEX, h.zero_speed_counts_s),
    ] {
        if speed != 0 {
            writes.push(w(HOMING_SPEEDS_INDEX, subindex, SdoValue::U32(speed)));
        }
    }
    writes.push(w(
        HOMING_ACCELERATION_INDEX,
        0,
        SdoValue::U32(h.acceleration_counts_s2),
    ));
    writes.push(w(HOME_OFFSET_INDEX, 0, SdoValue::I32(h.home_offset_counts)));
    writes
}

pub(crate) async fn sdo_write<S>(
    handle: &ethercrab::SubDeviceRef<'_, S>,
    write: SdoWrite,
) -> Result<(), ethercrab::error::Error>
where
    S: std::ops::Deref<Target = ethercrab::SubDevice>,
{
    let (i, s) = (write.index, write.subindex);
    match write.value {
        SdoValue::U8(v) => handle.sdo_write(i, s, v).await,
        SdoValue::U16(v) => handle.sdo_write(i, s, v).await,
        SdoValue::U32(v) => handle.sdo_write(i, s, v).await,
        SdoValue::I8(v) => handle.sdo_write(i, s, v).await,
        SdoValue::I16(v) => handle.sdo_write(i, s, v).await,
        SdoValue::I32(v) => handle.sdo_write(i, s, v).await,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use kerf_config::ethercat::DriveMode;

    #[test]
    fn a_csp_drive_is_configured_as_its_manual_lists_the_writes() {
        let writes = drive_writes(
            &Pdo::default_rx(DriveMode::Csp),
            &Pdo::default_tx(),
            8,
            (1, -3),
        );
        let as_tuples: Vec<(u16, u8, SdoValue)> = writes
            .iter()
            .map(|w| (w.index, w.subindex, w.value))
            .collect();
        use SdoValue::*;
        let expected = vec![
            (0x1C12, 0, U8(0)),
            (0x1600, 0, U8(0)),
            (0x1600, 1, U32(0x6040_0010)),
            (0x1600, 2, U32(0x607A_0020)),
            (0x1600, 0, U8(2)),
            (0x1C12, 1, U16(0x1600)),
            (0x1C12, 0, U8(1)),
            (0x1C13, 0, U8(0)),
            (0x1A00, 0, U8(0)),
            (0x1A00, 1, U32(0x6041_0010)),
            (0x1A00, 2, U32(0x6064_0020)),
            (0x1A00, 3, U32(0x606C_0020)),
            (0x1A00, 4, U32(0x60F4_0020)),
            (0x1A00, 5, U32(0x603F_0010)),
            (0x1A00, 6, U32(0x60FD_0020)),
            (0x1A00, 0, U8(6)),
            (0x1C13, 1, U16(0x1A00)),
            (0x1C13, 0, U8(1)),
            (0x6060, 0, I8(8)),
            (0x60C2, 1, U8(1)),
            (0x60C2, 2, I8(-3)),
        ];
        assert_eq!(as_tuples, expected);
    }

    #[test]
    fn a_drive_that_homes_itself_gets_its_homing_objects_and_only_the_speeds_given() {
        assert_eq!(homing_writes(None), vec![]);
        let objects = DriveHomingObjects {
            method: 21,
            search_speed_counts_s: 8000,
            zero_speed_counts_s: 1000,
            acceleration_counts_s2: 200_000,
            home_offset_counts: -3000,
        };
        let as_tuples = |writes: Vec<SdoWrite>| -> Vec<(u16, u8, SdoValue)> {
            writes
                .iter()
                .map(|w| (w.index, w.subindex, w.value))
                .collect()
        };
        use SdoValue::*;
        assert_eq!(
            as_tuples(homing_writes(Some(&objects))),
            vec![
                (0x6098, 0, I8(21)),
                (0x6099, 1, U32(8000)),
                (0x6099, 2, U32(1000)),
                (0x609A, 0, U32(200_000)),
                (0x607C, 0, I32(-3000)),
            ]
        );
        // Method 37 homes where the axis stands: no speeds given, none written.
        let here = DriveHomingObjects {
            method: 37,
            search_speed_counts_s: 0,
            zero_speed_counts_s: 0,
            ..objects
        };
        assert_eq!(
            as_tuples(homing_writes(Some(&here))),
            vec![
                (0x6098, 0, I8(37)),
                (0x609A, 0, U32(200_000)),
                (0x607C, 0, I32(-3000)),
            ]
        );
    }
}
