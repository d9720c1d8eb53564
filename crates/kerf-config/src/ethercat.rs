//! The EtherCAT bus as the configuration describes it (`[ethercat]`, `[[ethercat.drives]]`,
//! `[[ethercat.io]]`): a plain, checked record for the daemon's fieldbus side.
//!
//! Every subdevice on the ring is listed, at its ring position (0-based, in the order the
//! frame passes them): the CiA 402 servo drives, one per configured axis and the
//! spindle's (`axis = "s"`, in cyclic synchronous velocity) when it has one, and every other
//! subdevice (digital I/O terminals, and couplers, which have no bits) as I/O. The axis's
//! position scale is not repeated here: it is `[axes.*.drive] counts_per_mm`
//! (`counts_per_deg`) and `direction`, [`crate::AxisDrive::scale`].

/// The CiA 402 controlword (0x6040:0, 16 bits), in every drive's RxPDO.
pub const CONTROLWORD: (u16, u8) = (0x6040, 0);
/// The CiA 402 target position (0x607A:0, 32 bits), in a [`DriveMode::Csp`] drive's RxPDO.
pub const TARGET_POSITION: (u16, u8) = (0x607A, 0);
/// The CiA 402 target velocity (0x60FF:0, 32 bits), in a [`DriveMode::Csv`] drive's RxPDO.
pub const TARGET_VELOCITY: (u16, u8) = (0x60FF, 0);
/// The CiA 402 statusword (0x6041:0, 16 bits), in every drive's TxPDO.
pub const STATUSWORD: (u16, u8) = (0x6041, 0);
/// The CiA 402 position actual value (0x6064:0, 32 bits), in every drive's TxPDO.
pub const POSITION_ACTUAL: (u16, u8) = (0x6064, 0);
/// The CiA 402 velocity actual value (0x606C:0, 32 bits), in the spindle drive's TxPDO.
pub const VELOCITY_ACTUAL: (u16, u8) = (0x606C, 0);
/// [`EthercatDrive::axis_index`] of the spindle's drive (`axis = "s"`): after the six
/// axes X to C.
pub const SPINDLE_AXIS_INDEX: usize = 6;
/// The CiA 402 modes of operation (0x6060:0), set from [`DriveMode`] at bring-up.
pub const MODES_OF_OPERATION: u16 = 0x6060;
/// The CiA 402 interpolation time period (0x60C2), set from `period_us` at bring-up.
pub const INTERPOLATION_PERIOD: u16 = 0x60C2;
/// The homing objects of a drive that homes itself: method 0x6098, speeds 0x6099,
/// acceleration 0x609A, home offset 0x607C.
pub const HOMING_OBJECTS: [u16; 4] = [0x6098, 0x6099, 0x609A, 0x607C];
/// Modes of operation display.
pub const MODES_OF_OPERATION_DISPLAY: u16 = 0x6061;
/// The SyncManager 2 (outputs) PDO assignment object.
pub const RX_PDO_ASSIGN: u16 = 0x1C12;
/// The SyncManager 3 (inputs) PDO assignment object.
pub const TX_PDO_ASSIGN: u16 = 0x1C13;
/// The default RxPDO mapping object a drive's `rx_pdo` entries are written to.
pub const DEFAULT_RX_PDO_INDEX: u16 = 0x1600;
/// The default TxPDO mapping object a drive's `tx_pdo` entries are written to.
pub const DEFAULT_TX_PDO_INDEX: u16 = 0x1A00;

/// The expected identity of a subdevice (its SII EEPROM / object 0x1018).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Identity {
    /// `vendor_id`: the ETG vendor ID.
    pub vendor_id: u32,
    /// `product_code`.
    pub product_code: u32,
    /// `revision`: when given, the revision number must match too.
    pub revision: Option<u32>,
}

/// A drive's cyclic operating mode (`mode`), CiA 402 object 0x6060.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DriveMode {
    /// `"csp"`: cyclic synchronous position, mode 8; the axis's setpoints are target
    /// positions (0x607A) each period.
    Csp,
    /// `"csv"`: cyclic synchronous velocity, mode 9; target velocities (0x60FF). The
    /// spindle's drive only (`axis = "s"`, [`SPINDLE_AXIS_INDEX`]).
    Csv,
}

impl DriveMode {
    /// The value written to 0x6060 (modes of operation): 8 or 9.
    pub fn mode_of_operation(self) -> i8 {
        match self {
            DriveMode::Csp => 8,
            DriveMode::Csv => 9,
        }
    }

    /// The object the cyclic setpoint is written to: [`TARGET_POSITION`] or
    /// [`TARGET_VELOCITY`].
    pub fn target(self) -> (u16, u8) {
        match self {
            DriveMode::Csp => TARGET_POSITION,
            DriveMode::Csv => TARGET_VELOCITY,
        }
    }

    /// The name in the file.
    pub fn name(self) -> &'static str {
        match self {
            DriveMode::Csp => "csp",
            DriveMode::Csv => "csv",
        }
    }
}

/// One entry of a PDO mapping: an object mapped into the process data. Index 0 (with
/// subindex 0) is a gap of `bits` bits, as in CoE mapping objects.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PdoEntry {
    /// Object index (0: a gap).
    pub index: u16,
    /// Object subindex.
    pub subindex: u8,
    /// Size in bits: 1, 8, 16, 32 or 64 for an object; 1 to 64 for a gap.
    pub bits: u8,
}

impl PdoEntry {
    /// The value CoE writes into a mapping object's subindex for this entry:
    /// index << 16 | subindex << 8 | bits.
    pub fn mapping_value(self) -> u32 {
        u32::from(self.index) << 16 | u32::from(self.subindex) << 8 | u32::from(self.bits)
    }
}

/// A PDO: the mapping object it is written to and its entries, in process-data order.
/// Entries of 8 bits or more start on a whole byte and the whole PDO is whole bytes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Pdo {
    /// The mapping object (0x1600.. for RxPDOs, 0x1A00.. for TxPDOs), assigned alone in
    /// 0x1C12 (RxPDO, SyncManager 2) or 0x1C13 (TxPDO, SyncManager 3).
    pub index: u16,
    /// The mapped objects in order.
    pub entries: Vec<PdoEntry>,
}

impl Pdo {
    /// The PDO's size, bytes.
    pub fn size_bytes(&self) -> usize {
        self.entries
            .iter()
            .map(|e| usize::from(e.bits))
            .sum::<usize>()
            / 8
    }

    /// The bit offset of object `index:subindex` in the PDO, with its size in bits;
    /// `None` when it is not mapped.
    pub fn bit_offset(&self, index: u16, subindex: u8) -> Option<(usize, u8)> {
        let mut at = 0usize;
        for e in &self.entries {
            if e.index != 0 && (e.index, e.subindex) == (index, subindex) {
                return Some((at, e.bits));
            }
            at += usize::from(e.bits);
        }
        None
    }

    /// The CiA 402 CSP default RxPDO: controlword 0x6040 (16 bits), target position
    /// 0x607A (32 bits), in 0x1600.
    pub fn default_rx(mode: DriveMode) -> Pdo {
        let target = mode.target();
        Pdo {
            index: DEFAULT_RX_PDO_INDEX,
            entries: vec![entry(CONTROLWORD, 16), entry(target, 32)],
        }
    }

    /// The default TxPDO: statusword 0x6041 (16), position actual 0x6064 (32), velocity
    /// actual 0x606C (32), following error actual 0x60F4 (32), error code 0x603F (16),
    /// digital inputs 0x60FD (32), in 0x1A00.
    pub fn default_tx() -> Pdo {
        Pdo {
            index: DEFAULT_TX_PDO_INDEX,
            entries: vec![
                entry(STATUSWORD, 16),
                entry(POSITION_ACTUAL, 32),
                entry(VELOCITY_ACTUAL, 32),
                entry((0x60F4, 0), 32),
                entry((0x603F, 0), 16),
                entry((0x60FD, 0), 32),
            ],
        }
    }
}

fn entry((index, subindex): (u16, u8), bits: u8) -> PdoEntry {
    PdoEntry {
        index,
        subindex,
        bits,
    }
}

/// The value of an SDO start-up write, in its CoE type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SdoValue {
    /// `type = "u8"`.
    U8(u8),
    /// `type = "u16"`.
    U16(u16),
    /// `type = "u32"`.
    U32(u32),
    /// `type = "i8"`.
    I8(i8),
    /// `type = "i16"`.
    I16(i16),
    /// `type = "i32"`.
    I32(i32),
}

impl SdoValue {
    /// The bytes an SDO download sends, little-endian as CoE transfers them.
    pub fn to_le_bytes(self) -> Vec<u8> {
        match self {
            SdoValue::U8(v) => v.to_le_bytes().to_vec(),
            SdoValue::U16(v) => v.to_le_bytes().to_vec(),
            SdoValue::U32(v) => v.to_le_bytes().to_vec(),
            SdoValue::I8(v) => v.to_le_bytes().to_vec(),
            SdoValue::I16(v) => v.to_le_bytes().to_vec(),
            SdoValue::I32(v) => v.to_le_bytes().to_vec(),
        }
    }
}

/// One SDO start-up write (`sdo` entries), done in PRE-OP in the order listed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SdoWrite {
    /// Object index.
    pub index: u16,
    /// Object subindex.
    pub subindex: u8,
    /// The value, with its type.
    pub value: SdoValue,
}

/// One `[[ethercat.drives]]`: the CiA 402 servo drive of an axis.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct EthercatDrive {
    /// `axis`: the axis it drives, 0 to 5 for X, Y, Z, A, B, C, or
    /// [`SPINDLE_AXIS_INDEX`] for the spindle (`axis = "s"`, always [`DriveMode::Csv`]).
    pub axis_index: usize,
    /// `position`: ring position, 0-based.
    pub position: u16,
    /// `vendor_id`, `product_code`, `revision`.
    pub identity: Identity,
    /// `mode`.
    pub mode: DriveMode,
    /// `rx_pdo_index` and `rx_pdo`: the outputs (controlword, target).
    pub rx_pdo: Pdo,
    /// `tx_pdo_index` and `tx_pdo`: the inputs (statusword, position actual, ...).
    pub tx_pdo: Pdo,
    /// `sdo`: the start-up writes.
    pub sdo: Vec<SdoWrite>,
    /// The homing objects written at bring-up (after `sdo`) when the axis homes by its
    /// drive (`[axes.*.homing] kind = "drive"`): [`crate::Config::drive_homing_objects`].
    pub homing: Option<crate::DriveHomingObjects>,
}

/// A named bit of an I/O subdevice's process data.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct IoBit {
    /// The name, unique over the bus.
    pub name: String,
    /// Bit number in the subdevice's inputs (or outputs), from 0 at bit 0 of the first byte.
    pub bit: u16,
}

/// One `[[ethercat.io]]`: a subdevice other than a drive (digital I/O, a coupler).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct EthercatIo {
    /// `position`: ring position, 0-based.
    pub position: u16,
    /// `vendor_id`, `product_code`, `revision`.
    pub identity: Identity,
    /// `sdo`: the start-up writes.
    pub sdo: Vec<SdoWrite>,
    /// `inputs`, in bit order.
    pub inputs: Vec<IoBit>,
    /// `outputs`, in bit order.
    pub outputs: Vec<IoBit>,
}

/// `[ethercat]`: the bus that drives the axes (and the spindle when `[spindle]` is a
/// drive), when the machine has one.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct EthercatConfig {
    /// `interface`: the network interface the bus is on.
    pub interface: String,
    /// `dc`: whether distributed clocks are used (SYNC0 at the period).
    pub dc: bool,
    /// `sync0_shift_ns`: SYNC0's shift after the cycle start, ns, below the period.
    pub sync0_shift_ns: u32,
    /// `max_missed_cycles`: a fault latches when more cycles than this in a row have a
    /// working-counter mismatch or a lost or late frame.
    pub max_missed_cycles: u32,
    /// `watchdog_us`: the drives' process-data (SyncManager) watchdog, µs, a multiple of
    /// [`crate::WATCHDOG_UNIT_US`].
    pub watchdog_us: u32,
    /// `state_timeout_ms`: time each subdevice may take for each state change.
    pub state_timeout_ms: u32,
    /// `sdo_timeout_ms`: time a subdevice may take to answer an SDO request.
    pub sdo_timeout_ms: u32,
    /// `dc_settle_timeout_ms`: time the distributed clocks may take to settle.
    pub dc_settle_timeout_ms: u32,
    /// The drives, in file order: the axes' and the spindle's ([`Self::spindle_drive`]).
    pub drives: Vec<EthercatDrive>,
    /// The other subdevices, in file order.
    pub io: Vec<EthercatIo>,
}

impl EthercatConfig {
    /// The number of subdevices on the bus (drives and I/O; their positions are 0 to
    /// this minus one).
    pub fn subdevices(&self) -> usize {
        self.drives.len() + self.io.len()
    }

    /// The drive of axis `axis_index` (0 to 5 for X to C), if the bus has one.
    pub fn drive_of_axis(&self, axis_index: usize) -> Option<&EthercatDrive> {
        self.drives.iter().find(|d| d.axis_index == axis_index)
    }

    /// The spindle's drive (`axis = "s"`), if the bus has one.
    pub fn spindle_drive(&self) -> Option<&EthercatDrive> {
        self.drive_of_axis(SPINDLE_AXIS_INDEX)
    }

    /// The ESC's process-data watchdog setting for [`Self::watchdog_us`]: the number of
    /// [`crate::WATCHDOG_UNIT_US`] intervals (register 0x0420, with the watchdog divider
    /// 0x0400 at its default of 100 µs).
    pub fn watchdog_intervals(&self) -> u16 {
        u16::try_from(self.watchdog_us / crate::WATCHDOG_UNIT_US).unwrap_or(u16::MAX)
    }
}
