//! `[ethercat]` checked: the bus settings, a drive for every configured axis and nothing
//! else, every subdevice at its own ring position without gaps, I/O names unique on the
//! bus, and the axes' `[axes.*.drive]` consistent with being driven over the bus.

use std::collections::BTreeMap;

use kerf_drive::MAX_AXES;
use toml::Spanned;

use crate::ethercat::*;
use crate::raw::*;
use crate::*;

use super::Checker;
use super::ethercat_objects::Needed;

/// The axes' names as `axis` gives them, X to C.
const AXIS_KEYS: [&str; MAX_AXES] = ["x", "y", "z", "a", "b", "c"];

/// The spindle's name as `axis` gives it.
const SPINDLE_AXIS_KEY: &str = "s";

impl Checker<'_> {
    /// `[ethercat]` for the machine whose axes are `axes`, at `period_us`; marks the axes'
    /// drives as EtherCAT drives in `drive`.
    pub(crate) fn ethercat(
        &self,
        raw: &RawConfig,
        axes: &Axes,
        period_us: u32,
        drive: &mut DriveSide,
    ) -> Result<Option<EthercatConfig>, ConfigError> {
        let raw_drives = raw_axis_drives(raw);
        let Some(table) = &raw.ethercat else {
            for (i, d) in raw_drives.iter().enumerate() {
                if let Some(k) = d.and_then(|d| d.kind.as_ref())
                    && k.get_ref() == "ethercat"
                {
                    return Err(self.error(
                        k.span(),
                        format!(
                            "`axes.{}.drive.kind` is \"ethercat\" but the file has no [ethercat] table with a [[ethercat.drives]] for axis {}",
                            AXIS_KEYS[i],
                            AXIS_KEYS[i]
                        ),
                    ));
                }
            }
            return Ok(None);
        };
        let e = table.get_ref();
        let period_ns = period_us * 1000;
        let interface = self.interface(&e.interface)?;
        let dc = e.dc.unwrap_or(DEFAULT_ETHERCAT_DC);
        if let (false, Some(s)) = (dc, &e.sync0_shift_ns) {
            return Err(self.error(
                s.span(),
                "`ethercat.sync0_shift_ns` shifts SYNC0, which runs only with distributed clocks: remove it or set `ethercat.dc = true`".to_string(),
            ));
        }
        let sync0_shift_ns = match &e.sync0_shift_ns {
            None => period_ns / 2,
            Some(s) => self.integer(
                "ethercat.sync0_shift_ns",
                "a time in ns below the period",
                0..=period_ns - 1,
                s,
            )?,
        };
        let config = EthercatConfig {
            interface,
            dc,
            sync0_shift_ns,
            max_missed_cycles: self.integer_or(
                "ethercat.max_missed_cycles",
                "a number of cycles",
                MAX_MISSED_CYCLES_RANGE,
                &e.max_missed_cycles,
                DEFAULT_MAX_MISSED_CYCLES,
            )?,
            watchdog_us: self.watchdog(&e.watchdog_us, period_us)?,
            state_timeout_ms: self.timeout(
                "state_timeout_ms",
                &e.state_timeout_ms,
                DEFAULT_STATE_TIMEOUT_MS,
            )?,
            sdo_timeout_ms: self.timeout(
                "sdo_timeout_ms",
                &e.sdo_timeout_ms,
                DEFAULT_SDO_TIMEOUT_MS,
            )?,
            dc_settle_timeout_ms: self.timeout(
                "dc_settle_timeout_ms",
                &e.dc_settle_timeout_ms,
                DEFAULT_DC_SETTLE_TIMEOUT_MS,
            )?,
            drives: self.ecat_drives(e, table.span(), axes, &homed_by_drive(raw))?,
            io: self.ecat_io(e)?,
        };
        self.positions(e)?;
        self.axis_drives_on_the_bus(&raw_drives, &config, drive)?;
        Ok(Some(config))
    }

    /// `ethercat.interface`: a Linux network interface name.
    fn interface(&self, raw: &Spanned<String>) -> Result<String, ConfigError> {
        let name = raw.get_ref();
        // Linux: at most IFNAMSIZ - 1 = 15 bytes, no '/', no white space, not "." or "..".
        let valid = (1..=15).contains(&name.len())
            && !name
                .chars()
                .any(|c| c == '/' || c == ':' || c.is_whitespace())
            && name != "."
            && name != "..";
        if valid {
            Ok(name.clone())
        } else {
            Err(self.error(
                raw.span(),
                format!(
                    "`ethercat.interface` must be a network interface name (1 to 15 characters, no `/`, `:` or spaces), found `{name}`"
                ),
            ))
        }
    }

    /// `ethercat.watchdog_us`: whole watchdog units, at least two periods.
    fn watchdog(&self, raw: &Option<Spanned<i64>>, period_us: u32) -> Result<u32, ConfigError> {
        let min_us = MIN_WATCHDOG_PERIODS * period_us;
        let Some(raw) = raw else {
            if DEFAULT_WATCHDOG_US < min_us {
                return Err(ConfigError::Invalid {
                    origin: self.origin.to_string(),
                    position: None,
                    message: format!(
                        "the default `ethercat.watchdog_us` ({DEFAULT_WATCHDOG_US} µs) is shorter than {MIN_WATCHDOG_PERIODS} periods (`period_us` = {period_us}): set `ethercat.watchdog_us` to at least {}",
                        min_us.div_ceil(WATCHDOG_UNIT_US) * WATCHDOG_UNIT_US
                    ),
                });
            }
            return Ok(DEFAULT_WATCHDOG_US);
        };
        let v = self.integer(
            "ethercat.watchdog_us",
            &format!("a time in µs ({MIN_WATCHDOG_PERIODS} periods or more)"),
            min_us..=MAX_WATCHDOG_US,
            raw,
        )?;
        if v % WATCHDOG_UNIT_US != 0 {
            return Err(self.error(
                raw.span(),
                format!(
                    "`ethercat.watchdog_us` must be a multiple of {WATCHDOG_UNIT_US} µs (the subdevices' watchdog unit), found {v}"
                ),
            ));
        }
        Ok(v)
    }

    /// One of the bring-up timeouts, `ethercat.NAME`.
    fn timeout(
        &self,
        name: &str,
        raw: &Option<Spanned<i64>>,
        default: u32,
    ) -> Result<u32, ConfigError> {
        self.integer_or(
            &format!("ethercat.{name}"),
            "a time in ms",
            BRING_UP_TIMEOUT_RANGE_MS,
            raw,
            default,
        )
    }

    /// `[[ethercat.drives]]`: each names a configured axis, at most once.
    fn ecat_drives(
        &self,
        e: &RawEthercat,
        table: std::ops::Range<usize>,
        axes: &Axes,
        by_drive: &[bool; MAX_AXES],
    ) -> Result<Vec<EthercatDrive>, ConfigError> {
        let configured = axes.present();
        let mut out: Vec<EthercatDrive> = Vec::with_capacity(e.drives.len());
        for (i, d) in e.drives.iter().enumerate() {
            let key = format!("ethercat.drives[{i}]");
            let name = d.axis.get_ref().to_ascii_lowercase();
            let axis_index = match AXIS_KEYS.iter().position(|a| *a == name) {
                Some(a) if configured[a] => a,
                None if name == SPINDLE_AXIS_KEY => SPINDLE_AXIS_INDEX,
                found => {
                    let known: Vec<&str> = AXIS_KEYS
                        .iter()
                        .zip(configured)
                        .filter_map(|(a, c)| c.then_some(*a))
                        .collect();
                    let why = if found.is_some() {
                        format!(" (the file has no [axes.{name}])")
                    } else {
                        String::new()
                    };
                    return Err(self.error(
                        d.axis.span(),
                        format!(
                            "`{key}.axis` must be one of the configured axes {}, or s for the spindle, found `{}`{why}",
                            known.join(", "),
                            d.axis.get_ref()
                        ),
                    ));
                }
            };
            if let Some(j) = out.iter().position(|o| o.axis_index == axis_index) {
                return Err(self.error(
                    d.axis.span(),
                    if axis_index == SPINDLE_AXIS_INDEX {
                        format!(
                            "the spindle has two drives: `{key}` and `ethercat.drives[{j}]`; it has one"
                        )
                    } else {
                        format!(
                            "axis {name} has two drives: `{key}` and `ethercat.drives[{j}]`; each axis has one"
                        )
                    },
                ));
            }
            let homes = by_drive.get(axis_index).copied().unwrap_or(false);
            out.push(self.ecat_drive(&key, d, axis_index, homes)?);
        }
        if let Some(missing) =
            (0..MAX_AXES).find(|&a| configured[a] && !out.iter().any(|d| d.axis_index == a))
        {
            return Err(self.error(
                table,
                format!(
                    "axis {} has no drive: with [ethercat], every configured axis needs a [[ethercat.drives]] with `axis = \"{}\"`",
                    AXIS_KEYS[missing], AXIS_KEYS[missing]
                ),
            ));
        }
        Ok(out)
    }

    /// One `[[ethercat.drives]]` at `key`, for axis `axis_index`; `homes` when the axis
    /// homes by its drive: its default mapping carries the mode of operation (0x6060
    /// out, 0x6061 in), which the daemon switches to homing mode and back in the cyclic
    /// data, and a mapping of the file's must carry 0x6060.
    fn ecat_drive(
        &self,
        key: &str,
        d: &RawEcatDrive,
        axis_index: usize,
        homes: bool,
    ) -> Result<EthercatDrive, ConfigError> {
        let spindle = axis_index == SPINDLE_AXIS_INDEX;
        let mode = match &d.mode {
            None if spindle => DriveMode::Csv,
            None => DriveMode::Csp,
            Some(m) if m.get_ref() == "csp" => DriveMode::Csp,
            Some(m) if m.get_ref() == "csv" => DriveMode::Csv,
            Some(m) => {
                return Err(self.error(
                    m.span(),
                    format!(
                        "`{key}.mode` must be \"csp\" (cyclic synchronous position) or \"csv\" (cyclic synchronous velocity), found `{}`",
                        m.get_ref()
                    ),
                ));
            }
        };
        match (&d.mode, spindle, mode) {
            (Some(m), true, DriveMode::Csp) => {
                return Err(self.error(
                    m.span(),
                    format!(
                        "`{key}.mode` is \"csp\" but the drive is the spindle's (`axis = \"s\"`), which runs in cyclic synchronous velocity: make it \"csv\" or remove it"
                    ),
                ));
            }
            (Some(m), false, DriveMode::Csv) => {
                return Err(self.error(
                    m.span(),
                    format!(
                        "`{key}.mode` is \"csv\" (cyclic synchronous velocity), which only the spindle's drive (`axis = \"s\"`) runs; axis {} runs in \"csp\"",
                        AXIS_KEYS[axis_index]
                    ),
                ));
            }
            _ => {}
        }
        let target = match mode {
            DriveMode::Csp => "target position",
            DriveMode::Csv => "target velocity",
        };
        let (mut default_rx, mut default_tx) = (Pdo::default_rx(mode), Pdo::default_tx());
        if homes {
            default_rx.entries.push(PdoEntry {
                index: MODES_OF_OPERATION,
                subindex: 0,
                bits: 8,
            });
            default_tx.entries.push(PdoEntry {
                index: MODES_OF_OPERATION_DISPLAY,
                subindex: 0,
                bits: 8,
            });
        }
        let rx_pdo = self.pdo(
            &format!("{key}.rx_pdo"),
            &format!("{key}.rx_pdo_index"),
            RX_PDO_INDEX_RANGE,
            &d.rx_pdo_index,
            &d.rx_pdo,
            default_rx,
            &[
                Needed {
                    object: CONTROLWORD,
                    bits: 16,
                    what: "controlword",
                },
                Needed {
                    object: mode.target(),
                    bits: 32,
                    what: target,
                },
            ],
        )?;
        let actual = if spindle {
            Needed {
                object: VELOCITY_ACTUAL,
                bits: 32,
                what: "velocity actual value",
            }
        } else {
            Needed {
                object: POSITION_ACTUAL,
                bits: 32,
                what: "position actual value",
            }
        };
        let tx_pdo = self.pdo(
            &format!("{key}.tx_pdo"),
            &format!("{key}.tx_pdo_index"),
            TX_PDO_INDEX_RANGE,
            &d.tx_pdo_index,
            &d.tx_pdo,
            default_tx,
            &[
                Needed {
                    object: STATUSWORD,
                    bits: 16,
                    what: "statusword",
                },
                actual,
            ],
        )?;
        if let Some(both) = rx_pdo
            .entries
            .iter()
            .find(|r| r.index != 0 && tx_pdo.bit_offset(r.index, r.subindex).is_some())
        {
            let span = d.rx_pdo.as_ref().or(d.tx_pdo.as_ref()).map(|p| p.span());
            let message = format!(
                "`{key}` maps {} both in `rx_pdo` and in `tx_pdo`",
                super::ethercat_objects::object_name((both.index, both.subindex))
            );
            return Err(match span {
                Some(span) => self.error(span, message),
                None => self.unplaced(message),
            });
        }
        if let (true, Some(raw)) = (homes, &d.rx_pdo)
            && rx_pdo
                .bit_offset(MODES_OF_OPERATION, 0)
                .map(|(_, bits)| bits)
                != Some(8)
        {
            return Err(self.error(
                raw.span(),
                format!(
                    "`{key}.rx_pdo` must map the modes of operation 0x6060:00 (8 bits): axis {} homes by its drive (`axes.{}.homing.kind = \"drive\"`), which the daemon switches to homing mode (6) and back in the cyclic data",
                    AXIS_KEYS[axis_index], AXIS_KEYS[axis_index]
                ),
            ));
        }
        let homing_table = format!(
            "[axes.{}.homing]",
            AXIS_KEYS.get(axis_index).unwrap_or(&"s")
        );
        let mut reserved = vec![
            (MODES_OF_OPERATION, "`mode`"),
            (INTERPOLATION_PERIOD, "`period_us`"),
            (RX_PDO_ASSIGN, "`rx_pdo_index`"),
            (TX_PDO_ASSIGN, "`tx_pdo_index`"),
            (rx_pdo.index, "`rx_pdo`"),
            (tx_pdo.index, "`tx_pdo`"),
        ];
        if homes {
            // The homing objects come from the axis's homing table.
            for index in HOMING_OBJECTS {
                reserved.push((index, homing_table.as_str()));
            }
        }
        Ok(EthercatDrive {
            axis_index,
            position: self.integer(
                &format!("{key}.position"),
                "a ring position",
                RING_POSITION_RANGE,
                &d.position,
            )? as u16,
            identity: self.identity(key, &d.vendor_id, &d.product_code, &d.revision)?,
            mode,
            sdo: self.sdo_list(&format!("{key}.sdo"), &d.sdo, &reserved)?,
            rx_pdo,
            tx_pdo,
            // Filled in once the axis's homing is checked (`Config::drive_homing_objects`).
            homing: None,
        })
    }

    /// `[[ethercat.io]]`: identities, SDO lists and named bits, names unique on the bus.
    fn ecat_io(&self, e: &RawEthercat) -> Result<Vec<EthercatIo>, ConfigError> {
        let mut names: BTreeMap<String, String> = BTreeMap::new();
        let mut out = Vec::with_capacity(e.io.len());
        for (i, io) in e.io.iter().enumerate() {
            let key = format!("ethercat.io[{i}]");
            let inputs = self.io_bits(&format!("{key}.inputs"), &io.inputs, &mut names)?;
            let outputs = self.io_bits(&format!("{key}.outputs"), &io.outputs, &mut names)?;
            out.push(EthercatIo {
                position: self.integer(
                    &format!("{key}.position"),
                    "a ring position",
                    RING_POSITION_RANGE,
                    &io.position,
                )? as u16,
                identity: self.identity(&key, &io.vendor_id, &io.product_code, &io.revision)?,
                sdo: self.sdo_list(&format!("{key}.sdo"), &io.sdo, &[])?,
                inputs,
                outputs,
            });
        }
        Ok(out)
    }

    /// The named bits of one direction of an I/O subdevice (`key`), in bit order; `names`
    /// holds every name seen on the bus with where.
    fn io_bits(
        &self,
        key: &str,
        raw: &BTreeMap<String, Spanned<i64>>,
        names: &mut BTreeMap<String, String>,
    ) -> Result<Vec<IoBit>, ConfigError> {
        let mut out: Vec<IoBit> = Vec::with_capacity(raw.len());
        for (name, bit) in raw {
            let here = format!("{key}.{name}");
            if !super::valid_io_name(name) {
                return Err(self.error(
                    bit.span(),
                    format!(
                        "`{here}`: a bit's name must be 1 to 64 ASCII letters, digits, `_` or `-`, starting with a letter"
                    ),
                ));
            }
            if let Some(first) = names.get(name) {
                return Err(self.error(
                    bit.span(),
                    format!(
                        "the bit name `{name}` is used twice on the bus: `{first}` and `{here}`"
                    ),
                ));
            }
            let n = self.integer(&here, "a bit number", IO_BIT_RANGE, bit)? as u16;
            if let Some(other) = out.iter().find(|b| b.bit == n) {
                return Err(self.error(
                    bit.span(),
                    format!("`{here}` and `{key}.{}` are both bit {n}", other.name),
                ));
            }
            names.insert(name.clone(), here);
            out.push(IoBit {
                name: name.clone(),
                bit: n,
            });
        }
        out.sort_by_key(|b| b.bit);
        Ok(out)
    }

    /// Every subdevice at its own ring position, the positions 0 to N-1 without gaps.
    fn positions(&self, e: &RawEthercat) -> Result<(), ConfigError> {
        let all: Vec<(String, &Spanned<i64>)> = e
            .drives
            .iter()
            .enumerate()
            .map(|(i, d)| (format!("ethercat.drives[{i}]"), &d.position))
            .chain(
                e.io.iter()
                    .enumerate()
                    .map(|(i, io)| (format!("ethercat.io[{i}]"), &io.position)),
            )
            .collect();
        for (i, (key, p)) in all.iter().enumerate() {
            if let Some((first, _)) = all[..i].iter().find(|(_, q)| q.get_ref() == p.get_ref()) {
                return Err(self.error(
                    p.span(),
                    format!(
                        "`{key}.position` = {} is also the position of `{first}`; each subdevice has its own",
                        p.get_ref()
                    ),
                ));
            }
        }
        let n = all.len() as i64;
        if let Some((key, p)) = all.iter().find(|(_, p)| *p.get_ref() >= n) {
            let missing = (0..n)
                .find(|q| !all.iter().any(|(_, p)| p.get_ref() == q))
                .unwrap_or(0);
            return Err(self.error(
                p.span(),
                format!(
                    "`{key}.position` = {} but the bus lists {n} subdevices, so positions are 0 to {}: nothing is at position {missing}. List every subdevice on the ring (a coupler as an [[ethercat.io]] without bits)",
                    p.get_ref(),
                    n - 1
                ),
            ));
        }
        Ok(())
    }

    /// The axes' drives with `[ethercat]`: kind "ethercat", none of the simulated drive's
    /// tuning keys.
    fn axis_drives_on_the_bus(
        &self,
        raw_drives: &[Option<&RawDrive>; MAX_AXES],
        config: &EthercatConfig,
        drive: &mut DriveSide,
    ) -> Result<(), ConfigError> {
        for (i, d) in drive.axes.iter_mut().enumerate() {
            let Some(d) = d else { continue };
            if let Some(raw) = raw_drives[i] {
                let position = config.drive_of_axis(i).map_or(0, |d| d.position);
                if let Some(k) = &raw.kind
                    && k.get_ref() != "ethercat"
                {
                    return Err(self.error(
                        k.span(),
                        format!(
                            "`axes.{}.drive.kind` is \"{}\" but axis {} is driven over EtherCAT (the drive at position {position}); remove `kind` or make it \"ethercat\"",
                            AXIS_KEYS[i],
                            k.get_ref(),
                            AXIS_KEYS[i]
                        ),
                    ));
                }
                if let Some((name, span)) = sim_tuning_keys(raw).into_iter().flatten().next() {
                    return Err(self.error(
                        span,
                        format!(
                            "`axes.{}.drive.{name}` tunes the simulated drive, but axis {} is driven over EtherCAT (the drive at position {position}); remove it",
                            AXIS_KEYS[i],
                            AXIS_KEYS[i]
                        ),
                    ));
                }
            }
            d.kind = DriveKind::Ethercat;
        }
        Ok(())
    }

    /// An error without a place in the file.
    fn unplaced(&self, message: String) -> ConfigError {
        ConfigError::Invalid {
            origin: self.origin.to_string(),
            position: None,
            message,
        }
    }
}

/// The raw `[axes.*.drive]` tables, X to C.
/// Per axis, X to C: whether `raw` homes it by its drive (`[axes.*.homing] kind =
/// "drive"`; the kind itself is checked with the homing).
fn homed_by_drive(raw: &RawConfig) -> [bool; MAX_AXES] {
    let kind = |h: Option<&Spanned<String>>| h.is_some_and(|k| k.get_ref() == "drive");
    let a = &raw.axes;
    [
        kind(a.x.homing.as_ref().map(|h| &h.kind)),
        kind(a.y.homing.as_ref().map(|h| &h.kind)),
        kind(a.z.homing.as_ref().map(|h| &h.kind)),
        kind(
            a.a.as_ref()
                .and_then(|r| r.homing.as_ref())
                .map(|h| &h.kind),
        ),
        kind(
            a.b.as_ref()
                .and_then(|r| r.homing.as_ref())
                .map(|h| &h.kind),
        ),
        kind(
            a.c.as_ref()
                .and_then(|r| r.homing.as_ref())
                .map(|h| &h.kind),
        ),
    ]
}

fn raw_axis_drives(raw: &RawConfig) -> [Option<&RawDrive>; MAX_AXES] {
    [
        raw.axes.x.drive.as_ref(),
        raw.axes.y.drive.as_ref(),
        raw.axes.z.drive.as_ref(),
        raw.axes.a.as_ref().and_then(|a| a.drive.as_ref()),
        raw.axes.b.as_ref().and_then(|a| a.drive.as_ref()),
        raw.axes.c.as_ref().and_then(|a| a.drive.as_ref()),
    ]
}

/// The simulated drive's tuning keys given in `raw`, with their places.
fn sim_tuning_keys(raw: &RawDrive) -> [Option<(&'static str, std::ops::Range<usize>)>; 8] {
    fn f(
        name: &'static str,
        v: &Option<Spanned<f64>>,
    ) -> Option<(&'static str, std::ops::Range<usize>)> {
        v.as_ref().map(|v| (name, v.span()))
    }
    fn i(
        name: &'static str,
        v: &Option<Spanned<i64>>,
    ) -> Option<(&'static str, std::ops::Range<usize>)> {
        v.as_ref().map(|v| (name, v.span()))
    }
    [
        f("bandwidth_hz", &raw.bandwidth_hz),
        f("damping", &raw.damping),
        f("inertia_ratio", &raw.inertia_ratio),
        f("velocity_feed_forward", &raw.velocity_feed_forward),
        i("substeps", &raw.substeps),
        f(
            "overcurrent_accel_counts_s2",
            &raw.overcurrent_accel_counts_s2,
        ),
        f(
            "quick_stop_decel_counts_s2",
            &raw.quick_stop_decel_counts_s2,
        ),
        i(
            "following_error_window_counts",
            &raw.following_error_window_counts,
        ),
    ]
}
