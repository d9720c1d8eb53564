//! The whole configuration checked, key group by key group: machine, daemon, dialect,
//! period, tolerance, axes, drives, the machine's functions, G-code settings.

use std::path::Path;

use kerf_drive::sim::SimConfig;
use kerf_gcode::{Dialect, Settings};

use crate::raw::*;
use crate::*;

use super::Checker;

impl Checker<'_> {
    pub(crate) fn daemon(&self, raw: &RawDaemon) -> Result<DaemonConfig, ConfigError> {
        let d = DaemonConfig::default();
        let priority = match &raw.priority {
            None => d.priority,
            Some(p) => self.integer("daemon.priority", "a SCHED_FIFO priority", 1..=99, p)? as u8,
        };
        let cpu = match &raw.cpu {
            None => None,
            Some(c) => Some(self.integer("daemon.cpu", "a CPU number", 0..=4095, c)?),
        };
        let cpu_latency_us = self.integer_or(
            "daemon.cpu_latency_us",
            "a latency in µs",
            CPU_LATENCY_RANGE_US,
            &raw.cpu_latency_us,
            d.cpu_latency_us,
        )?;
        let queue_segments = self.integer_or(
            "daemon.queue_segments",
            "a number of segments",
            QUEUE_SEGMENTS_RANGE,
            &raw.queue_segments,
            d.queue_segments,
        )?;
        let move_window = self.integer_or(
            "daemon.move_window",
            "a number of moves",
            MOVE_WINDOW_RANGE,
            &raw.move_window,
            d.move_window,
        )?;
        let state_file = match &raw.state_file {
            None => d.state_file,
            Some(f) if f.get_ref().is_empty() => {
                return Err(self.error(
                    f.span(),
                    "`daemon.state_file` must name a file, found an empty string".to_string(),
                ));
            }
            Some(f) => Some(self.dir.join(f.get_ref())),
        };
        Ok(DaemonConfig {
            priority,
            cpu,
            cpu_latency_us,
            queue_segments,
            move_window,
            state_file,
        })
    }

    /// The whole file checked, in the order of its reference; the first bad key is the error.
    pub(crate) fn config(&self, raw: RawConfig) -> Result<Config, ConfigError> {
        let machine = self.machine(&raw)?;
        let daemon = self.daemon(&raw.daemon)?;
        let dialect = self.dialect(&raw)?;

        let period_us = self.period(&raw)?;

        let tolerance_mm = match &raw.tolerance_mm {
            None => DEFAULT_TOLERANCE_MM,
            Some(t) => self.within("tolerance_mm", "mm", TOLERANCE_RANGE_MM, t)?,
        };

        let axes = Axes {
            x: self.linear("x", &raw.axes.x)?,
            y: self.linear("y", &raw.axes.y)?,
            z: self.linear("z", &raw.axes.z)?,
            a: self.rotary("a", &raw.axes.a)?,
            b: self.rotary("b", &raw.axes.b)?,
            c: self.rotary("c", &raw.axes.c)?,
        };
        let mut drive = self.drive_side(&raw, &axes)?;
        size_substeps(&raw, &mut drive, period_us);
        let ethercat = self.ethercat(&raw, &axes, period_us, &mut drive)?;
        let io = self.io(&raw.io, ethercat.as_ref())?;
        let spindle = self.spindle(raw.spindle.as_ref(), &io, ethercat.as_ref())?;
        let coolant = self.coolant(&raw.coolant, &io)?;
        let tool_changer = self.tool_changer(raw.tool_changer.as_ref(), &io)?;
        self.outputs_used_once(&raw)?;
        let operator = self.operator(&raw.operator);
        let setups = self.axis_setups(&raw, &axes, &drive, &io, ethercat.as_ref())?;
        let homing = self.homing(&raw.homing)?;
        let jog = self.jog(&raw.jog)?;
        let serve = self.serve(&raw.serve)?;
        let dump_dir = match &raw.safety.dump_dir {
            None => None,
            Some(d) if d.get_ref().is_empty() => {
                return Err(self.error(
                    d.span(),
                    "`safety.dump_dir` must name a directory, found an empty string".to_string(),
                ));
            }
            Some(d) => Some(self.dir.join(d.get_ref())),
        };

        let defaults = Settings::default();
        let arc_tolerance_mm = match &raw.gcode.arc_tolerance_mm {
            None => defaults.arc_tolerance_mm,
            Some(t) => self.within("gcode.arc_tolerance_mm", "mm", TOLERANCE_RANGE_MM, t)?,
        };
        let arc_tolerance_rel = match &raw.gcode.arc_tolerance_rel {
            None => defaults.arc_tolerance_rel,
            Some(t) => self.within(
                "gcode.arc_tolerance_rel",
                "(fraction of the radius)",
                ARC_TOLERANCE_REL_RANGE,
                t,
            )?,
        };

        let w = &raw.work_offsets;
        let work_offsets_mm = [
            self.offset("g54", &w.g54)?,
            self.offset("g55", &w.g55)?,
            self.offset("g56", &w.g56)?,
            self.offset("g57", &w.g57)?,
            self.offset("g58", &w.g58)?,
            self.offset("g59", &w.g59)?,
            self.offset("g59_1", &w.g59_1)?,
            self.offset("g59_2", &w.g59_2)?,
            self.offset("g59_3", &w.g59_3)?,
        ];

        let g = &raw.gcode;
        let tool_table = g.tool_table.as_ref().map(|f| self.dir.join(f.get_ref()));
        let tools = self.tools(&raw, tool_table.as_deref())?;
        let subroutine_path = match &g.subroutine_path {
            None => Vec::new(),
            Some(list) => list.get_ref().iter().map(|d| self.dir.join(d)).collect(),
        };
        let max_loop_iterations = self.max_loop_iterations(&raw)?;
        let block_delete = g.block_delete.unwrap_or(defaults.block_delete);
        let g28_home_mm_deg = self.home("gcode.g28_home_mm_deg", &g.g28_home_mm_deg)?;
        let g30_home_mm_deg = self.home("gcode.g30_home_mm_deg", &g.g30_home_mm_deg)?;
        let parameter_file = g
            .parameter_file
            .as_ref()
            .map(|f| self.dir.join(f.get_ref()));

        let config = Config {
            machine,
            daemon,
            dialect,
            period_us,
            tolerance_mm,
            axes,
            arc_tolerance_mm,
            arc_tolerance_rel,
            work_offsets_mm,
            tools,
            tool_table,
            subroutine_path,
            dump_dir,
            max_loop_iterations,
            block_delete,
            g28_home_mm_deg,
            g30_home_mm_deg,
            parameter_file,
            drive,
            ethercat,
            io,
            spindle,
            coolant,
            tool_changer,
            operator,
            homing,
            jog,
            serve,
            setups,
        };
        Ok(config.with_drive_homing_on_the_bus())
    }
    /// `machine`: the name of the daemon's services.
    fn machine(&self, raw: &RawConfig) -> Result<String, ConfigError> {
        Ok(match &raw.machine {
            None => DEFAULT_MACHINE.to_string(),
            Some(m) if valid_machine_name(m.get_ref()) => m.get_ref().clone(),
            Some(m) => {
                return Err(self.error(
                    m.span(),
                    format!(
                        "`machine` must be 1 to 64 ASCII letters, digits, `-` or `_` (it names the daemon's services), found `{}`",
                        m.get_ref()
                    ),
                ));
            }
        })
    }

    /// `dialect`: the machine's G-code dialect, when the file names one.
    fn dialect(&self, raw: &RawConfig) -> Result<Option<Dialect>, ConfigError> {
        Ok(match &raw.dialect {
            None => None,
            Some(name) => Some(Dialect::from_name(name.get_ref()).ok_or_else(|| {
                let known: Vec<&str> = Dialect::ALL.iter().map(|d| d.name()).collect();
                self.error(
                    name.span(),
                    format!(
                        "unknown dialect `{}` in `dialect`, expected one of: {} (or tormach)",
                        name.get_ref(),
                        known.join(", ")
                    ),
                )
            })?),
        })
    }

    /// `period_us`: the interpolation period.
    fn period(&self, raw: &RawConfig) -> Result<u32, ConfigError> {
        Ok(match &raw.period_us {
            None => DEFAULT_PERIOD_US,
            Some(p) => match u32::try_from(*p.get_ref()) {
                Ok(v) if (MIN_PERIOD_US..=MAX_PERIOD_US).contains(&v) => v,
                _ => {
                    return Err(self.error(
                        p.span(),
                        format!(
                            "`period_us` must be between {MIN_PERIOD_US} and {MAX_PERIOD_US} µs, found {}",
                            p.get_ref()
                        ),
                    ));
                }
            },
        })
    }

    /// `[[tools]]` and the tool table `gcode.tool_table` names (at `tool_table`, resolved
    /// against the configuration's directory): every tool once.
    fn tools(
        &self,
        raw: &RawConfig,
        tool_table: Option<&Path>,
    ) -> Result<Vec<ToolEntry>, ConfigError> {
        let g = &raw.gcode;
        let mut tools: Vec<ToolEntry> = Vec::with_capacity(raw.tools.len());
        for t in &raw.tools {
            let number = match u32::try_from(*t.number.get_ref()) {
                Ok(n) => n,
                Err(_) => {
                    return Err(self.error(
                        t.number.span(),
                        format!(
                            "`tools.number` must be a tool number from 0 to {}, found {}",
                            u32::MAX,
                            t.number.get_ref()
                        ),
                    ));
                }
            };
            if tools.iter().any(|e| e.number == number) {
                return Err(self.error(
                    t.number.span(),
                    format!("tool {number} is listed twice in `tools`"),
                ));
            }
            let length_mm = match &t.length_mm {
                None => 0.0,
                Some(l) => self.coordinate("tools.length_mm", "mm", l)?,
            };
            let radius_mm = match &t.radius_mm {
                None => 0.0,
                Some(r) => self.within("tools.radius_mm", "mm", 0.0..=MAX_COORDINATE_MM, r)?,
            };
            tools.push(ToolEntry {
                number,
                length_mm,
                radius_mm,
                ..ToolEntry::default()
            });
        }

        if let (Some(path), Some(f)) = (tool_table, &g.tool_table) {
            let table = tooltable::load_tool_table(path, &path.display().to_string()).map_err(
                |e| match e {
                    ConfigError::Io { source, .. } => self.error(
                        f.span(),
                        format!(
                            "cannot read `gcode.tool_table` {}: {source}",
                            path.display()
                        ),
                    ),
                    e => e,
                },
            )?;
            for t in table {
                if tools.iter().any(|e| e.number == t.number) {
                    return Err(self.error(
                        f.span(),
                        format!(
                            "tool {} is both in `tools` and in `gcode.tool_table`",
                            t.number
                        ),
                    ));
                }
                tools.push(t);
            }
        }
        Ok(tools)
    }

    /// `gcode.max_loop_iterations`.
    fn max_loop_iterations(&self, raw: &RawConfig) -> Result<u64, ConfigError> {
        Ok(match &raw.gcode.max_loop_iterations {
            None => Settings::default().max_loop_iterations,
            Some(n) => match u64::try_from(*n.get_ref()) {
                Ok(v) if MAX_LOOP_ITERATIONS_RANGE.contains(&v) => v,
                _ => {
                    return Err(self.error(
                        n.span(),
                        format!(
                            "`gcode.max_loop_iterations` must be from {} to {}, found {}",
                            MAX_LOOP_ITERATIONS_RANGE.start(),
                            MAX_LOOP_ITERATIONS_RANGE.end(),
                            n.get_ref()
                        ),
                    ));
                }
            },
        })
    }
}

/// The simulated drives' integration steps: without `substeps`, enough for their
/// bandwidth and damping at this period (at least the default); a number given that is
/// too small is refused where the drives run (`Config::check_drives`).
fn size_substeps(raw: &RawConfig, drive: &mut DriveSide, period_us: u32) {
    let given = |d: Option<&RawDrive>| d.is_some_and(|d| d.substeps.is_some());
    let raw_substeps = [
        given(raw.axes.x.drive.as_ref()),
        given(raw.axes.y.drive.as_ref()),
        given(raw.axes.z.drive.as_ref()),
        given(raw.axes.a.as_ref().and_then(|a| a.drive.as_ref())),
        given(raw.axes.b.as_ref().and_then(|a| a.drive.as_ref())),
        given(raw.axes.c.as_ref().and_then(|a| a.drive.as_ref())),
    ];
    for (i, d) in drive.axes.iter_mut().enumerate() {
        let Some(d) = d else { continue };
        let sim = SimConfig {
            period_ns: u64::from(period_us) * 1000,
            ..d.sim
        };
        if !raw_substeps[i] {
            d.sim.substeps = d.sim.substeps.max(sim.min_substeps());
        }
    }
}
