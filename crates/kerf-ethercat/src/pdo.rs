//! Where each object the control uses sits in a CiA 402 drive's process image, from the
//! drive's PDO mapping (the configuration's [`Pdo`]: the CSP default or an override), and
//! the interpolation period the drive is told.
//!
//! Entries are packed in order with no gaps between them, as the SyncManager lays them
//! out; the configuration has already checked that the objects the control needs are
//! mapped, at their sizes and on whole bytes, and the layout checks it again rather than
//! read the wrong bytes.

use kerf_config::ethercat::Pdo;
use thiserror::Error;

/// Controlword.
pub const CONTROLWORD: u16 = 0x6040;
/// Statusword.
pub const STATUSWORD: u16 = 0x6041;
/// Error code of the last fault.
pub const ERROR_CODE: u16 = 0x603F;
/// Modes of operation.
pub const MODES_OF_OPERATION: u16 = 0x6060;
/// Modes of operation display.
pub const MODES_OF_OPERATION_DISPLAY: u16 = 0x6061;
/// Position actual value.
pub const POSITION_ACTUAL: u16 = 0x6064;
/// Velocity actual value.
pub const VELOCITY_ACTUAL: u16 = 0x606C;
/// Target position.
pub const TARGET_POSITION: u16 = 0x607A;
/// Target velocity (cyclic synchronous velocity).
pub const TARGET_VELOCITY: u16 = 0x60FF;
/// Following error actual value.
pub const FOLLOWING_ERROR_ACTUAL: u16 = 0x60F4;
/// Digital inputs.
pub const DIGITAL_INPUTS: u16 = 0x60FD;
/// Interpolation time period (subindex 1 value, subindex 2 exponent of ten, seconds).
pub const INTERPOLATION_PERIOD: u16 = 0x60C2;
/// SyncManager 2 (outputs) PDO assignment.
pub const SM2_ASSIGNMENT: u16 = 0x1C12;
/// SyncManager 3 (inputs) PDO assignment.
pub const SM3_ASSIGNMENT: u16 = 0x1C13;

/// Where one object sits in a process image: byte offset and size in bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Slot {
    /// Byte offset from the start of the drive's image.
    pub offset: usize,
    /// Size in bytes.
    pub bytes: usize,
}

/// Where the objects the control uses sit in one drive's output and input images.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DriveLayout {
    /// Controlword in the outputs.
    pub controlword: Slot,
    /// Target position in the outputs.
    pub target_position: Slot,
    /// Modes of operation in the outputs, if mapped (else written once by SDO).
    pub modes_of_operation: Option<Slot>,
    /// Statusword in the inputs.
    pub statusword: Slot,
    /// Position actual in the inputs.
    pub position_actual: Slot,
    /// Velocity actual in the inputs, if mapped.
    pub velocity_actual: Option<Slot>,
    /// Following error actual in the inputs, if mapped.
    pub following_error: Option<Slot>,
    /// Error code in the inputs, if mapped.
    pub error_code: Option<Slot>,
    /// Modes of operation display in the inputs, if mapped.
    pub modes_display: Option<Slot>,
    /// Digital inputs, if mapped.
    pub digital_inputs: Option<Slot>,
    /// Bytes of the outputs.
    pub output_bytes: usize,
    /// Bytes of the inputs.
    pub input_bytes: usize,
}

/// A PDO mapping the control cannot work with.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Error)]
pub enum LayoutError {
    /// An object the control needs is not mapped.
    #[error("the {direction} PDO does not map {index:#06x} ({name}), which the control needs")]
    Missing {
        /// "Rx" (outputs) or "Tx" (inputs).
        direction: &'static str,
        /// The object.
        index: u16,
        /// Its name.
        name: &'static str,
    },
    /// An object the control uses is mapped at another size or off a byte boundary.
    #[error(
        "PDO entry {index:#06x} is mapped with {bits} bits at bit {bit_offset}: the control reads it as {expected} bits on a whole byte"
    )]
    Misplaced {
        /// The object.
        index: u16,
        /// Mapped size.
        bits: u8,
        /// Bit offset in the PDO.
        bit_offset: usize,
        /// The object's size.
        expected: u8,
    },
}

/// The slot of `index:0` in `pdo`, checked to be `bits` wide on a whole byte; `None` when
/// not mapped.
fn slot(pdo: &Pdo, index: u16, bits: u8) -> Result<Option<Slot>, LayoutError> {
    match pdo.bit_offset(index, 0) {
        None => Ok(None),
        Some((bit_offset, mapped)) if mapped == bits && bit_offset % 8 == 0 => Ok(Some(Slot {
            offset: bit_offset / 8,
            bytes: usize::from(bits / 8),
        })),
        Some((bit_offset, mapped)) => Err(LayoutError::Misplaced {
            index,
            bits: mapped,
            bit_offset,
            expected: bits,
        }),
    }
}

fn needed(
    pdo: &Pdo,
    direction: &'static str,
    index: u16,
    bits: u8,
    name: &'static str,
) -> Result<Slot, LayoutError> {
    slot(pdo, index, bits)?.ok_or(LayoutError::Missing {
        direction,
        index,
        name,
    })
}

impl DriveLayout {
    /// The layout of a drive mapped with `rx` (outputs) and `tx` (inputs).
    pub fn new(rx: &Pdo, tx: &Pdo) -> Result<DriveLayout, LayoutError> {
        Ok(DriveLayout {
            controlword: needed(rx, "Rx", CONTROLWORD, 16, "controlword")?,
            target_position: needed(rx, "Rx", TARGET_POSITION, 32, "target position")?,
            modes_of_operation: slot(rx, MODES_OF_OPERATION, 8)?,
            statusword: needed(tx, "Tx", STATUSWORD, 16, "statusword")?,
            position_actual: needed(tx, "Tx", POSITION_ACTUAL, 32, "position actual value")?,
            velocity_actual: slot(tx, VELOCITY_ACTUAL, 32)?,
            following_error: slot(tx, FOLLOWING_ERROR_ACTUAL, 32)?,
            error_code: slot(tx, ERROR_CODE, 16)?,
            modes_display: slot(tx, MODES_OF_OPERATION_DISPLAY, 8)?,
            digital_inputs: slot(tx, DIGITAL_INPUTS, 32)?,
            output_bytes: rx.size_bytes(),
            input_bytes: tx.size_bytes(),
        })
    }
}

/// Where the objects the control uses sit in the spindle drive's output and input images
/// (cyclic synchronous velocity, mode 9): the controlword and the target velocity out, the
/// statusword and the velocity actual value in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SpindleLayout {
    /// Controlword in the outputs.
    pub controlword: Slot,
    /// Target velocity (0x60FF, counts/s) in the outputs.
    pub target_velocity: Slot,
    /// Modes of operation in the outputs, if mapped (else written once by SDO).
    pub modes_of_operation: Option<Slot>,
    /// Statusword in the inputs.
    pub statusword: Slot,
    /// Velocity actual (0x606C, counts/s) in the inputs.
    pub velocity_actual: Slot,
    /// Error code in the inputs, if mapped.
    pub error_code: Option<Slot>,
    /// Modes of operation display in the inputs, if mapped.
    pub modes_display: Option<Slot>,
    /// Bytes of the outputs.
    pub output_bytes: usize,
    /// Bytes of the inputs.
    pub input_bytes: usize,
}

impl SpindleLayout {
    /// The layout of a spindle drive mapped with `rx` (outputs) and `tx` (inputs).
    pub fn new(rx: &Pdo, tx: &Pdo) -> Result<SpindleLayout, LayoutError> {
        Ok(SpindleLayout {
            controlword: needed(rx, "Rx", CONTROLWORD, 16, "controlword")?,
            target_velocity: needed(rx, "Rx", TARGET_VELOCITY, 32, "target velocity")?,
            modes_of_operation: slot(rx, MODES_OF_OPERATION, 8)?,
            statusword: needed(tx, "Tx", STATUSWORD, 16, "statusword")?,
            velocity_actual: needed(tx, "Tx", VELOCITY_ACTUAL, 32, "velocity actual value")?,
            error_code: slot(tx, ERROR_CODE, 16)?,
            modes_display: slot(tx, MODES_OF_OPERATION_DISPLAY, 8)?,
            output_bytes: rx.size_bytes(),
            input_bytes: tx.size_bytes(),
        })
    }
}

/// The interpolation time period (0x60C2) for `period_ns`: a value of at most 255 and an
/// exponent of ten, `value · 10^exponent` seconds, exactly; `None` where no such pair is
/// exact (a period whose significant digits do not fit in a byte, like 333 µs).
pub fn interpolation_period(period_ns: u64) -> Option<(u8, i8)> {
    if period_ns == 0 {
        return None;
    }
    let mut value = period_ns;
    let mut exponent: i8 = -9;
    while value.is_multiple_of(10) && exponent < 0 {
        value /= 10;
        exponent += 1;
    }
    u8::try_from(value).ok().map(|v| (v, exponent))
}

#[cfg(test)]
mod tests {
    use super::*;
    use kerf_config::ethercat::{DriveMode, PdoEntry};

    fn pdo(index: u16, entries: &[(u16, u8, u8)]) -> Pdo {
        Pdo {
            index,
            entries: entries
                .iter()
                .map(|&(index, subindex, bits)| PdoEntry {
                    index,
                    subindex,
                    bits,
                })
                .collect(),
        }
    }

    #[test]
    fn the_csp_default_packs_as_the_drive_manuals_list_it() {
        let layout =
            DriveLayout::new(&Pdo::default_rx(DriveMode::Csp), &Pdo::default_tx()).unwrap();
        // RxPDO: controlword 2 bytes at 0, target position 4 bytes at 2: 6 bytes.
        assert_eq!(
            layout.controlword,
            Slot {
                offset: 0,
                bytes: 2
            }
        );
        assert_eq!(
            layout.target_position,
            Slot {
                offset: 2,
                bytes: 4
            }
        );
        assert_eq!(layout.output_bytes, 6);
        // TxPDO: 2 + 4 + 4 + 4 + 2 + 4 = 20 bytes.
        assert_eq!(
            layout.statusword,
            Slot {
                offset: 0,
                bytes: 2
            }
        );
        assert_eq!(
            layout.position_actual,
            Slot {
                offset: 2,
                bytes: 4
            }
        );
        assert_eq!(
            layout.velocity_actual,
            Some(Slot {
                offset: 6,
                bytes: 4
            })
        );
        assert_eq!(
            layout.following_error,
            Some(Slot {
                offset: 10,
                bytes: 4
            })
        );
        assert_eq!(
            layout.error_code,
            Some(Slot {
                offset: 14,
                bytes: 2
            })
        );
        assert_eq!(
            layout.digital_inputs,
            Some(Slot {
                offset: 16,
                bytes: 4
            })
        );
        assert_eq!(layout.input_bytes, 20);
        assert_eq!(layout.modes_of_operation, None);
        assert_eq!(layout.modes_display, None);
    }

    #[test]
    fn a_mapping_without_what_the_control_needs_is_refused_by_name() {
        let rx = pdo(0x1600, &[(0x6040, 0, 16)]);
        let error = DriveLayout::new(&rx, &Pdo::default_tx()).unwrap_err();
        assert_eq!(
            error,
            LayoutError::Missing {
                direction: "Rx",
                index: 0x607A,
                name: "target position"
            }
        );
        assert!(
            error.to_string().contains("0x607a (target position)"),
            "{error}"
        );
        let tx = pdo(0x1A00, &[(0x6064, 0, 32)]);
        let error = DriveLayout::new(&Pdo::default_rx(DriveMode::Csp), &tx).unwrap_err();
        assert_eq!(
            error,
            LayoutError::Missing {
                direction: "Tx",
                index: 0x6041,
                name: "statusword"
            }
        );
    }

    #[test]
    fn objects_at_another_size_or_off_a_byte_are_refused() {
        let rx = pdo(0x1600, &[(0x6040, 0, 32), (0x607A, 0, 32)]);
        assert_eq!(
            DriveLayout::new(&rx, &Pdo::default_tx()),
            Err(LayoutError::Misplaced {
                index: 0x6040,
                bits: 32,
                bit_offset: 0,
                expected: 16
            })
        );
        // A 4-bit gap entry before the statusword puts it at bit 4.
        let tx = pdo(0x1A00, &[(0, 0, 4), (0x6041, 0, 16), (0x6064, 0, 32)]);
        assert_eq!(
            DriveLayout::new(&Pdo::default_rx(DriveMode::Csp), &tx),
            Err(LayoutError::Misplaced {
                index: 0x6041,
                bits: 16,
                bit_offset: 4,
                expected: 16
            })
        );
    }

    #[test]
    fn gap_entries_and_the_mode_byte_move_what_follows() {
        let rx = pdo(
            0x1600,
            &[(0x6040, 0, 16), (0x6060, 0, 8), (0, 0, 8), (0x607A, 0, 32)],
        );
        let layout = DriveLayout::new(&rx, &Pdo::default_tx()).unwrap();
        assert_eq!(
            layout.modes_of_operation,
            Some(Slot {
                offset: 2,
                bytes: 1
            })
        );
        assert_eq!(
            layout.target_position,
            Slot {
                offset: 4,
                bytes: 4
            }
        );
        assert_eq!(layout.output_bytes, 8);
    }

    #[test]
    fn the_csv_default_packs_the_target_velocity_after_the_controlword() {
        let layout =
            SpindleLayout::new(&Pdo::default_rx(DriveMode::Csv), &Pdo::default_tx()).unwrap();
        // RxPDO: controlword 2 bytes at 0, target velocity 4 bytes at 2: 6 bytes.
        assert_eq!(
            layout.target_velocity,
            Slot {
                offset: 2,
                bytes: 4
            }
        );
        assert_eq!(layout.output_bytes, 6);
        // TxPDO: statusword (2), position actual (4), then velocity actual at byte 6.
        assert_eq!(
            layout.velocity_actual,
            Slot {
                offset: 6,
                bytes: 4
            }
        );
        assert_eq!(
            layout.error_code,
            Some(Slot {
                offset: 14,
                bytes: 2
            })
        );
        // A CSP mapping has no target velocity: refused by name.
        assert_eq!(
            SpindleLayout::new(&Pdo::default_rx(DriveMode::Csp), &Pdo::default_tx()),
            Err(LayoutError::Missing {
                direction: "Rx",
                index: 0x60FF,
                name: "target velocity"
            })
        );
        // Only the statusword and the velocity actual are needed in.
        let tx = pdo(0x1A00, &[(0x6041, 0, 16), (0x606C, 0, 32)]);
        let layout = SpindleLayout::new(&Pdo::default_rx(DriveMode::Csv), &tx).unwrap();
        assert_eq!((layout.input_bytes, layout.error_code), (6, None));
    }

    #[test]
    fn interpolation_periods_are_exact_value_and_exponent_pairs() {
        // 1 ms = 1 · 10⁻³ s; 250 µs = 25 · 10⁻⁵ s; 4 ms = 4 · 10⁻³ s; 125 µs = 125 · 10⁻⁶ s.
        assert_eq!(interpolation_period(1_000_000), Some((1, -3)));
        assert_eq!(interpolation_period(250_000), Some((25, -5)));
        assert_eq!(interpolation_period(4_000_000), Some((4, -3)));
        assert_eq!(interpolation_period(125_000), Some((125, -6)));
        // 333 µs = 333 · 10⁻⁶: 333 does not fit a byte, and no other pair is exact.
        assert_eq!(interpolation_period(333_000), None);
        assert_eq!(interpolation_period(0), None);
    }
}
