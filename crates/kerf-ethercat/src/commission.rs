//! Commissioning without the daemon, as machine builders know it from IgH's `ethercat`
//! tool and SOEM's `slaveinfo`: a scan that lists every subdevice with its identity,
//! state, distributed-clock support, mailbox protocols and (over CoE) its PDO
//! assignment and mapping; and SDO reads and writes on one subdevice.
//!
//! Each runs on the calling thread and leaves the bus in PRE-OP. Each needs the
//! [`Claim`] on the interface, taken by the caller before and held until it returns:
//! while the daemon (or another command) holds the interface the claim is refused, and
//! no frame of a command reaches a bus someone else is running.

use std::fmt::Write as _;
use std::time::Duration;

use ethercrab::{DcSupport, MainDevice};
use kerf_config::ethercat::{SdoValue, SdoWrite};
use thiserror::Error;

use crate::bus::{BringUpError, Group, found_of, open, scan_group};
use crate::claim::Claim;
use crate::identity::Found;
use crate::pdo::{SM2_ASSIGNMENT, SM3_ASSIGNMENT};
use crate::pump::Pump;

/// SII word of the mailbox protocols a subdevice supports (ETG.2010).
const SII_MAILBOX_PROTOCOLS_WORD: u16 = 0x001C;
/// CoE in the mailbox protocols word.
const MAILBOX_COE: u16 = 0x0004;
/// Longest SDO exchange of a commissioning command.
const SDO_BOUND: Duration = Duration::from_secs(3);

/// One subdevice as the scan shows it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ScanEntry {
    /// Position and identity.
    pub found: Found,
    /// AL state and status code, in words ("PRE-OP", "0x0000: No error").
    pub state: String,
    /// Distributed clocks: "none", "reference only", "32-bit", "64-bit".
    pub dc: &'static str,
    /// Mailbox protocols ("CoE, FoE"), or "none".
    pub mailbox: String,
    /// PDO assignment and mapping read over CoE, one line per PDO (empty without CoE).
    pub pdos: Vec<String>,
}

impl ScanEntry {
    /// The entry as the scan prints it: one line, then the PDO lines indented.
    pub fn text(&self) -> String {
        let f = &self.found;
        let mut out = format!(
            "{:>3}  {:<24} vendor {:#010x} product {:#010x} revision {:#010x} serial {:#010x}  {}  DC {}  mailbox {}",
            f.position,
            format!("{:?}", f.name),
            f.vendor_id,
            f.product_code,
            f.revision,
            f.serial,
            self.state,
            self.dc,
            self.mailbox
        );
        for line in &self.pdos {
            let _ = write!(out, "\n       {line}");
        }
        out
    }
}

fn dc_words(dc: DcSupport) -> &'static str {
    match dc {
        DcSupport::None => "none",
        DcSupport::RefOnly => "reference only",
        DcSupport::Bits32 => "32-bit",
        DcSupport::Bits64 => "64-bit",
    }
}

fn mailbox_words(protocols: u16) -> String {
    let names = [
        (0x01, "AoE"),
        (0x02, "EoE"),
        (0x04, "CoE"),
        (0x08, "FoE"),
        (0x10, "SoE"),
        (0x20, "VoE"),
    ];
    let list: Vec<&str> = names
        .iter()
        .filter(|(bit, _)| protocols & bit != 0)
        .map(|&(_, n)| n)
        .collect();
    if list.is_empty() {
        "none".to_owned()
    } else {
        list.join(", ")
    }
}

/// Scans the bus on the claimed interface and describes every subdevice.
pub fn scan_detail(claim: &Claim) -> Result<Vec<ScanEntry>, BringUpError> {
    let timeouts = crate::bus::timeouts();
    let (maindevice, mut pump) = open(claim, timeouts)?;
    let group = scan_group(&maindevice, &mut pump, timeouts.state_transition * 2)?;
    let found = found_of(&group, &maindevice);
    let mut entries = Vec::with_capacity(found.len());
    for f in found {
        let index = usize::from(f.position);
        let sub = group
            .subdevice(&maindevice, index)
            .map_err(|source| step(&f, "not found", source))?;
        let (state, code) = run(&mut pump, &f, "AL status", sub.status())?;
        let protocols: u16 = run(
            &mut pump,
            &f,
            "SII mailbox protocols",
            sub.eeprom_read(&maindevice, SII_MAILBOX_PROTOCOLS_WORD),
        )?;
        let pdos = if protocols & MAILBOX_COE != 0 {
            pdo_lines(&mut pump, &group, &maindevice, &f)?
        } else {
            Vec::new()
        };
        entries.push(ScanEntry {
            state: format!("{state} ({code})"),
            dc: dc_words(sub.dc_support()),
            mailbox: mailbox_words(protocols),
            pdos,
            found: f,
        });
    }
    Ok(entries)
}

fn step(f: &Found, what: &str, source: ethercrab::error::Error) -> BringUpError {
    BringUpError::Step {
        step: format!("position {} {:?}: {what}", f.position, f.name),
        source,
    }
}

/// [`crate::bus::run`] for one subdevice, its step named by position and name.
fn run<T>(
    pump: &mut Pump,
    f: &Found,
    what: &str,
    future: impl Future<Output = Result<T, ethercrab::error::Error>>,
) -> Result<T, BringUpError> {
    let step = || format!("position {} {:?}: {what}", f.position, f.name);
    crate::bus::run(pump, step, future, SDO_BOUND)
}

/// "SM2 (outputs) 0x1600: 0x6040:00 16 bit, 0x607a:00 32 bit" for each assigned PDO.
fn pdo_lines(
    pump: &mut Pump,
    group: &Group,
    maindevice: &MainDevice<'static>,
    f: &Found,
) -> Result<Vec<String>, BringUpError> {
    let sub = group
        .subdevice(maindevice, usize::from(f.position))
        .map_err(|source| step(f, "not found", source))?;
    let mut lines = Vec::new();
    for (assignment, name) in [
        (SM2_ASSIGNMENT, "SM2 (outputs)"),
        (SM3_ASSIGNMENT, "SM3 (inputs)"),
    ] {
        let count: u8 = run(pump, f, "PDO assignment", sub.sdo_read(assignment, 0))?;
        for i in 1..=count {
            let pdo: u16 = run(pump, f, "PDO assignment", sub.sdo_read(assignment, i))?;
            let entries: u8 = run(pump, f, "PDO mapping", sub.sdo_read(pdo, 0))?;
            let mut line = format!("{name} {pdo:#06x}:");
            for e in 1..=entries {
                let value: u32 = run(pump, f, "PDO mapping", sub.sdo_read(pdo, e))?;
                let sep = if e == 1 { " " } else { ", " };
                let _ = write!(
                    line,
                    "{sep}{:#06x}:{:02x} {} bit",
                    value >> 16,
                    (value >> 8) & 0xFF,
                    value & 0xFF
                );
            }
            lines.push(line);
        }
    }
    Ok(lines)
}

/// A CoE data type of an SDO read or write.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SdoType {
    /// UNSIGNED8.
    U8,
    /// UNSIGNED16.
    U16,
    /// UNSIGNED32.
    U32,
    /// INTEGER8.
    I8,
    /// INTEGER16.
    I16,
    /// INTEGER32.
    I32,
}

/// A value that is not of its type.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("{text:?} is not a {type_name} value (decimal, or hex with 0x)")]
pub struct ValueError {
    /// The text given.
    pub text: String,
    /// The type's name.
    pub type_name: &'static str,
}

impl SdoType {
    /// The type named `u8`, `u16`, `u32`, `i8`, `i16` or `i32`.
    pub fn from_name(name: &str) -> Option<SdoType> {
        Some(match name {
            "u8" => SdoType::U8,
            "u16" => SdoType::U16,
            "u32" => SdoType::U32,
            "i8" => SdoType::I8,
            "i16" => SdoType::I16,
            "i32" => SdoType::I32,
            _ => return None,
        })
    }

    /// The type's name.
    pub fn name(self) -> &'static str {
        match self {
            SdoType::U8 => "u8",
            SdoType::U16 => "u16",
            SdoType::U32 => "u32",
            SdoType::I8 => "i8",
            SdoType::I16 => "i16",
            SdoType::I32 => "i32",
        }
    }

    /// `text` (decimal, or hex with `0x`, a leading `-` for the signed types) as a value
    /// of this type, range-checked.
    pub fn parse(self, text: &str) -> Result<SdoValue, ValueError> {
        let bad = || ValueError {
            text: text.to_owned(),
            type_name: self.name(),
        };
        let t = text.trim();
        let (negative, digits) = match t.strip_prefix('-') {
            Some(rest) => (true, rest),
            None => (false, t),
        };
        let magnitude = match digits
            .strip_prefix("0x")
            .or_else(|| digits.strip_prefix("0X"))
        {
            Some(hex) => i64::from_str_radix(hex, 16),
            None => digits.parse::<i64>(),
        }
        .map_err(|_| bad())?;
        let v = if negative { -magnitude } else { magnitude };
        Ok(match self {
            SdoType::U8 => SdoValue::U8(u8::try_from(v).map_err(|_| bad())?),
            SdoType::U16 => SdoValue::U16(u16::try_from(v).map_err(|_| bad())?),
            SdoType::U32 => SdoValue::U32(u32::try_from(v).map_err(|_| bad())?),
            SdoType::I8 => SdoValue::I8(i8::try_from(v).map_err(|_| bad())?),
            SdoType::I16 => SdoValue::I16(i16::try_from(v).map_err(|_| bad())?),
            SdoType::I32 => SdoValue::I32(i32::try_from(v).map_err(|_| bad())?),
        })
    }
}

/// The value as the commands print it: decimal, and hex for the unsigned types.
pub fn value_text(value: SdoValue) -> String {
    match value {
        SdoValue::U8(v) => format!("{v} ({v:#04x})"),
        SdoValue::U16(v) => format!("{v} ({v:#06x})"),
        SdoValue::U32(v) => format!("{v} ({v:#010x})"),
        SdoValue::I8(v) => v.to_string(),
        SdoValue::I16(v) => v.to_string(),
        SdoValue::I32(v) => v.to_string(),
    }
}

/// Opens the bus and runs `f` on the subdevice at `position` (its SDO reads and writes).
fn on_subdevice<T>(
    claim: &Claim,
    position: u16,
    what: &str,
    f: impl for<'a> FnOnce(
        &'a mut Pump,
        &'a Group,
        &'a MainDevice<'static>,
        &'a Found,
    ) -> Result<T, BringUpError>,
) -> Result<T, BringUpError> {
    let timeouts = crate::bus::timeouts();
    let (maindevice, mut pump) = open(claim, timeouts)?;
    let group = scan_group(&maindevice, &mut pump, timeouts.state_transition * 2)?;
    let found = found_of(&group, &maindevice);
    let Some(sub) = found.into_iter().find(|s| s.position == position) else {
        return Err(BringUpError::Mismatch {
            lines: vec![format!("position {position}: nothing found for {what}")],
        });
    };
    f(&mut pump, &group, &maindevice, &sub)
}

/// Reads object `index:subindex` of the subdevice at `position` on the claimed interface
/// as `kind`.
pub fn sdo_read(
    claim: &Claim,
    position: u16,
    index: u16,
    subindex: u8,
    kind: SdoType,
) -> Result<SdoValue, BringUpError> {
    on_subdevice(
        claim,
        position,
        "the SDO read",
        |pump, group, maindevice, f| {
            let sub = group
                .subdevice(maindevice, usize::from(position))
                .map_err(|source| step(f, "not found", source))?;
            let what = format!("SDO read {index:#06x}:{subindex}");
            Ok(match kind {
                SdoType::U8 => SdoValue::U8(run(pump, f, &what, sub.sdo_read(index, subindex))?),
                SdoType::U16 => SdoValue::U16(run(pump, f, &what, sub.sdo_read(index, subindex))?),
                SdoType::U32 => SdoValue::U32(run(pump, f, &what, sub.sdo_read(index, subindex))?),
                SdoType::I8 => SdoValue::I8(run(pump, f, &what, sub.sdo_read(index, subindex))?),
                SdoType::I16 => SdoValue::I16(run(pump, f, &what, sub.sdo_read(index, subindex))?),
                SdoType::I32 => SdoValue::I32(run(pump, f, &what, sub.sdo_read(index, subindex))?),
            })
        },
    )
}

/// Writes `value` to object `index:subindex` of the subdevice at `position` on the
/// claimed interface.
pub fn sdo_write(
    claim: &Claim,
    position: u16,
    index: u16,
    subindex: u8,
    value: SdoValue,
) -> Result<(), BringUpError> {
    on_subdevice(
        claim,
        position,
        "the SDO write",
        |pump, group, maindevice, f| {
            let sub = group
                .subdevice(maindevice, usize::from(position))
                .map_err(|source| step(f, "not found", source))?;
            let what = format!("SDO write {index:#06x}:{subindex}");
            let write = SdoWrite {
                index,
                subindex,
                value,
            };
            run(pump, f, &what, crate::bus::sdo_write(&sub, write))
        },
    )
}

/// What `kerf ethercat exchange` measured: the round trip of each cyclic exchange.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RoundTrips {
    /// Round trips of the complete exchanges, ns, sorted.
    pub complete_ns: Vec<u64>,
    /// Exchanges whose frame did not come back within the period.
    pub lost: u64,
    /// Exchanges with a working counter short of the bus's.
    pub short: u64,
    /// Exchanges with a subdevice not in OP.
    pub not_op: u64,
}

impl RoundTrips {
    /// The `q` quantile of the complete round trips, ns (0 when there is none).
    pub fn quantile_ns(&self, q: f64) -> u64 {
        let n = self.complete_ns.len();
        if n == 0 {
            return 0;
        }
        let i = ((n as f64 * q).ceil() as usize).clamp(1, n) - 1;
        self.complete_ns[i]
    }
}

/// Brings the bus of `config` to OP for a cycle of `period_ns` and runs `cycles`
/// exchanges paced at the period, with every drive's controlword 0 (the drives stay
/// disabled: nothing moves), timing each round trip. For commissioning a NIC and for the
/// figures in PERFORMANCE.md. Not real-time: the pacing is a plain sleep. `claim` must be
/// on the configuration's interface.
pub fn exchange_round_trips(
    claim: &Claim,
    config: &kerf_config::ethercat::EthercatConfig,
    period_ns: u64,
    cycles: u32,
) -> Result<RoundTrips, BringUpError> {
    let mut bus = crate::bus::Bus::bring_up(config, period_ns, claim)?;
    let expected = bus.expected_working_counter();
    let period = Duration::from_nanos(period_ns);
    let mut out = RoundTrips {
        complete_ns: Vec::with_capacity(cycles as usize),
        lost: 0,
        short: 0,
        not_op: 0,
    };
    let mut next = std::time::Instant::now();
    for _ in 0..cycles {
        next += period;
        let started = std::time::Instant::now();
        match crate::bus::outcome(&bus.tx_rx(period), expected) {
            crate::bus::Outcome::NotOp(_) => out.not_op += 1,
            crate::bus::Outcome::Short => out.short += 1,
            crate::bus::Outcome::Complete => out
                .complete_ns
                .push(u64::try_from(started.elapsed().as_nanos()).unwrap_or(u64::MAX)),
            crate::bus::Outcome::Lost => out.lost += 1,
        }
        std::thread::sleep(next.saturating_duration_since(std::time::Instant::now()));
    }
    out.complete_ns.sort_unstable();
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_are_parsed_in_decimal_or_hex_within_their_type() {
        assert_eq!(SdoType::U8.parse("255"), Ok(SdoValue::U8(255)));
        assert_eq!(SdoType::U16.parse("0x1600"), Ok(SdoValue::U16(0x1600)));
        assert_eq!(SdoType::I8.parse("-128"), Ok(SdoValue::I8(-128)));
        assert_eq!(SdoType::I32.parse("-0x10"), Ok(SdoValue::I32(-16)));
        assert_eq!(
            SdoType::U32.parse("4294967295"),
            Ok(SdoValue::U32(u32::MAX))
        );
        for (kind, text) in [
            (SdoType::U8, "256"),
            (SdoType::U8, "-1"),
            (SdoType::I8, "128"),
            (SdoType::U16, "x12"),
            (SdoType::U32, ""),
        ] {
            let e = kind.parse(text).unwrap_err();
            assert_eq!(
                e.to_string(),
                format!(
                    "{text:?} is not a {} value (decimal, or hex with 0x)",
                    kind.name()
                )
            );
        }
    }

    #[test]
    fn types_are_named_as_the_configuration_names_them() {
        for name in ["u8", "u16", "u32", "i8", "i16", "i32"] {
            assert_eq!(SdoType::from_name(name).map(SdoType::name), Some(name));
        }
        assert_eq!(SdoType::from_name("f32"), None);
    }

    #[test]
    fn quantiles_are_taken_from_the_sorted_round_trips() {
        let r = RoundTrips {
            complete_ns: (1..=1000).collect(),
            lost: 0,
            short: 0,
            not_op: 0,
        };
        assert_eq!(r.quantile_ns(0.5), 500);
        assert_eq!(r.quantile_ns(0.99), 990);
        assert_eq!(r.quantile_ns(0.999), 999);
        assert_eq!(r.quantile_ns(1.0), 1000);
        let none = RoundTrips {
            complete_ns: Vec::new(),
            lost: 3,
            short: 0,
            not_op: 0,
        };
        assert_eq!(none.quantile_ns(0.5), 0);
    }

    #[test]
    fn mailbox_protocols_and_dc_support_are_named() {
        assert_eq!(mailbox_words(0x0004), "CoE");
        assert_eq!(mailbox_words(0x000C), "CoE, FoE");
        assert_eq!(mailbox_words(0), "none");
        assert_eq!(dc_words(DcSupport::Bits64), "64-bit");
    }
}
