//! Homing, jogging and the axes' switches checked: `[homing]`, `[jog]`, and per axis
//! `[axes.*.homing]` (the keys of its kind, speeds within the axis's velocity, the home
//! position within its travel; for kind "drive" the method the drive supports and every
//! object within its type in counts), `[axes.*.limit_switches]` (each a digital input of
//! `[io]`), `[axes.*.sim]` (only beside simulated drives; each switch it drives a
//! simulated input whose value the simulation sets); no input serves two functions.

use kerf_drive::MAX_AXES;
use kerf_drive::cia402::Scale;
use kerf_drive::sim::{SUPPORTED_METHODS, is_supported_method};
use toml::Spanned;

use crate::ethercat::EthercatConfig;
use crate::raw::*;
use crate::toml_words::number;
use crate::*;

use super::Checker;
use super::machine::{IoType, Kind};

/// What the checks of one axis's switch tables need to know of the axis.
struct AxisFacts<'r> {
    /// X 0 to C 5.
    index: usize,
    /// `x`, ..., `c`.
    name: &'static str,
    /// `mm` or `deg`: the unit of its lengths, in key names and messages.
    unit: &'static str,
    /// Its travel, `min_*` and `max_*`.
    travel: (f64, f64),
    /// `velocity_*`.
    velocity: f64,
    /// `acceleration_*`.
    acceleration: f64,
    /// Its drive's scale.
    scale: Option<Scale>,
    /// Its tables as the file gives them.
    tables: AxisSwitchTables<'r>,
}

impl AxisFacts<'_> {
    /// `BASE_UNIT` (`home_mm`, `home_deg`); `speed`: `_s` appended (`final_speed_mm_s`).
    fn last(&self, base: &str, speed: bool) -> String {
        format!("{base}_{}{}", self.unit, if speed { "_s" } else { "" })
    }

    /// `axes.NAME.TABLE.BASE_UNIT` (`axes.x.homing.home_mm`); `speed` as for
    /// [`AxisFacts::last`].
    fn key(&self, table: &str, base: &str, speed: bool) -> String {
        format!("axes.{}.{table}.{}", self.name, self.last(base, speed))
    }

    /// The unit of a speed, in messages (`mm/s`).
    fn speed_unit(&self) -> String {
        format!("{}/s", self.unit)
    }

    /// `velocity_mm_s` or `velocity_deg_s`.
    fn velocity_key(&self) -> String {
        format!("velocity_{}_s", self.unit)
    }

    /// `acceleration_mm_s2` or `acceleration_deg_s2`.
    fn acceleration_key(&self) -> String {
        format!("acceleration_{}_s2", self.unit)
    }
}

/// The axes the file has, X to C, with their drives' scales.
fn axis_facts<'r>(raw: &'r RawConfig, axes: &Axes, drive: &DriveSide) -> Vec<AxisFacts<'r>> {
    let mut out = Vec::with_capacity(MAX_AXES);
    let linear = [
        ("x", &raw.axes.x, axes.x),
        ("y", &raw.axes.y, axes.y),
        ("z", &raw.axes.z, axes.z),
    ];
    for (index, (name, r, a)) in linear.into_iter().enumerate() {
        out.push(AxisFacts {
            index,
            name,
            unit: "mm",
            travel: (a.min_mm, a.max_mm),
            velocity: a.velocity_mm_s,
            acceleration: a.acceleration_mm_s2,
            scale: drive.axes[index].map(|d| d.scale),
            tables: r.switch_tables(),
        });
    }
    let rotary = [
        ("a", &raw.axes.a, axes.a),
        ("b", &raw.axes.b, axes.b),
        ("c", &raw.axes.c, axes.c),
    ];
    for (i, (name, r, a)) in rotary.into_iter().enumerate() {
        if let (Some(r), Some(a)) = (r, a) {
            out.push(AxisFacts {
                index: 3 + i,
                name,
                unit: "deg",
                travel: (a.min_deg, a.max_deg),
                velocity: a.velocity_deg_s,
                acceleration: a.acceleration_deg_s2,
                scale: drive.axes[3 + i].map(|d| d.scale),
                tables: r.switch_tables(),
            });
        }
    }
    out
}

impl Checker<'_> {
    /// `[homing]`.
    pub(crate) fn homing(&self, raw: &RawHoming) -> Result<HomingConfig, ConfigError> {
        Ok(HomingConfig {
            required: raw.required.unwrap_or(DEFAULT_HOMING_REQUIRED),
            unhomed_jog_pct: self.within_or(
                "homing.unhomed_jog_pct",
                "% (of the axis's velocity)",
                UNHOMED_JOG_PCT_RANGE,
                &raw.unhomed_jog_pct,
                DEFAULT_UNHOMED_JOG_PCT,
            )?,
        })
    }

    /// `[jog]`.
    pub(crate) fn jog(&self, raw: &RawJog) -> Result<JogConfig, ConfigError> {
        Ok(JogConfig {
            deadman_ms: self.integer_or(
                "jog.deadman_ms",
                "a time in ms",
                DEADMAN_RANGE_MS,
                &raw.deadman_ms,
                DEFAULT_DEADMAN_MS,
            )?,
            default_speed_pct: self.within_or(
                "jog.default_speed_pct",
                "% (of the axis's velocity)",
                JOG_SPEED_PCT_RANGE,
                &raw.default_speed_pct,
                DEFAULT_JOG_SPEED_PCT,
            )?,
        })
    }

    /// Every axis's `[axes.*.homing]`, `[axes.*.limit_switches]` and `[axes.*.sim]`, with
    /// the checked axes, `[io]` and `[ethercat]`; then no input serving two functions.
    pub(crate) fn axis_setups(
        &self,
        raw: &RawConfig,
        axes: &Axes,
        drive: &DriveSide,
        io: &IoConfig,
        bus: Option<&EthercatConfig>,
    ) -> Result<[Option<AxisSetup>; MAX_AXES], ConfigError> {
        let facts = axis_facts(raw, axes, drive);
        let mut setups = [None; MAX_AXES];
        for a in &facts {
            setups[a.index] = Some(AxisSetup {
                homing: self.axis_homing(a, io, bus)?,
                limit_switches: self.limit_switches(a, io)?,
                sim: SimAxis::default(),
            });
        }
        self.inputs_used_once(raw, &facts)?;
        for a in &facts {
            if let Some(setup) = &mut setups[a.index] {
                setup.sim = self.sim_axis(a, &setup.homing, &raw.io, bus)?;
            }
        }
        Ok(setups)
    }

    /// `[axes.*.homing]` of axis `a`: the keys of its kind.
    fn axis_homing(
        &self,
        a: &AxisFacts,
        io: &IoConfig,
        bus: Option<&EthercatConfig>,
    ) -> Result<AxisHoming, ConfigError> {
        let Some(h) = &a.tables.homing else {
            return Ok(AxisHoming::default());
        };
        let table = format!("axes.{}.homing", a.name);
        let kind = self.kind(
            &format!("{table}.kind"),
            Some(h.kind),
            &["none", "switch", "absolute", "drive"],
            "none",
        )?;
        let span = |v: Option<&Spanned<f64>>| v.map(|v| v.span());
        const SWITCH: &str = "kind \"switch\"";
        const DRIVE: &str = "kind \"drive\"";
        const MOVING: &str = "kinds \"switch\" and \"drive\"";
        // Each key of a kind that moves the axis, with the kinds that take it, in the
        // order of the reference.
        let keys = [
            ("switch".to_string(), h.switch.map(|v| v.span()), SWITCH),
            ("method".to_string(), h.method.map(|v| v.span()), DRIVE),
            (
                a.last("search_velocity", true),
                span(h.search_velocity),
                MOVING,
            ),
            (
                a.last("latch_velocity", true),
                span(h.latch_velocity),
                MOVING,
            ),
            (
                format!("acceleration_{}_s2", a.unit),
                span(h.acceleration),
                DRIVE,
            ),
            (
                a.last("search_distance", false),
                span(h.search_distance),
                MOVING,
            ),
            (a.last("home", false), span(h.home), MOVING),
            (a.last("final_speed", true), span(h.final_speed), MOVING),
            ("sequence".to_string(), h.sequence.map(|v| v.span()), MOVING),
        ];
        for (key, place, owners) in &keys {
            let taken = match kind.name {
                "switch" => *owners != DRIVE,
                "drive" => *owners != SWITCH,
                _ => false,
            };
            if let (false, Some(place)) = (taken, place) {
                return Err(self.error(
                    place.clone(),
                    format!(
                        "`{table}.{key}` is a key of {owners}, but {}; remove it",
                        kind.said(&table)
                    ),
                ));
            }
        }
        if let ("none", Some(offset)) = (kind.name, h.home_offset) {
            return Err(self.error(
                offset.span(),
                format!(
                    "`{}` is a key of kinds \"switch\", \"absolute\" and \"drive\", but {}; remove it",
                    a.key("homing", "home_offset", false),
                    kind.said(&table)
                ),
            ));
        }
        let home_offset_units = match h.home_offset {
            None => DEFAULT_HOME_OFFSET_MM,
            Some(v) => self.coordinate(&a.key("homing", "home_offset", false), a.unit, v)?,
        };
        Ok(match kind.name {
            "absolute" => AxisHoming {
                kind: HomingKind::Absolute,
                home_offset_units,
                ..AxisHoming::default()
            },
            "switch" => AxisHoming {
                home_offset_units,
                ..self.switch_homing(a, h, &table, &kind, io)?
            },
            "drive" => self.drive_homing(a, h, &table, &kind, bus, home_offset_units)?,
            _ => AxisHoming::default(),
        })
    }

    /// The keys of a `"switch"` homing of axis `a` (all but `home_offset`).
    fn switch_homing(
        &self,
        a: &AxisFacts,
        h: &AxisHomingKeys,
        table: &str,
        kind: &Kind,
        io: &IoConfig,
    ) -> Result<AxisHoming, ConfigError> {
        let Some(switch) = h.switch else {
            return Err(self.missing(
                table,
                kind,
                None,
                "switch",
                "the digital input of [io] the home switch is wired to",
            ));
        };
        let switch_input =
            self.io_ref(&format!("{table}.switch"), switch, io, IoType::DigitalInput)?;
        let search_key = a.key("homing", "search_velocity", true);
        let Some(search) = h.search_velocity else {
            return Err(self.missing(
                table,
                kind,
                None,
                &a.last("search_velocity", true),
                "the speed of the search for the switch, signed: its sign is the direction",
            ));
        };
        let search_velocity = *search.get_ref();
        if !(search_velocity != 0.0 && search_velocity.abs() <= a.velocity) {
            return Err(self.error(
                search.span(),
                format!(
                    "`{search_key}` must be non-zero and at most the axis's `{}`, {} {}, in magnitude (its sign is the direction of the search), found {}",
                    a.velocity_key(),
                    number(a.velocity),
                    a.speed_unit(),
                    number(search_velocity)
                ),
            ));
        }
        let latch_key = a.key("homing", "latch_velocity", true);
        let Some(latch) = h.latch_velocity else {
            return Err(self.missing(
                table,
                kind,
                None,
                &a.last("latch_velocity", true),
                "the speed of the move that latches the switch's edge, signed: the search's sign approaches the edge again after a back-off, the opposite sign leaves the switch",
            ));
        };
        let latch_velocity = *latch.get_ref();
        if !(latch_velocity != 0.0 && latch_velocity.abs() <= search_velocity.abs()) {
            return Err(self.error(
                latch.span(),
                format!(
                    "`{latch_key}` must be non-zero and at most the search's speed, {} {} (`{search_key}`), in magnitude, found {}",
                    number(search_velocity.abs()),
                    a.speed_unit(),
                    number(latch_velocity)
                ),
            ));
        }
        let (min, max) = a.travel;
        let search_distance_units = match h.search_distance {
            None => DEFAULT_SEARCH_DISTANCE_TRAVELS * (max - min),
            Some(d) => self.above_zero(
                &a.key("homing", "search_distance", false),
                a.unit,
                MAX_SEARCH_DISTANCE_MM,
                "",
                d,
            )?,
        };
        let home_units = self.home_position(a, h)?;
        let final_speed_units_s = match h.final_speed {
            None => search_velocity.abs(),
            Some(v) => self.above_zero(
                &a.key("homing", "final_speed", true),
                &a.speed_unit(),
                a.velocity,
                &format!(" (the axis's `{}`)", a.velocity_key()),
                v,
            )?,
        };
        let sequence = self.sequence(table, h)?;
        Ok(AxisHoming {
            kind: HomingKind::Switch,
            switch_input: Some(u32::from(switch_input.number)),
            drive_method: 0,
            search_velocity_units_s: search_velocity,
            latch_velocity_units_s: latch_velocity,
            acceleration_units_s2: 0.0,
            search_distance_units,
            home_offset_units: DEFAULT_HOME_OFFSET_MM,
            home_units,
            final_speed_units_s,
            sequence,
        })
    }

    /// The keys of a `"drive"` homing of axis `a`, whose `home_offset` is
    /// `home_offset_units`: the method (one the simulated drive supports, or any of CiA
    /// 402's on EtherCAT), the speeds and the acceleration as magnitudes within the axis's
    /// limits, each within its object's type in counts; the keys shared with kind
    /// "switch" as there.
    fn drive_homing(
        &self,
        a: &AxisFacts,
        h: &AxisHomingKeys,
        table: &str,
        kind: &Kind,
        bus: Option<&EthercatConfig>,
        home_offset_units: f64,
    ) -> Result<AxisHoming, ConfigError> {
        let Some(method) = h.method else {
            return Err(self.missing(
                table,
                kind,
                None,
                "method",
                "the CiA 402 homing method (0x6098) the drive homes with",
            ));
        };
        let method_key = format!("{table}.method");
        let found = *method.get_ref();
        let drive_method = match (bus, i8::try_from(found)) {
            (Some(_), Ok(m)) if DRIVE_HOMING_METHOD_RANGE.contains(&m) => m,
            (None, Ok(m)) if is_supported_method(m) => m,
            (Some(_), _) => {
                return Err(self.error(
                    method.span(),
                    format!(
                        "`{method_key}` must be a CiA 402 homing method from {} to {}, found {found}",
                        DRIVE_HOMING_METHOD_RANGE.start(),
                        DRIVE_HOMING_METHOD_RANGE.end()
                    ),
                ));
            }
            (None, _) => {
                let list: Vec<String> = SUPPORTED_METHODS.iter().map(|m| m.to_string()).collect();
                return Err(self.error(
                    method.span(),
                    format!(
                        "`{method_key}` must be a homing method the simulated drive supports ({}), found {found}",
                        list.join(", ")
                    ),
                ));
            }
        };
        let moves = drive_method_moves(drive_method);
        let search_key = a.key("homing", "search_velocity", true);
        let speed_words = format!(
            " (the axis's `{}`; kind \"drive\" takes a speed: the method gives the direction)",
            a.velocity_key()
        );
        let search_velocity = match h.search_velocity {
            None if moves => {
                return Err(self.missing(
                    table,
                    kind,
                    None,
                    &a.last("search_velocity", true),
                    &format!(
                        "the drive's speed during the search for the switch (0x6099:01), which method {drive_method} needs"
                    ),
                ));
            }
            None => 0.0,
            Some(v) => {
                self.above_zero(&search_key, &a.speed_unit(), a.velocity, &speed_words, v)?
            }
        };
        let latch_velocity = match h.latch_velocity {
            None if moves => {
                return Err(self.missing(
                    table,
                    kind,
                    None,
                    &a.last("latch_velocity", true),
                    &format!(
                        "the drive's speed during the search for zero (0x6099:02), which method {drive_method} needs"
                    ),
                ));
            }
            None => 0.0,
            Some(v) if search_velocity > 0.0 => self.above_zero(
                &a.key("homing", "latch_velocity", true),
                &a.speed_unit(),
                search_velocity,
                &format!(" (`{search_key}`)"),
                v,
            )?,
            Some(v) => self.above_zero(
                &a.key("homing", "latch_velocity", true),
                &a.speed_unit(),
                a.velocity,
                &speed_words,
                v,
            )?,
        };
        let acceleration_units_s2 = match h.acceleration {
            None => a.acceleration,
            Some(v) => self.above_zero(
                &format!("{table}.acceleration_{}_s2", a.unit),
                &format!("{}/s²", a.unit),
                a.acceleration,
                &format!(" (the axis's `{}`)", a.acceleration_key()),
                v,
            )?,
        };
        let (min, max) = a.travel;
        let search_distance_units = match (h.search_distance, bus) {
            (Some(d), Some(_)) => {
                return Err(self.error(
                    d.span(),
                    format!(
                        "`{}` is the simulated drive's search limit for kind \"drive\"; with [ethercat] the drive searches within its own limits; remove it",
                        a.key("homing", "search_distance", false)
                    ),
                ));
            }
            (Some(d), None) => self.above_zero(
                &a.key("homing", "search_distance", false),
                a.unit,
                MAX_SEARCH_DISTANCE_MM,
                "",
                d,
            )?,
            (None, _) => DEFAULT_SEARCH_DISTANCE_TRAVELS * (max - min),
        };
        let home_units = self.home_position(a, h)?;
        let final_speed_units_s = match h.final_speed {
            None if search_velocity > 0.0 => search_velocity,
            None => a.velocity * DEFAULT_DRIVE_FINAL_SPEED_PCT / 100.0,
            Some(v) => self.above_zero(
                &a.key("homing", "final_speed", true),
                &a.speed_unit(),
                a.velocity,
                &format!(" (the axis's `{}`)", a.velocity_key()),
                v,
            )?,
        };
        let sequence = self.sequence(table, h)?;
        // Every object within its type in the drive's counts.
        if let Some(scale) = a.scale {
            let cpu = scale.counts_per_unit();
            let objects = [
                (
                    search_key.clone(),
                    h.search_velocity,
                    search_velocity,
                    "counts/s",
                    "0x6099:01",
                ),
                (
                    a.key("homing", "latch_velocity", true),
                    h.latch_velocity,
                    latch_velocity,
                    "counts/s",
                    "0x6099:02",
                ),
                (
                    format!("{table}.acceleration_{}_s2", a.unit),
                    h.acceleration,
                    acceleration_units_s2,
                    "counts/s²",
                    "0x609A",
                ),
            ];
            for (key, given, v, counts_unit, object) in objects {
                let counts = (v * cpu).round();
                if counts > f64::from(u32::MAX) {
                    let message = format!(
                        "`{key}` is {} {counts_unit} at the drive's {} counts/{}, beyond the 32-bit {object} ({})",
                        number(counts),
                        number(cpu),
                        a.unit,
                        u32::MAX
                    );
                    return Err(match given {
                        Some(g) => self.error(g.span(), message),
                        None => self.error(h.kind.span(), message),
                    });
                }
            }
            if let (Err(_), Some(v)) = (scale.to_counts(home_offset_units), h.home_offset) {
                return Err(self.error(
                    v.span(),
                    format!(
                        "`{}` is {} counts at the drive's {} counts/{}, beyond the 32-bit home offset 0x607C ({})",
                        a.key("homing", "home_offset", false),
                        number((home_offset_units * cpu).round()),
                        number(cpu),
                        a.unit,
                        i32::MAX
                    ),
                ));
            }
        }
        Ok(AxisHoming {
            kind: HomingKind::Drive,
            switch_input: None,
            drive_method,
            search_velocity_units_s: search_velocity,
            latch_velocity_units_s: latch_velocity,
            acceleration_units_s2,
            search_distance_units,
            home_offset_units,
            home_units,
            final_speed_units_s,
            sequence,
        })
    }

    /// `home_mm` (`home_deg`) of axis `a`: within its travel; by default
    /// [`DEFAULT_HOME_MM`] when that is within it.
    fn home_position(&self, a: &AxisFacts, h: &AxisHomingKeys) -> Result<f64, ConfigError> {
        let (min, max) = a.travel;
        let home_key = a.key("homing", "home", false);
        let travel_words = format!(
            "the travel of axis {}, {} to {} {} (`min_{}`, `max_{}`)",
            a.name,
            number(min),
            number(max),
            a.unit,
            a.unit,
            a.unit
        );
        match h.home {
            None if (min..=max).contains(&DEFAULT_HOME_MM) => Ok(DEFAULT_HOME_MM),
            None => Err(self.error(
                h.kind.span(),
                format!(
                    "`{home_key}` is not given, and its default, {} {}, is outside {travel_words}: give the position the axis goes to after homing",
                    number(DEFAULT_HOME_MM),
                    a.unit
                ),
            )),
            Some(v) if (min..=max).contains(v.get_ref()) => Ok(*v.get_ref()),
            Some(v) => Err(self.error(
                v.span(),
                format!(
                    "`{home_key}` ({} {}) must lie within {travel_words}",
                    number(*v.get_ref()),
                    a.unit
                ),
            )),
        }
    }

    /// `sequence` of a homing table.
    fn sequence(&self, table: &str, h: &AxisHomingKeys) -> Result<u32, ConfigError> {
        match h.sequence {
            None => Ok(DEFAULT_HOMING_SEQUENCE),
            Some(s) => self.integer(
                &format!("{table}.sequence"),
                "a homing sequence number",
                HOMING_SEQUENCE_RANGE,
                s,
            ),
        }
    }

    /// A value above 0 and at most `max` (`max_words` says what `max` is).
    fn above_zero(
        &self,
        key: &str,
        unit: &str,
        max: f64,
        max_words: &str,
        value: &Spanned<f64>,
    ) -> Result<f64, ConfigError> {
        let v = *value.get_ref();
        if v > 0.0 && v <= max {
            Ok(v)
        } else {
            Err(self.error(
                value.span(),
                format!(
                    "`{key}` must be above 0 and at most {} {unit}{max_words}, found {}",
                    number(max),
                    number(v)
                ),
            ))
        }
    }

    /// `[axes.*.limit_switches]` of axis `a`.
    fn limit_switches(&self, a: &AxisFacts, io: &IoConfig) -> Result<LimitSwitches, ConfigError> {
        let Some(l) = a.tables.limit_switches else {
            return Ok(LimitSwitches::default());
        };
        let input = |end: &str, v: &Option<Spanned<String>>| match v {
            None => Ok(None),
            Some(v) => self
                .io_ref(
                    &format!("axes.{}.limit_switches.{end}", a.name),
                    v,
                    io,
                    IoType::DigitalInput,
                )
                .map(|r| Some(u32::from(r.number))),
        };
        Ok(LimitSwitches {
            min_input: input("min", &l.min)?,
            max_input: input("max", &l.max)?,
        })
    }

    /// No digital input serves two of the machine's functions: the home and limit
    /// switches of `axes`, the spindle's at-speed and the tool changer's changed inputs
    /// (each of which its kind accepted).
    fn inputs_used_once(&self, raw: &RawConfig, axes: &[AxisFacts]) -> Result<(), ConfigError> {
        let spindle = raw.spindle.as_ref().map(|s| s.get_ref());
        let changer = raw.tool_changer.as_ref().map(|s| s.get_ref());
        let mut used: Vec<(String, &Spanned<String>)> = Vec::new();
        if let Some(i) = spindle.and_then(|s| s.at_speed_input.as_ref()) {
            used.push(("spindle.at_speed_input".to_string(), i));
        }
        if let Some(i) = changer.and_then(|c| c.changed_input.as_ref()) {
            used.push(("tool_changer.changed_input".to_string(), i));
        }
        for a in axes {
            if let Some(s) = a.tables.homing.as_ref().and_then(|h| h.switch) {
                used.push((format!("axes.{}.homing.switch", a.name), s));
            }
            if let Some(l) = a.tables.limit_switches {
                for (end, v) in [("min", &l.min), ("max", &l.max)] {
                    if let Some(v) = v {
                        used.push((format!("axes.{}.limit_switches.{end}", a.name), v));
                    }
                }
            }
        }
        for (i, (key, v)) in used.iter().enumerate() {
            if let Some((first, _)) = used[..i].iter().find(|(_, w)| w.get_ref() == v.get_ref()) {
                return Err(self.error(
                    v.span(),
                    format!(
                        "`{first}` and `{key}` both name the input `{}`; each machine function has its own input",
                        v.get_ref()
                    ),
                ));
            }
        }
        Ok(())
    }

    /// `[axes.*.sim]` of axis `a`, homed as `homing`: refused beside `[ethercat]`; each
    /// switch it places needs its input (kind "drive": the home switch is the drive's own,
    /// for a method that uses one), and that input's value is the simulation's (`sim` of
    /// `[io]` refused for it).
    fn sim_axis(
        &self,
        a: &AxisFacts,
        homing: &AxisHoming,
        raw_io: &RawIo,
        bus: Option<&EthercatConfig>,
    ) -> Result<SimAxis, ConfigError> {
        let kind = homing.kind;
        let Some((table_span, s)) = &a.tables.sim else {
            return Ok(SimAxis::default());
        };
        if bus.is_some() {
            return Err(self.error(
                table_span.clone(),
                format!(
                    "[axes.{}.sim] describes the simulated machine behind a simulated drive, but with [ethercat] the drives and their switches are real; remove it",
                    a.name
                ),
            ));
        }
        let key = |base: &str| a.key("sim", base, false);
        let value = |base: &str, v: Option<&Spanned<f64>>| match v {
            None => Ok(None),
            Some(v) => self.coordinate(&key(base), a.unit, v).map(Some),
        };
        let start_units = value("start", s.start)?.unwrap_or(DEFAULT_SIM_START_MM);
        let home_switch_units = value("home_switch", s.home_switch)?;
        let min_limit_units = value("min_limit", s.min_limit)?;
        let max_limit_units = value("max_limit", s.max_limit)?;

        if let Some(v) = s.home_switch {
            if kind == HomingKind::Drive && !drive_method_moves(homing.drive_method) {
                return Err(self.error(
                    v.span(),
                    format!(
                        "`{}` places a simulated home switch, but `axes.{}.homing.method` {} homes where the axis stands, without a switch; remove it",
                        key("home_switch"),
                        a.name,
                        homing.drive_method
                    ),
                ));
            }
            if !matches!(kind, HomingKind::Switch | HomingKind::Drive) {
                let why = match &a.tables.homing {
                    Some(h) => format!("`axes.{}.homing.kind` is \"{}\"", a.name, h.kind.get_ref()),
                    None => format!("axis {} has no [axes.{}.homing]", a.name, a.name),
                };
                return Err(self.error(
                    v.span(),
                    format!(
                        "`{}` places a simulated home switch, but {why}: it needs kind \"switch\" or \"drive\"; remove it or home the axis on a switch",
                        key("home_switch")
                    ),
                ));
            }
            if let Some(name) = a.tables.homing.as_ref().and_then(|h| h.switch) {
                self.driven_by_the_simulation(name, &key("home_switch"), raw_io)?;
            }
        }
        let limits = a.tables.limit_switches;
        for (end, v) in [("min", s.min_limit), ("max", s.max_limit)] {
            let Some(v) = v else { continue };
            let input = limits.and_then(|l| if end == "min" { &l.min } else { &l.max }.as_ref());
            let this = key(&format!("{end}_limit"));
            let Some(name) = input else {
                return Err(self.error(
                    v.span(),
                    format!(
                        "`{this}` places the simulated {end} limit switch, but `axes.{}.limit_switches.{end}` names no input for it; add it or remove this key",
                        a.name
                    ),
                ));
            };
            self.driven_by_the_simulation(name, &this, raw_io)?;
        }
        if let (Some(lo), Some(hi), Some(v)) = (min_limit_units, max_limit_units, s.max_limit)
            && lo >= hi
        {
            return Err(self.error(
                v.span(),
                format!(
                    "`{}` ({}) must be greater than `{}` ({})",
                    key("max_limit"),
                    number(hi),
                    key("min_limit"),
                    number(lo)
                ),
            ));
        }
        Ok(SimAxis {
            start_units,
            home_switch_units,
            min_limit_units,
            max_limit_units,
        })
    }

    /// The input named `name` is set by the axis simulation that `by` (a key) places: its
    /// `sim` start value in `[io]` would be overwritten at once, so it is refused. (The
    /// input is a simulated one: `[axes.*.sim]` exists only without `[ethercat]`, where
    /// every input of `[io]` is.)
    fn driven_by_the_simulation(
        &self,
        name: &Spanned<String>,
        by: &str,
        raw_io: &RawIo,
    ) -> Result<(), ConfigError> {
        let entry = raw_io
            .digital_inputs
            .iter()
            .enumerate()
            .find(|(_, d)| d.name.get_ref() == name.get_ref());
        if let Some((i, d)) = entry
            && let Some(sim) = &d.sim
        {
            return Err(self.error(
                sim.span(),
                format!(
                    "`io.digital_inputs[{i}].sim` sets the start value of `{}`, but the simulation sets that input from the axis's position (`{by}`); remove it",
                    name.get_ref()
                ),
            ));
        }
        Ok(())
    }
}
