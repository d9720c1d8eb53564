//! Drive side of Kerf: what stands between the interpolator's setpoints and the motors.
//!
//! - [`cia402`]: the CiA 402 drive profile (controlword 0x6040, statusword 0x6041, the
//!   power state machine, cyclic synchronous position mode 8) and the [`cia402::Drive`]
//!   interface a fieldbus drive or the simulated one implements.
//! - [`sim`]: the simulated servo drive: the whole state machine and a servo model, so
//!   that following error, overshoot and drive faults behave as a real drive's.
//! - [`safety`]: the checks of the real-time cycle above every drive (plausibility, soft
//!   limits, following error, stream supervision), latched faults, the quick stop.
//! - [`machine`]: the machine model: the program's actions on the spindle (a simulated
//!   spindle drive or outputs), coolant, tool changer and I/O image, its pauses and
//!   waits, and its faults.
//! - [`homing`]: the homing sequence of one axis (home switch, absolute encoder) as a
//!   state machine that tells the axis's mover what to do each cycle.
//! - [`recorder`]: the black-box ring of the last seconds of cycles and its CSV export.
//! - [`stage`]: all of it in one call per cycle: read the drives, enable them, check,
//!   write the targets, record; resets and black-box dumps.
//!
//! Everything called in the real-time cycle is allocation-free.
#![deny(missing_docs)]
#![forbid(unsafe_code)]

pub mod cia402;
pub mod homing;
pub mod machine;
pub mod recorder;
pub mod safety;
pub mod sim;
pub mod stage;

pub use kerf_geom::{MAX_AXES, PerAxis};
