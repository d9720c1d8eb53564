//! The machine's functions besides the axes checked: `[io]` (numbers and names unique,
//! each name a bit of the bus with `[ethercat]`), `[spindle]`, `[coolant]`,
//! `[tool_changer]` (each key of its kind, each name an `[io]` entry of the right type,
//! no output driven by two functions) and `[operator]`.

use std::collections::BTreeMap;
use std::ops::Range;

use toml::Spanned;

use crate::ethercat::EthercatConfig;
use crate::raw::*;
use crate::toml_words::number;
use crate::*;

use super::{Checker, valid_io_name};

/// The four kinds of `[io]` entry.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum IoType {
    DigitalOutput,
    DigitalInput,
    AnalogOutput,
    AnalogInput,
}

impl IoType {
    /// "a digital output", ...
    fn words(self) -> &'static str {
        match self {
            IoType::DigitalOutput => "a digital output",
            IoType::DigitalInput => "a digital input",
            IoType::AnalogOutput => "an analog output",
            IoType::AnalogInput => "an analog input",
        }
    }

    /// The list of `[io]` it is in.
    fn list(self) -> &'static str {
        match self {
            IoType::DigitalOutput => "io.digital_outputs",
            IoType::DigitalInput => "io.digital_inputs",
            IoType::AnalogOutput => "io.analog_outputs",
            IoType::AnalogInput => "io.analog_inputs",
        }
    }
}

/// One raw `[io]` entry of any list: its number and name.
struct Entry<'r> {
    number: &'r Spanned<i64>,
    name: &'r Spanned<String>,
}

/// A spindle or tool changer kind: its name and the value that gives it (`None`: the
/// default).
pub(super) struct Kind<'r> {
    pub(super) name: &'static str,
    pub(super) raw: Option<&'r Spanned<String>>,
}

impl Kind<'_> {
    /// "`spindle.kind` is \"drive\"" (with "by default" when the file does not give it).
    pub(super) fn said(&self, table: &str) -> String {
        match self.raw {
            Some(_) => format!("`{table}.kind` is \"{}\"", self.name),
            None => format!("`{table}.kind` is \"{}\" by default", self.name),
        }
    }
}

impl Checker<'_> {
    /// `[io]`, with `bus` the checked `[ethercat]`.
    pub(crate) fn io(
        &self,
        raw: &RawIo,
        bus: Option<&EthercatConfig>,
    ) -> Result<IoConfig, ConfigError> {
        let mut names: BTreeMap<String, String> = BTreeMap::new();
        let mut io = IoConfig::default();

        let entries: Vec<Entry> = raw
            .digital_outputs
            .iter()
            .map(|o| Entry {
                number: &o.number,
                name: &o.name,
            })
            .collect();
        for (i, o) in entries.iter().enumerate() {
            let key = format!("io.digital_outputs[{i}]");
            let (number, name) =
                self.io_entry(&key, IoType::DigitalOutput, &entries[..i], o, &mut names)?;
            let bus_bit = match bus {
                None => None,
                Some(bus) => Some(self.bus_bit(&key, o.name, bus, true)?),
            };
            io.digital_outputs.push(DigitalOutput {
                number,
                name,
                bus_bit,
            });
        }

        let entries: Vec<Entry> = raw
            .digital_inputs
            .iter()
            .map(|o| Entry {
                number: &o.number,
                name: &o.name,
            })
            .collect();
        for (i, (d, e)) in raw.digital_inputs.iter().zip(&entries).enumerate() {
            let key = format!("io.digital_inputs[{i}]");
            let (number, name) =
                self.io_entry(&key, IoType::DigitalInput, &entries[..i], e, &mut names)?;
            let bus_bit = match bus {
                None => None,
                Some(bus) => {
                    let bit = self.bus_bit(&key, &d.name, bus, false)?;
                    if let Some(sim) = &d.sim {
                        return Err(self.error(
                            sim.span(),
                            format!(
                                "`{key}.sim` sets a simulated input, but with [ethercat] `{name}` is input bit {} of the I/O subdevice at position {}; remove it",
                                bit.bit, bit.position
                            ),
                        ));
                    }
                    Some(bit)
                }
            };
            io.digital_inputs.push(DigitalInput {
                number,
                sim: d.sim.as_ref().is_some_and(|s| *s.get_ref()),
                name,
                bus_bit,
            });
        }

        let entries: Vec<Entry> = raw
            .analog_outputs
            .iter()
            .map(|o| Entry {
                number: &o.number,
                name: &o.name,
            })
            .collect();
        for (i, o) in entries.iter().enumerate() {
            let key = format!("io.analog_outputs[{i}]");
            let (number, name) =
                self.io_entry(&key, IoType::AnalogOutput, &entries[..i], o, &mut names)?;
            self.no_analog_on_the_bus(&key, o.name, bus)?;
            io.analog_outputs.push(AnalogOutput { number, name });
        }

        let entries: Vec<Entry> = raw
            .analog_inputs
            .iter()
            .map(|o| Entry {
                number: &o.number,
                name: &o.name,
            })
            .collect();
        for (i, (a, e)) in raw.analog_inputs.iter().zip(&entries).enumerate() {
            let key = format!("io.analog_inputs[{i}]");
            let (number, name) =
                self.io_entry(&key, IoType::AnalogInput, &entries[..i], e, &mut names)?;
            self.no_analog_on_the_bus(&key, &a.name, bus)?;
            let sim = match &a.sim {
                None => 0.0,
                Some(s) => self.within(
                    &format!("{key}.sim"),
                    "(the input's units)",
                    ANALOG_VALUE_RANGE,
                    s,
                )?,
            };
            io.analog_inputs.push(AnalogInput { number, name, sim });
        }

        io.digital_outputs.sort_by_key(|e| e.number);
        io.digital_inputs.sort_by_key(|e| e.number);
        io.analog_outputs.sort_by_key(|e| e.number);
        io.analog_inputs.sort_by_key(|e| e.number);
        Ok(io)
    }

    /// The `[io]` entry `entry` at `key`: its number within the range of its type and
    /// unlike those `before` it in its list, its name valid and unlike every name in
    /// `names` (the names seen in `[io]`, with where; it is added).
    fn io_entry(
        &self,
        key: &str,
        kind: IoType,
        before: &[Entry],
        entry: &Entry,
        names: &mut BTreeMap<String, String>,
    ) -> Result<(u8, String), ConfigError> {
        let (range, what) = match kind {
            IoType::DigitalOutput => (DIGITAL_IO_NUMBER_RANGE, "a digital output number"),
            IoType::DigitalInput => (DIGITAL_IO_NUMBER_RANGE, "a digital input number"),
            IoType::AnalogOutput => (ANALOG_IO_NUMBER_RANGE, "an analog output number"),
            IoType::AnalogInput => (ANALOG_IO_NUMBER_RANGE, "an analog input number"),
        };
        let number = self.integer(&format!("{key}.number"), what, range, entry.number)?;
        if let Some(j) = before
            .iter()
            .position(|e| *e.number.get_ref() == i64::from(number))
        {
            return Err(self.error(
                entry.number.span(),
                format!(
                    "`{key}.number` = {number} is also the number of `{}[{j}]`; each of {} has its own",
                    kind.list(),
                    kind.list()
                ),
            ));
        }
        let name = entry.name.get_ref();
        if !valid_io_name(name) {
            return Err(self.error(
                entry.name.span(),
                format!(
                    "`{key}.name` must be 1 to 64 ASCII letters, digits, `_` or `-`, starting with a letter, found `{name}`"
                ),
            ));
        }
        if let Some(first) = names.get(name) {
            return Err(self.error(
                entry.name.span(),
                format!("the name `{name}` is used twice in [io]: `{first}` and `{key}`"),
            ));
        }
        names.insert(name.clone(), key.to_string());
        // Within DIGITAL_IO_NUMBER_RANGE or ANALOG_IO_NUMBER_RANGE: at most 63.
        Ok((number as u8, name.clone()))
    }

    /// With `[ethercat]`, the bit of the bus named `name`: an output bit for an output
    /// (`output`), else an input bit.
    fn bus_bit(
        &self,
        key: &str,
        name: &Spanned<String>,
        bus: &EthercatConfig,
        output: bool,
    ) -> Result<BusBit, ConfigError> {
        let find = |outputs: bool| {
            bus.io.iter().find_map(|io| {
                let bits = if outputs { &io.outputs } else { &io.inputs };
                bits.iter()
                    .find(|b| b.name == *name.get_ref())
                    .map(|b| BusBit {
                        position: io.position,
                        bit: b.bit,
                    })
            })
        };
        if let Some(bit) = find(output) {
            return Ok(bit);
        }
        let (direction, other) = if output {
            ("output", "input")
        } else {
            ("input", "output")
        };
        let why = match find(!output) {
            Some(b) => format!(
                " (it is an {other} bit of the subdevice at position {})",
                b.position
            ),
            None => String::new(),
        };
        Err(self.error(
            name.span(),
            format!(
                "`{key}.name` is `{}`, which is not an {direction} bit of any [[ethercat.io]]{why}: with [ethercat], every digital {direction} of [io] is a bit named in an I/O subdevice's `{direction}s`",
                name.get_ref()
            ),
        ))
    }

    /// Analog I/O is simulated only: refused with `[ethercat]`.
    fn no_analog_on_the_bus(
        &self,
        key: &str,
        name: &Spanned<String>,
        bus: Option<&EthercatConfig>,
    ) -> Result<(), ConfigError> {
        match bus {
            None => Ok(()),
            Some(_) => Err(self.error(
                name.span(),
                format!(
                    "`{key}` (`{}`): analog inputs and outputs on EtherCAT are not supported yet; with [ethercat], [io] has digital inputs and outputs only",
                    name.get_ref()
                ),
            )),
        }
    }

    /// The `[io]` entry of type `kind` that `key` names.
    pub(super) fn io_ref(
        &self,
        key: &str,
        raw: &Spanned<String>,
        io: &IoConfig,
        kind: IoType,
    ) -> Result<IoRef, ConfigError> {
        let name = raw.get_ref();
        let found = [
            (
                IoType::DigitalOutput,
                io.digital_output(name).map(|e| e.number),
            ),
            (
                IoType::DigitalInput,
                io.digital_input(name).map(|e| e.number),
            ),
            (
                IoType::AnalogOutput,
                io.analog_output(name).map(|e| e.number),
            ),
            (IoType::AnalogInput, io.analog_input(name).map(|e| e.number)),
        ];
        match found.iter().find(|(_, n)| n.is_some()) {
            Some(&(t, Some(number))) if t == kind => Ok(IoRef {
                name: name.clone(),
                number,
            }),
            Some(&(t, _)) => Err(self.error(
                raw.span(),
                format!(
                    "`{key}` names `{name}`, which is {} (`{}`); it must be {} (`{}`)",
                    t.words(),
                    t.list(),
                    kind.words(),
                    kind.list()
                ),
            )),
            None => Err(self.error(
                raw.span(),
                format!(
                    "`{key}` names `{name}`, which is not in [io]; it must be {} (`{}`)",
                    kind.words(),
                    kind.list()
                ),
            )),
        }
    }

    /// A kind from `allowed`, or `default`.
    pub(super) fn kind<'r>(
        &self,
        key: &str,
        raw: Option<&'r Spanned<String>>,
        allowed: &[&'static str],
        default: &'static str,
    ) -> Result<Kind<'r>, ConfigError> {
        let Some(k) = raw else {
            return Ok(Kind {
                name: default,
                raw: None,
            });
        };
        match allowed.iter().find(|a| **a == k.get_ref()) {
            Some(name) => Ok(Kind { name, raw: Some(k) }),
            None => {
                let quoted: Vec<String> = allowed.iter().map(|a| format!("\"{a}\"")).collect();
                let words = match quoted.split_last() {
                    Some((last, [])) => last.clone(),
                    Some((last, rest)) => format!("{} or {last}", rest.join(", ")),
                    None => String::new(),
                };
                Err(self.error(
                    k.span(),
                    format!("`{key}` must be {words}, found `{}`", k.get_ref()),
                ))
            }
        }
    }

    /// The keys of kind `owner` given (`given`: name and place) are refused unless the
    /// kind is `owner`.
    pub(super) fn keys_of_kind(
        &self,
        table: &str,
        kind: &Kind,
        owner: &str,
        given: &[(&str, Option<Range<usize>>)],
    ) -> Result<(), ConfigError> {
        if kind.name == owner {
            return Ok(());
        }
        match given.iter().find_map(|(k, s)| s.clone().map(|s| (k, s))) {
            None => Ok(()),
            Some((k, span)) => Err(self.error(
                span,
                format!(
                    "`{table}.{k}` is a key of kind \"{owner}\", but {}; remove it",
                    kind.said(table)
                ),
            )),
        }
    }

    /// A key the kind needs: present, else an error at the kind (or the table).
    pub(super) fn required<'r>(
        &self,
        table: &str,
        kind: &Kind,
        table_span: Option<Range<usize>>,
        key: &str,
        what: &str,
        value: &'r Option<Spanned<String>>,
    ) -> Result<&'r Spanned<String>, ConfigError> {
        value
            .as_ref()
            .ok_or_else(|| self.missing(table, kind, table_span, key, what))
    }

    /// The error of a key the kind needs that the file does not give, at the kind (or the
    /// table).
    pub(super) fn missing(
        &self,
        table: &str,
        kind: &Kind,
        table_span: Option<Range<usize>>,
        key: &str,
        what: &str,
    ) -> ConfigError {
        let message = format!("{} needs `{table}.{key}`, {what}", kind.said(table));
        match kind.raw.map(|k| k.span()).or(table_span) {
            Some(span) => self.error(span, message),
            None => ConfigError::Invalid {
                origin: self.origin.to_string(),
                position: None,
                message,
            },
        }
    }

    /// `[spindle]`, with the checked `[io]` and `[ethercat]`.
    pub(crate) fn spindle(
        &self,
        raw: Option<&Spanned<RawSpindle>>,
        io: &IoConfig,
        bus: Option<&EthercatConfig>,
    ) -> Result<SpindleConfig, ConfigError> {
        let empty = RawSpindle::default();
        let (r, table_span) = match raw {
            Some(t) => (t.get_ref(), Some(t.span())),
            None => (&empty, None),
        };
        let spindle_drive = bus.and_then(|b| b.spindle_drive());
        // With [ethercat] the spindle is not simulated: a drive only when the bus has one.
        let default_kind = if bus.is_some() && spindle_drive.is_none() {
            "none"
        } else {
            "drive"
        };
        let kind = self.kind(
            "spindle.kind",
            r.kind.as_ref(),
            &["drive", "outputs", "none"],
            default_kind,
        )?;
        if let (Some(d), Some(k)) = (spindle_drive, kind.raw)
            && kind.name != "drive"
        {
            return Err(self.error(
                k.span(),
                format!(
                    "`spindle.kind` is \"{}\" but the EtherCAT drive at position {} is the spindle's (`axis = \"s\"`): a spindle on the bus is a \"drive\"",
                    kind.name, d.position
                ),
            ));
        }
        if let (Some(_), None, Some(k)) = (bus, spindle_drive, kind.raw)
            && kind.name == "drive"
        {
            return Err(self.error(
                k.span(),
                "`spindle.kind` is \"drive\" but [ethercat] lists no spindle drive, and with [ethercat] the spindle is not simulated: add a [[ethercat.drives]] with `axis = \"s\"` (mode \"csv\"), or make the kind \"outputs\" or \"none\"".to_string(),
            ));
        }
        let span = |v: &Option<Spanned<String>>| v.as_ref().map(|v| v.span());
        let fspan = |v: &Option<Spanned<f64>>| v.as_ref().map(|v| v.span());
        self.keys_of_kind(
            "spindle",
            &kind,
            "outputs",
            &[
                ("enable_output", span(&r.enable_output)),
                ("reverse_output", span(&r.reverse_output)),
                ("speed_output", span(&r.speed_output)),
                ("speed_output_scale", fspan(&r.speed_output_scale)),
                ("at_speed_input", span(&r.at_speed_input)),
                ("spin_up_s", fspan(&r.spin_up_s)),
            ],
        )?;
        self.keys_of_kind(
            "spindle",
            &kind,
            "drive",
            &[("counts_per_rev", fspan(&r.counts_per_rev))],
        )?;

        let max_rpm = self.within_or(
            "spindle.max_rpm",
            "rpm",
            SPINDLE_RPM_RANGE,
            &r.max_rpm,
            DEFAULT_SPINDLE_MAX_RPM,
        )?;
        let min_rpm = self.within_or(
            "spindle.min_rpm",
            "rpm",
            0.0..=*SPINDLE_RPM_RANGE.end(),
            &r.min_rpm,
            DEFAULT_SPINDLE_MIN_RPM,
        )?;
        if let Some(m) = &r.min_rpm
            && min_rpm >= max_rpm
        {
            return Err(self.error(
                m.span(),
                format!(
                    "`spindle.min_rpm` ({}) must be below `spindle.max_rpm` ({})",
                    number(min_rpm),
                    number(max_rpm)
                ),
            ));
        }
        let acceleration_rpm_s = self.within_or(
            "spindle.acceleration_rpm_s",
            "rpm/s",
            SPINDLE_ACCELERATION_RANGE_RPM_S,
            &r.acceleration_rpm_s,
            DEFAULT_SPINDLE_ACCELERATION_RPM_S,
        )?;
        let at_speed_tolerance = self.within_or(
            "spindle.at_speed_tolerance",
            "(fraction of the commanded speed)",
            AT_SPEED_TOLERANCE_RANGE,
            &r.at_speed_tolerance,
            DEFAULT_AT_SPEED_TOLERANCE,
        )?;
        let at_speed_timeout_s = self.within_or(
            "spindle.at_speed_timeout_s",
            "s",
            MACHINE_TIMEOUT_RANGE_S,
            &r.at_speed_timeout_s,
            DEFAULT_AT_SPEED_TIMEOUT_S,
        )?;
        let orient_timeout_s = self.within_or(
            "spindle.orient_timeout_s",
            "s",
            MACHINE_TIMEOUT_RANGE_S,
            &r.orient_timeout_s,
            DEFAULT_ORIENT_TIMEOUT_S,
        )?;
        let ramp_s = max_rpm / acceleration_rpm_s;
        if at_speed_timeout_s <= ramp_s {
            let place = fspan(&r.at_speed_timeout_s)
                .or(fspan(&r.max_rpm))
                .or(fspan(&r.acceleration_rpm_s))
                .or(table_span.clone())
                .unwrap_or(0..0);
            return Err(self.error(
                place,
                format!(
                    "`spindle.at_speed_timeout_s` ({} s) must exceed the time the spindle takes from 0 to `max_rpm` ({} rpm) at `acceleration_rpm_s` ({} rpm/s), {} s: every start to full speed would fault",
                    number(at_speed_timeout_s),
                    number(max_rpm),
                    number(acceleration_rpm_s),
                    number(ramp_s)
                ),
            ));
        }

        let kind = match kind.name {
            "none" => SpindleKind::None,
            "drive" => SpindleKind::Drive(SpindleDrive {
                counts_per_rev: self.within_or(
                    "spindle.counts_per_rev",
                    "counts",
                    SPINDLE_COUNTS_PER_REV_RANGE,
                    &r.counts_per_rev,
                    DEFAULT_SPINDLE_COUNTS_PER_REV,
                )?,
                on_bus: spindle_drive.is_some(),
            }),
            _ => SpindleKind::Outputs(self.spindle_outputs(
                r,
                &kind,
                table_span,
                io,
                at_speed_timeout_s,
            )?),
        };
        Ok(SpindleConfig {
            kind,
            max_rpm,
            min_rpm,
            acceleration_rpm_s,
            at_speed_tolerance,
            at_speed_timeout_s,
            fault_out_of_band: r.fault_out_of_band.unwrap_or(true),
            orient_timeout_s,
            off_at_end: r.off_at_end.unwrap_or(true),
            off_at_abort: r.off_at_abort.unwrap_or(true),
            off_at_fault: r.off_at_fault.unwrap_or(true),
        })
    }

    /// The keys of an `"outputs"` spindle.
    fn spindle_outputs(
        &self,
        r: &RawSpindle,
        kind: &Kind,
        table_span: Option<Range<usize>>,
        io: &IoConfig,
        at_speed_timeout_s: f64,
    ) -> Result<SpindleOutputs, ConfigError> {
        let t = "spindle";
        let enable = self.required(
            t,
            kind,
            table_span.clone(),
            "enable_output",
            "the digital output that switches the spindle on",
            &r.enable_output,
        )?;
        let speed = self.required(
            t,
            kind,
            table_span.clone(),
            "speed_output",
            "the analog output that sets its speed",
            &r.speed_output,
        )?;
        let Some(scale) = &r.speed_output_scale else {
            return Err(self.missing(
                t,
                kind,
                table_span,
                "speed_output_scale",
                "the analog output's units per rpm (10 V at 24000 rpm: 0.0004167)",
            ));
        };
        let spin_up_s = self.within_or(
            "spindle.spin_up_s",
            "s",
            SPIN_UP_RANGE_S,
            &r.spin_up_s,
            DEFAULT_SPIN_UP_S,
        )?;
        let at_speed_input = match &r.at_speed_input {
            None => None,
            Some(i) => Some(self.io_ref("spindle.at_speed_input", i, io, IoType::DigitalInput)?),
        };
        if at_speed_input.is_none() && at_speed_timeout_s <= spin_up_s {
            let place = r
                .at_speed_timeout_s
                .as_ref()
                .or(r.spin_up_s.as_ref())
                .map(|v| v.span())
                .or(table_span)
                .unwrap_or(0..0);
            return Err(self.error(
                place,
                format!(
                    "`spindle.at_speed_timeout_s` ({} s) must exceed `spindle.spin_up_s` ({} s): without `at_speed_input` the spindle counts as at speed only after `spin_up_s`, so every start would fault",
                    number(at_speed_timeout_s),
                    number(spin_up_s)
                ),
            ));
        }
        Ok(SpindleOutputs {
            enable_output: self.io_ref(
                "spindle.enable_output",
                enable,
                io,
                IoType::DigitalOutput,
            )?,
            reverse_output: match &r.reverse_output {
                None => None,
                Some(o) => {
                    Some(self.io_ref("spindle.reverse_output", o, io, IoType::DigitalOutput)?)
                }
            },
            speed_output: self.io_ref("spindle.speed_output", speed, io, IoType::AnalogOutput)?,
            speed_output_scale: self.within(
                "spindle.speed_output_scale",
                "(output units per rpm)",
                SPEED_OUTPUT_SCALE_RANGE,
                scale,
            )?,
            at_speed_input,
            spin_up_s,
        })
    }

    /// `[coolant]`, with the checked `[io]`.
    pub(crate) fn coolant(
        &self,
        raw: &RawCoolant,
        io: &IoConfig,
    ) -> Result<CoolantConfig, ConfigError> {
        let output = |key: &str, v: &Option<Spanned<String>>| match v {
            None => Ok(None),
            Some(v) => self.io_ref(key, v, io, IoType::DigitalOutput).map(Some),
        };
        Ok(CoolantConfig {
            mist: output("coolant.mist", &raw.mist)?,
            flood: output("coolant.flood", &raw.flood)?,
            off_at_end: raw.off_at_end.unwrap_or(true),
            off_at_abort: raw.off_at_abort.unwrap_or(true),
            off_at_fault: raw.off_at_fault.unwrap_or(true),
        })
    }

    /// `[tool_changer]`, with the checked `[io]`.
    pub(crate) fn tool_changer(
        &self,
        raw: Option<&Spanned<RawToolChanger>>,
        io: &IoConfig,
    ) -> Result<ToolChanger, ConfigError> {
        let Some(table) = raw else {
            return Ok(ToolChanger::Manual);
        };
        let r = table.get_ref();
        let t = "tool_changer";
        let kind = self.kind(
            "tool_changer.kind",
            r.kind.as_ref(),
            &["manual", "automatic", "none"],
            "manual",
        )?;
        let span = |v: &Option<Spanned<String>>| v.as_ref().map(|v| v.span());
        self.keys_of_kind(
            t,
            &kind,
            "automatic",
            &[
                ("number_output", span(&r.number_output)),
                ("change_output", span(&r.change_output)),
                ("changed_input", span(&r.changed_input)),
                ("timeout_s", r.timeout_s.as_ref().map(|v| v.span())),
            ],
        )?;
        Ok(match kind.name {
            "manual" => ToolChanger::Manual,
            "none" => ToolChanger::None,
            _ => {
                let at = Some(table.span());
                let number = self.required(
                    t,
                    &kind,
                    at.clone(),
                    "number_output",
                    "the analog output carrying the tool number",
                    &r.number_output,
                )?;
                let change = self.required(
                    t,
                    &kind,
                    at.clone(),
                    "change_output",
                    "the digital output requesting the change",
                    &r.change_output,
                )?;
                let changed = self.required(
                    t,
                    &kind,
                    at,
                    "changed_input",
                    "the digital input that says the change is done",
                    &r.changed_input,
                )?;
                ToolChanger::Automatic(AutomaticToolChanger {
                    number_output: self.io_ref(
                        "tool_changer.number_output",
                        number,
                        io,
                        IoType::AnalogOutput,
                    )?,
                    change_output: self.io_ref(
                        "tool_changer.change_output",
                        change,
                        io,
                        IoType::DigitalOutput,
                    )?,
                    changed_input: self.io_ref(
                        "tool_changer.changed_input",
                        changed,
                        io,
                        IoType::DigitalInput,
                    )?,
                    timeout_s: self.within_or(
                        "tool_changer.timeout_s",
                        "s",
                        MACHINE_TIMEOUT_RANGE_S,
                        &r.timeout_s,
                        DEFAULT_TOOL_CHANGE_TIMEOUT_S,
                    )?,
                })
            }
        })
    }

    /// No output is driven by two machine functions (the spindle's, coolant's and tool
    /// changer's output keys of `raw`, all of which the kinds accepted).
    pub(crate) fn outputs_used_once(&self, raw: &RawConfig) -> Result<(), ConfigError> {
        let spindle = raw.spindle.as_ref().map(|s| s.get_ref());
        let changer = raw.tool_changer.as_ref().map(|s| s.get_ref());
        let used: [(&str, Option<&Spanned<String>>); 7] = [
            (
                "spindle.enable_output",
                spindle.and_then(|s| s.enable_output.as_ref()),
            ),
            (
                "spindle.reverse_output",
                spindle.and_then(|s| s.reverse_output.as_ref()),
            ),
            (
                "spindle.speed_output",
                spindle.and_then(|s| s.speed_output.as_ref()),
            ),
            ("coolant.mist", raw.coolant.mist.as_ref()),
            ("coolant.flood", raw.coolant.flood.as_ref()),
            (
                "tool_changer.number_output",
                changer.and_then(|c| c.number_output.as_ref()),
            ),
            (
                "tool_changer.change_output",
                changer.and_then(|c| c.change_output.as_ref()),
            ),
        ];
        for (i, (key, v)) in used.iter().enumerate() {
            let Some(v) = v else { continue };
            if let Some((first, _)) = used[..i]
                .iter()
                .find(|(_, w)| w.is_some_and(|w| w.get_ref() == v.get_ref()))
            {
                return Err(self.error(
                    v.span(),
                    format!(
                        "`{first}` and `{key}` both name the output `{}`; each machine function has its own output",
                        v.get_ref()
                    ),
                ));
            }
        }
        Ok(())
    }

    /// `[operator]`.
    pub(crate) fn operator(&self, raw: &RawOperator) -> OperatorConfig {
        OperatorConfig {
            optional_stop: raw.optional_stop.unwrap_or(DEFAULT_OPTIONAL_STOP),
            single_block: raw.single_block.unwrap_or(DEFAULT_SINGLE_BLOCK),
        }
    }
}
