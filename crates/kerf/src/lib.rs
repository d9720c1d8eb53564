//! The `kerf` command-line tools as a library, so that tests and benches run them in-process.
//!
//! - [`config`]: the machine configuration file (TOML), validated once into a plain record.
//! - [`plan`](mod@plan): `kerf plan`, the resolved program as JSON lines (the front end's contract).
//! - [`sim`]: `kerf sim`, the whole pipeline in virtual time.
//! - [`travel`]: the configured travel limits checked on the exact path before any motion.
//!
//! The binary (`src/main.rs`) only parses arguments, opens files, prints errors and picks
//! exit codes; everything with behaviour worth testing lives here. The library's errors are
//! typed enums that say what went wrong and where; the binary turns each into one line,
//! `FILE:LINE:COL: error: MESSAGE`, and exit code 2.
#![deny(missing_docs)]

pub mod config;
pub mod plan;
pub mod sim;
pub mod travel;

pub use config::{Config, ConfigError};
pub use plan::{PlanError, choose_dialect, plan};
