//! The EtherCAT drive side of Kerf, on the pure-Rust MainDevice ethercrab, configured by
//! kerf.toml's `[ethercat]` table (`kerf_config::ethercat`).
//!
//! - [`identity`]: found against expected, one line per differing position.
//! - [`pdo`]: where the objects the control uses sit in a drive's process data.
//! - [`image`]: one drive's process data as a [`kerf_drive::cia402::Drive`], and the
//!   spindle drive's (cyclic synchronous velocity).
//! - [`iomap`]: the machine's digital inputs and outputs on the I/O subdevices' bits.
//! - [`al`]: a subdevice's EtherCAT states and AL status codes in words, and its status
//!   read.
//! - [`bus`]: bring-up to OP and the cyclic exchange.
//! - [`dc`]: the host's cycle locked onto the distributed clock's SYNC0.
//! - [`claim`]: one program at a time on an interface (the daemon or a commissioning
//!   command), the others refused naming the holder.
//! - [`commission`]: the scan and SDO access of `kerf ethercat`.
//! - [`pump`] and [`socket`]: ethercrab's frames moved by the owning thread through a raw
//!   socket, with no executor, no helper thread and no allocation per exchange.
#![deny(missing_docs)]

pub mod al;
pub mod bus;
pub mod claim;
pub mod commission;
pub mod dc;
pub mod identity;
pub mod image;
pub mod iomap;
pub mod pdo;
pub mod pump;
pub mod socket;
