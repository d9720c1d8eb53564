//! The `kerf` command-line tools and the daemon `kerfd` as a library, so that tests and
//! benches run them in-process.
//!
//! - [`config`]: the machine configuration file (TOML), validated once into a plain record.
//! - [`plan`](mod@plan): `kerf plan`, the resolved program as JSON lines (the front end's contract).
//! - [`sim`]: `kerf sim`, the whole pipeline in virtual time.
//! - [`sim_plot`]: its plot (`kerf sim --plot FILE.svg|FILE.png`).
//! - [`travel`]: the configured travel limits checked on the exact path before any motion.
//! - [`daemon`]: the interpolator daemon's threads (`kerfd`, `kerf run --embedded`).
//! - [`ipc`]: the iceoryx2 services of a machine, opened alike by the daemon and clients.
//! - [`client`]: requests, status and the setpoint stream for `kerf run`, `status`,
//!   `hold`, `resume`, `abort`, `override`, `record`, `reset` and `dump`.
//! - [`blackbox`]: the drive side's black-box files read and drawn (`kerf plot`).
//! - [`clidoc`]: shell completions and man pages from the binaries' clap definitions.
//!
//! The binaries (`src/bin/kerf`, `src/bin/kerfd.rs`) only parse arguments, open files,
//! print errors and pick exit codes; everything with behaviour worth testing lives here.
//! The library's errors are typed enums that say what went wrong and where; the binary
//! turns each into one line, `FILE:LINE:COL: error: MESSAGE`, and a non-zero exit code.
#![deny(missing_docs)]
#![forbid(unsafe_code)]

pub mod blackbox;
pub mod clidoc;
pub mod client;
pub mod config;
pub mod daemon;
pub mod ipc;
pub mod plan;
pub mod sim;
pub mod sim_plot;
pub mod tooltable;
pub mod travel;

pub use config::{Config, ConfigError};
pub use plan::{
    DialectSource, PlanError, assumed_dialect_note, choose_dialect, choose_dialect_from, plan,
    plan_counted,
};
