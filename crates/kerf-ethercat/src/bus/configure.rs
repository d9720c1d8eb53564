//! The PRE-OP configuration of a drive: the SDO writes of its PDO mapping, mode of
//! operation and interpolation period, and an SDO write of any type.

use kerf_config::ethercat::{Pdo, SdoValue, SdoWrite};

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
}
