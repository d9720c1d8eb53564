//! The `kerf` command-line tool as a library, so that tests and benches run it in-process.
//!
//! - [`plan`](mod@plan): `kerf plan`, the resolved program as JSON lines (the front end's contract).
//! - [`sim`]: `kerf sim`, the whole pipeline in virtual time.
//! - [`sim_plot`]: its plot (`kerf sim --plot FILE.svg|FILE.png`).
//! - [`client`]: requests, status and the setpoint stream for `kerf run`, `status`,
//!   `hold`, `resume`, `abort`, `override`, `record`, `reset` and `dump`.
//! - [`dro`]: the machine's offsets and the work position (`kerf status`, `kerf offset`).
//! - [`blackbox`]: the drive side's black-box files read and drawn (`kerf plot`).
//! - [`clidoc`]: shell completions and man pages from the binaries' clap definitions.
//!
//! The machine configuration is the crate `kerf_config`; the daemon (`kerfd`, and `kerf
//! run --embedded` in-process) is the crate `kerfd`.
//!
//! The binary (`src/bin/kerf`) only parses arguments, opens files, prints errors and
//! picks exit codes; everything with behaviour worth testing lives here. The library's
//! errors are typed enums that say what went wrong and where; the binary turns each into
//! one line, `FILE:LINE:COL: error: MESSAGE`, and a non-zero exit code.
#![deny(missing_docs)]
#![forbid(unsafe_code)]

pub mod blackbox;
pub mod clidoc;
pub mod client;
pub mod dro;
pub mod plan;
pub mod serve;
pub mod sim;
pub mod sim_plot;
pub mod status_view;

pub use plan::{
    DialectSource, PlanOutputError, assumed_dialect_note, choose_dialect, choose_dialect_from,
    plan, plan_counted,
};
