//! What Kerf's tests share; a dev-dependency of the crates whose tests use it, never a
//! dependency of shipped code.
//!
//! - [`alloc`]: a counting global allocator, armed per thread, that the allocation tests
//!   of the real-time paths install (the motion core, the daemon's cycle, the drive side,
//!   the periodic clock, the interpreter's hot path);
//! - [`config_text`]: the bundled example machine's configuration without its homing, for
//!   tests that run programs on it but are not about homing;
//! - [`machines`]: the test machines the planner and motion tests measure against;
//! - [`netns`]: a private network namespace with a veth pair, for the EtherCAT tests.
#![deny(missing_docs)]

pub mod alloc;
pub mod config_text;
pub mod machines;
pub mod netns;
