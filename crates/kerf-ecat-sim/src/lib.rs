//! An emulated EtherCAT network for tests: CiA 402 servo drives and digital I/O
//! subdevices that answer real EtherCAT frames (EtherType 0x88A4). The core is pure and
//! deterministic (frame bytes and a time in, frame bytes out, see [`network::Network`]);
//! the binary `kerf-ecat-sim` puts it on a Linux interface through a raw socket.
//!
//! Default identities (all plainly test values; vendor id 0x0000_4B52 is "KR"):
//!
//! | kind  | vendor id   | product code | revision    | serial             | name                |
//! |-------|-------------|--------------|-------------|--------------------|---------------------|
//! | drive | 0x0000_4B52 | 0x0000_0402  | 0x0001_0000 | 0x0000_1001 + n    | `Kerf CiA402 drive` |
//! | I/O   | 0x0000_4B52 | 0x0000_0010  | 0x0001_0000 | 0x0000_2001 + n    | `Kerf digital I/O`  |
//!
//! where n counts the drives (or the I/O subdevices) from 0. The drives come first on the
//! line, then the I/O subdevices. Each I/O subdevice has 8 inputs and 8 outputs.
//!
//! # The binary's control for tests
//!
//! Options: `--refuse-safe-op P[:CODE]` (repeatable) makes the subdevice at position P
//! refuse PRE-OP → SAFE-OP with AL status code CODE (hexadecimal, `0x` optional; 0x001D,
//! invalid output configuration, by default): its AL status stays PRE-OP with the error
//! indicator (0x0130 = 0x12) and 0x0134 holds CODE ([`SafeOpRefusal`]); `--dc-drift-ppm
//! X` (below).
//!
//! The process-data watchdog: every output SyncManager enables it (ESC defaults: divider
//! 0x09C2 = 100 µs, 0x0420 = 1000, so 100 ms; the MainDevice may change them). When no
//! output write arrives for that long in OP, the subdevice drops to SAFE-OP with the
//! error indicator and AL status code 0x001B (0x0130 = 0x14), a drive stops its motor by
//! its own quick stop and rests in Switch on disabled, an I/O subdevice clears its
//! outputs. The MainDevice recovers it by writing AL control 0x0120: the acknowledge bit
//! 0x10 clears the indicator and the code, and the state bits of the same write are acted
//! on, so 0x14 (acknowledge, stay in SAFE-OP) then 0x08, or 0x18 at once, return it to OP
//! (see [`al::Al::request`]); the watchdog counts anew from OP. The drive behind is then
//! in Switch on disabled (or Fault, if it had one), and its controlword enables it again
//! where it stopped. Without the acknowledge bit, requests are ignored while the
//! indicator is set.
//!
//! Standard input, one command a line, P a ring position (0 first) and N decimal, CODE
//! and BITS decimal or `0x` hex:
//!
//! | command         | what it does                                                        |
//! |-----------------|---------------------------------------------------------------------|
//! | `mute`          | stop answering frames (a pulled cable)                              |
//! | `unmute`        | answer again                                                        |
//! | `fault P CODE`  | the drive at P trips a fault with error code CODE (0x603F)          |
//! | `leave-op P CODE` | the subdevice at P leaves OP by an error of its own: SAFE-OP + error, AL status code CODE; a drive stops itself as after its watchdog |
//! | `stall P`       | the drive at P's motor jams (see [`drive`]): position stays, velocity 0, following error grows with the target, statusword bit 13 beyond the window; no fault of its own |
//! | `free P`        | it turns again                                                      |
//! | `inputs N BITS` | the N-th I/O subdevice's (0 first) input bits                       |
//! | `state`         | one line per subdevice on standard output, flushed ([`report`])     |
//!
//! Commands are carried out in order, between frames; a refused one is reported on
//! standard error. Standard output carries nothing but the answers to `state`, e.g.
//!
//! ```text
//! subdevice 0 kind=drive al=OP al_error=0 al_code=0x0000 watchdog_trips=0 cia402=operation_enabled statusword=0x1237 error_code=0x0000 position_counts=4000 velocity_counts_s=0 following_error_counts=0 stalled=0 stopped_ms=- mode=8 target_velocity_counts_s=0
//! subdevice 1 kind=io al=OP al_error=0 al_code=0x0000 watchdog_trips=0 inputs=0x5A outputs=0x00
//! ```
//!
//! Distributed clocks: every subdevice has a 64-bit DC. Their local clocks start 0.5 ms
//! apart (the drives at 0, 1, 2 ms…, the I/O subdevices at 0.5, 1.5 ms… after the host's
//! time at start) and run from one oscillator for the whole line, which
//! `--dc-drift-ppm X` ([`NetworkSpec::dc_drift_ppm`]) makes run X parts per million fast
//! (negative: slow) against the host's CLOCK_MONOTONIC: with X = 50 the reference clock's
//! system time (0x0910) gains 50 µs per second of host time. The subdevices drift
//! together, so the MainDevice's drift control keeps them on the reference while the
//! reference drifts against the host, as a real line's reference clock does. The
//! process-data watchdog and the drives' own quick stop keep the host's time.
#![deny(unsafe_code)]

pub mod al;
pub mod coe;
pub mod dc;
pub mod drive;
pub mod esc;
pub mod frame;
pub mod io;
pub mod network;
pub mod od;
pub mod report;
pub mod sii;
pub mod socket;
pub mod switches;

use kerf_drive::sim::SimConfig;

use crate::dc::DcClock;
use crate::drive::DriveDevice;
use crate::esc::Esc;
use crate::io::{IoDevice, IoHandle};
use crate::network::Network;
use crate::sii::Identity;

/// Default vendor id.
pub const VENDOR_ID: u32 = 0x0000_4B52;
/// Default product code of the drives.
pub const DRIVE_PRODUCT_CODE: u32 = 0x0000_0402;
/// Default product code of the I/O subdevices.
pub const IO_PRODUCT_CODE: u32 = 0x0000_0010;
/// Default revision.
pub const REVISION: u32 = 0x0001_0000;
/// Serial number of the first drive.
pub const DRIVE_SERIAL_BASE: u32 = 0x0000_1001;
/// Serial number of the first I/O subdevice.
pub const IO_SERIAL_BASE: u32 = 0x0000_2001;
/// Name of the drives.
pub const DRIVE_NAME: &str = "Kerf CiA402 drive";
/// Name of the I/O subdevices.
pub const IO_NAME: &str = "Kerf digital I/O";
/// Input and output bits of an I/O subdevice.
pub const IO_BITS: u8 = 8;

/// A subdevice that refuses PRE-OP → SAFE-OP: it stays in PRE-OP with the AL status
/// error indicator set and this AL status code (0x0134), as a drive does whose
/// configuration does not suit it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SafeOpRefusal {
    /// Its position on the line (0 first).
    pub position: u16,
    /// The AL status code it answers with (0x001D, invalid output configuration, by
    /// default: [`al::CODE_INVALID_OUTPUT_CONFIG`]).
    pub al_status_code: u16,
}

/// A drive's home switch ([`drive::DriveDevice::set_home_switch`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HomeSwitch {
    /// The drive's position on the line (0 first).
    pub position: u16,
    /// Where the switch is in the motor's own frame, counts from power-up.
    pub counts: f64,
}

/// What to emulate.
#[derive(Debug, Clone, PartialEq)]
pub struct NetworkSpec {
    /// Number of drives.
    pub drives: u16,
    /// Number of I/O subdevices.
    pub io: u16,
    /// Vendor id of every subdevice.
    pub vendor_id: u32,
    /// Product code of the drives.
    pub drive_product_code: u32,
    /// Product code of the I/O subdevices.
    pub io_product_code: u32,
    /// Revision of every subdevice.
    pub revision: u32,
    /// The drives' servo model.
    pub sim: SimConfig,
    /// The ramp of a drive's motor velocity in cyclic synchronous velocity (mode 9, a
    /// spindle drive), counts/s² ([`drive::DEFAULT_VELOCITY_ACCEL_COUNTS_S2`] by default).
    pub velocity_accel_counts_s2: f64,
    /// Subdevices that refuse PRE-OP → SAFE-OP, each with its AL status code.
    pub refuse_safe_op: Vec<SafeOpRefusal>,
    /// The line's oscillator runs this many parts per million fast against the host's
    /// monotonic time (negative: slow): every subdevice's local clock advances
    /// `1 + dc_drift_ppm · 10⁻⁶` ns per host ns (see [`dc::oscillator_ns`]).
    pub dc_drift_ppm: f64,
    /// Drives with a home switch.
    pub home_switches: Vec<HomeSwitch>,
}

impl Default for NetworkSpec {
    fn default() -> Self {
        NetworkSpec {
            drives: 0,
            io: 0,
            vendor_id: VENDOR_ID,
            drive_product_code: DRIVE_PRODUCT_CODE,
            io_product_code: IO_PRODUCT_CODE,
            revision: REVISION,
            sim: SimConfig::default(),
            velocity_accel_counts_s2: drive::DEFAULT_VELOCITY_ACCEL_COUNTS_S2,
            refuse_safe_op: Vec::new(),
            dc_drift_ppm: 0.0,
            home_switches: Vec::new(),
        }
    }
}

/// Builds the line: the drives, then the I/O subdevices; returns the I/O handles too.
pub fn build(spec: &NetworkSpec) -> (Network, Vec<IoHandle>) {
    let mut escs = Vec::new();
    let mut handles = Vec::new();
    for n in 0..u32::from(spec.drives) {
        let identity = Identity {
            vendor_id: spec.vendor_id,
            product_code: spec.drive_product_code,
            revision: spec.revision,
            serial: DRIVE_SERIAL_BASE + n,
        };
        let mut app = DriveDevice::new(identity, DRIVE_NAME, spec.sim);
        app.set_velocity_accel_counts_s2(spec.velocity_accel_counts_s2);
        if let Some(switch) = spec
            .home_switches
            .iter()
            .rev()
            .find(|h| u32::from(h.position) == n)
        {
            app.set_home_switch(Some(switch.counts));
        }
        let clock = DcClock::new(u64::from(n) * 1_000_000, spec.dc_drift_ppm);
        escs.push(Esc::new(Box::new(app), clock));
    }
    for n in 0..u32::from(spec.io) {
        let identity = Identity {
            vendor_id: spec.vendor_id,
            product_code: spec.io_product_code,
            revision: spec.revision,
            serial: IO_SERIAL_BASE + n,
        };
        let (app, handle) = IoDevice::new(identity, IO_NAME, IO_BITS, IO_BITS);
        let clock = DcClock::new(500_000 + u64::from(n) * 1_000_000, spec.dc_drift_ppm);
        escs.push(Esc::new(Box::new(app), clock));
        handles.push(handle);
    }
    for refusal in &spec.refuse_safe_op {
        if let Some(esc) = escs.get_mut(usize::from(refusal.position)) {
            esc.refuse(al::AlState::SafeOp, refusal.al_status_code);
        }
    }
    (Network::new(escs), handles)
}
