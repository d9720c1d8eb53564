//! One CiA 402 drive's process image as the cycle sees it: the outputs the control writes
//! (controlword, target position) and the inputs of the last exchange (statusword,
//! positions, error code), copied between this mirror and the bus's process data once per
//! cycle. It implements [`kerf_drive::cia402::Drive`], so the drive stage, the safety
//! layer and the black box work on an EtherCAT drive exactly as on a simulated one.
//!
//! Process data is little-endian (EtherCAT's byte order). Objects not mapped read as 0,
//! except the mode display, which is the mode written at bring-up (0x6060 by SDO) unless
//! 0x6061 is mapped.

use kerf_drive::cia402::Drive;

use crate::pdo::{DriveLayout, Slot, SpindleLayout};

/// The mirror of one drive's process data.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DriveImage {
    layout: DriveLayout,
    controlword: u16,
    target_position_counts: i32,
    mode: i8,
    statusword: u16,
    position_actual_counts: i32,
    velocity_actual_counts_s: i32,
    following_error_counts: i32,
    error_code: u16,
    mode_display: i8,
    digital_inputs: u32,
}

fn put(out: &mut [u8], slot: Slot, bytes: &[u8]) {
    if let Some(dst) = out.get_mut(slot.offset..slot.offset + slot.bytes) {
        dst.copy_from_slice(&bytes[..slot.bytes]);
    }
}

fn get<const N: usize>(input: &[u8], slot: Slot) -> Option<[u8; N]> {
    input
        .get(slot.offset..slot.offset + N)
        .and_then(|s| s.try_into().ok())
}

impl DriveImage {
    /// A drive laid out as `layout`, in mode `mode` (written by SDO at bring-up).
    pub fn new(layout: DriveLayout, mode: i8) -> DriveImage {
        DriveImage {
            layout,
            controlword: 0,
            target_position_counts: 0,
            mode,
            statusword: 0,
            position_actual_counts: 0,
            velocity_actual_counts_s: 0,
            following_error_counts: 0,
            error_code: 0,
            mode_display: mode,
            digital_inputs: 0,
        }
    }

    /// The layout.
    pub fn layout(&self) -> &DriveLayout {
        &self.layout
    }

    /// Digital inputs (0x60FD) of the last exchange, 0 if not mapped.
    pub fn digital_inputs(&self) -> u32 {
        self.digital_inputs
    }

    /// Writes the outputs into the drive's output image (`out`, its bytes of the PDI).
    pub fn write_outputs(&self, out: &mut [u8]) {
        put(
            out,
            self.layout.controlword,
            &self.controlword.to_le_bytes(),
        );
        put(
            out,
            self.layout.target_position,
            &self.target_position_counts.to_le_bytes(),
        );
        if let Some(slot) = self.layout.modes_of_operation {
            put(out, slot, &self.mode.to_le_bytes());
        }
    }

    /// Reads the inputs from the drive's input image (`input`, its bytes of the PDI).
    pub fn read_inputs(&mut self, input: &[u8]) {
        let l = self.layout;
        if let Some(b) = get::<2>(input, l.statusword) {
            self.statusword = u16::from_le_bytes(b);
        }
        if let Some(b) = get::<4>(input, l.position_actual) {
            self.position_actual_counts = i32::from_le_bytes(b);
        }
        if let Some(b) = l.velocity_actual.and_then(|s| get::<4>(input, s)) {
            self.velocity_actual_counts_s = i32::from_le_bytes(b);
        }
        if let Some(b) = l.following_error.and_then(|s| get::<4>(input, s)) {
            self.following_error_counts = i32::from_le_bytes(b);
        }
        if let Some(b) = l.error_code.and_then(|s| get::<2>(input, s)) {
            self.error_code = u16::from_le_bytes(b);
        }
        if let Some(b) = l.modes_display.and_then(|s| get::<1>(input, s)) {
            self.mode_display = i8::from_le_bytes(b);
        }
        if let Some(b) = l.digital_inputs.and_then(|s| get::<4>(input, s)) {
            self.digital_inputs = u32::from_le_bytes(b);
        }
    }
}

impl Drive for DriveImage {
    fn write(&mut self, controlword: u16, target_position_counts: i32) {
        self.controlword = controlword;
        self.target_position_counts = target_position_counts;
    }

    fn set_mode_of_operation(&mut self, mode: i8) {
        self.mode = mode;
        if self.layout.modes_display.is_none() && self.layout.modes_of_operation.is_some() {
            // With the mode in the process data but not its display, the drive takes the
            // mode at the next exchange; the display follows it.
            self.mode_display = mode;
        }
    }

    fn mode_of_operation_display(&self) -> i8 {
        self.mode_display
    }

    fn statusword(&self) -> u16 {
        self.statusword
    }

    fn position_actual_counts(&self) -> i32 {
        self.position_actual_counts
    }

    fn velocity_actual_counts_s(&self) -> i32 {
        self.velocity_actual_counts_s
    }

    fn following_error_counts(&self) -> i32 {
        self.following_error_counts
    }

    fn error_code(&self) -> u16 {
        self.error_code
    }
}

/// The mirror of the spindle drive's process data (cyclic synchronous velocity): the
/// controlword and target velocity out, the statusword, velocity actual and error code in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SpindleImage {
    layout: SpindleLayout,
    controlword: u16,
    target_velocity_counts_s: i32,
    mode: i8,
    statusword: u16,
    velocity_actual_counts_s: i32,
    error_code: u16,
    mode_display: i8,
}

impl SpindleImage {
    /// A spindle drive laid out as `layout`, in mode `mode` (9, written by SDO at
    /// bring-up).
    pub fn new(layout: SpindleLayout, mode: i8) -> SpindleImage {
        SpindleImage {
            layout,
            controlword: 0,
            target_velocity_counts_s: 0,
            mode,
            statusword: 0,
            velocity_actual_counts_s: 0,
            error_code: 0,
            mode_display: mode,
        }
    }

    /// The layout.
    pub fn layout(&self) -> &SpindleLayout {
        &self.layout
    }

    /// Sets the outputs of the next exchange: controlword (0x6040) and target velocity
    /// (0x60FF, counts/s).
    pub fn write(&mut self, controlword: u16, target_velocity_counts_s: i32) {
        self.controlword = controlword;
        self.target_velocity_counts_s = target_velocity_counts_s;
    }

    /// The controlword last written.
    pub fn controlword(&self) -> u16 {
        self.controlword
    }

    /// The target velocity last written, counts/s.
    pub fn target_velocity_counts_s(&self) -> i32 {
        self.target_velocity_counts_s
    }

    /// Statusword (0x6041) of the last exchange.
    pub fn statusword(&self) -> u16 {
        self.statusword
    }

    /// Velocity actual value (0x606C) of the last exchange, counts/s.
    pub fn velocity_actual_counts_s(&self) -> i32 {
        self.velocity_actual_counts_s
    }

    /// Error code (0x603F) of the last exchange, 0 if not mapped.
    pub fn error_code(&self) -> u16 {
        self.error_code
    }

    /// Modes of operation display: 0x6061 when mapped, else the mode written at bring-up.
    pub fn mode_of_operation_display(&self) -> i8 {
        self.mode_display
    }

    /// Writes the outputs into the drive's output image (`out`, its bytes of the PDI).
    pub fn write_outputs(&self, out: &mut [u8]) {
        put(
            out,
            self.layout.controlword,
            &self.controlword.to_le_bytes(),
        );
        put(
            out,
            self.layout.target_velocity,
            &self.target_velocity_counts_s.to_le_bytes(),
        );
        if let Some(slot) = self.layout.modes_of_operation {
            put(out, slot, &self.mode.to_le_bytes());
        }
    }

    /// Reads the inputs from the drive's input image (`input`, its bytes of the PDI).
    pub fn read_inputs(&mut self, input: &[u8]) {
        let l = self.layout;
        if let Some(b) = get::<2>(input, l.statusword) {
            self.statusword = u16::from_le_bytes(b);
        }
        if let Some(b) = get::<4>(input, l.velocity_actual) {
            self.velocity_actual_counts_s = i32::from_le_bytes(b);
        }
        if let Some(b) = l.error_code.and_then(|s| get::<2>(input, s)) {
            self.error_code = u16::from_le_bytes(b);
        }
        if let Some(b) = l.modes_display.and_then(|s| get::<1>(input, s)) {
            self.mode_display = i8::from_le_bytes(b);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use kerf_config::ethercat::{DriveMode, Pdo};

    #[test]
    fn outputs_are_little_endian_at_the_csp_default_offsets() {
        let mut image = DriveImage::new(
            DriveLayout::new(&Pdo::default_rx(DriveMode::Csp), &Pdo::default_tx()).unwrap(),
            8,
        );
        image.write(0x000F, -2);
        let mut out = [0xAAu8; 6];
        image.write_outputs(&mut out);
        // Controlword 0x000F, then -2 as a 32-bit two's complement: FE FF FF FF.
        assert_eq!(out, [0x0F, 0x00, 0xFE, 0xFF, 0xFF, 0xFF]);
    }

    #[test]
    fn inputs_are_read_from_the_csp_default_offsets() {
        let mut image = DriveImage::new(
            DriveLayout::new(&Pdo::default_rx(DriveMode::Csp), &Pdo::default_tx()).unwrap(),
            8,
        );
        let input = [
            0x37, 0x12, // statusword 0x1237
            0x10, 0x27, 0x00, 0x00, // position actual 10000
            0x18, 0xFC, 0xFF, 0xFF, // velocity actual -1000
            0x05, 0x00, 0x00, 0x00, // following error 5
            0x10, 0x23, // error code 0x2310
            0x01, 0x00, 0x01, 0x00, // digital inputs 0x00010001
        ];
        image.read_inputs(&input);
        assert_eq!(image.statusword(), 0x1237);
        assert_eq!(image.position_actual_counts(), 10_000);
        assert_eq!(image.velocity_actual_counts_s(), -1000);
        assert_eq!(image.following_error_counts(), 5);
        assert_eq!(image.error_code(), 0x2310);
        assert_eq!(image.digital_inputs(), 0x0001_0001);
        assert_eq!(image.mode_of_operation_display(), 8);
    }

    #[test]
    fn a_short_image_leaves_the_values_of_the_last_exchange() {
        let mut image = DriveImage::new(
            DriveLayout::new(&Pdo::default_rx(DriveMode::Csp), &Pdo::default_tx()).unwrap(),
            8,
        );
        image.read_inputs(&[0x37, 0x02, 0x01, 0x00, 0x00, 0x00]);
        image.read_inputs(&[0x21, 0x00]);
        assert_eq!(image.statusword(), 0x0021);
        assert_eq!(image.position_actual_counts(), 1);
    }

    #[test]
    fn the_spindle_image_writes_the_target_velocity_and_reads_the_velocity_actual() {
        let layout =
            SpindleLayout::new(&Pdo::default_rx(DriveMode::Csv), &Pdo::default_tx()).unwrap();
        let mut image = SpindleImage::new(layout, 9);
        // 6000 rpm at 10000 counts/rev: 1e6 counts/s = 0x000F4240.
        image.write(0x000F, 1_000_000);
        let mut out = [0u8; 6];
        image.write_outputs(&mut out);
        assert_eq!(out, [0x0F, 0x00, 0x40, 0x42, 0x0F, 0x00]);
        let input = [
            0x37, 0x16, // statusword 0x1637
            0x00, 0x00, 0x00, 0x00, // position actual (not used)
            0xC0, 0xBD, 0xF0, 0xFF, // velocity actual -1e6
            0x00, 0x00, 0x00, 0x00, // following error
            0x00, 0x75, // error code 0x7500
            0x00, 0x00, 0x00, 0x00,
        ];
        image.read_inputs(&input);
        assert_eq!(image.statusword(), 0x1637);
        assert_eq!(image.velocity_actual_counts_s(), -1_000_000);
        assert_eq!(image.error_code(), 0x7500);
        assert_eq!(image.mode_of_operation_display(), 9);
    }
}
