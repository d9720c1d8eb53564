//! Reading a configuration: the file or text parsed into the raw records and checked.

use std::path::Path;

use kerf_drive::cia402::Scale;
use kerf_gcode::Settings;

use crate::check::Checker;
use crate::raw::RawConfig;
use crate::toml_words::{in_file_terms, position_of};
use crate::*;

impl Config {
    /// The bundled example configuration (`config/kerf.toml`).
    pub fn builtin() -> Config {
        // The bundled file is checked by a unit test, so failing here would be a build
        // defect; falling back to the same numbers keeps the binary from ever panicking.
        Config::from_toml_str(BUILTIN_TOML, BUILTIN_ORIGIN).unwrap_or_else(|_| Config {
            machine: DEFAULT_MACHINE.to_string(),
            daemon: DaemonConfig::default(),
            dialect: None,
            period_us: DEFAULT_PERIOD_US,
            tolerance_mm: DEFAULT_TOLERANCE_MM,
            axes: Axes {
                x: FALLBACK_AXIS,
                y: FALLBACK_AXIS,
                z: FALLBACK_AXIS,
                a: None,
                b: None,
                c: None,
            },
            arc_tolerance_mm: Settings::default().arc_tolerance_mm,
            arc_tolerance_rel: Settings::default().arc_tolerance_rel,
            work_offsets_mm: [[0.0; 3]; 9],
            tools: Vec::new(),
            tool_table: None,
            subroutine_path: Vec::new(),
            dump_dir: None,
            max_loop_iterations: Settings::default().max_loop_iterations,
            block_delete: Settings::default().block_delete,
            g28_home_mm_deg: [0.0; 6],
            g30_home_mm_deg: [0.0; 6],
            parameter_file: None,
            drive: DriveSide {
                axes: {
                    let axis = Scale::new(DEFAULT_COUNTS_PER_UNIT, 1)
                        .ok()
                        .map(AxisDrive::with_scale);
                    [axis, axis, axis, None, None, None]
                },
                margin: kerf_drive::safety::DEFAULT_MARGIN,
                stall_cycles: kerf_drive::safety::DEFAULT_STALL_CYCLES,
                recorder_seconds: kerf_drive::recorder::DEFAULT_SECONDS,
            },
            ethercat: None,
            io: IoConfig::default(),
            spindle: SpindleConfig::default(),
            coolant: CoolantConfig::default(),
            tool_changer: ToolChanger::default(),
            operator: OperatorConfig::default(),
            homing: HomingConfig::default(),
            jog: JogConfig::default(),
            serve: ServeConfig::default(),
            setups: [
                Some(AxisSetup::default()),
                Some(AxisSetup::default()),
                Some(AxisSetup::default()),
                None,
                None,
                None,
            ],
        })
    }

    /// Reads and validates the file at `path`; errors name the path as given.
    pub fn load(path: &Path) -> Result<Config, ConfigError> {
        let origin = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Io {
            origin: origin.clone(),
            source,
        })?;
        let dir = path.parent().unwrap_or(Path::new(""));
        Config::from_toml_str_in(&text, &origin, dir)
    }

    /// Parses and validates TOML text; `origin` names the text in error messages. The
    /// files it names (`gcode.tool_table`, ...) are relative to the current directory.
    pub fn from_toml_str(text: &str, origin: &str) -> Result<Config, ConfigError> {
        Config::from_toml_str_in(text, origin, Path::new(""))
    }

    /// Parses and validates TOML text whose relative file names are relative to `dir`.
    pub fn from_toml_str_in(text: &str, origin: &str, dir: &Path) -> Result<Config, ConfigError> {
        let raw: RawConfig = toml::from_str(text).map_err(|e| ConfigError::Invalid {
            origin: origin.to_string(),
            position: e.span().map(|s| position_of(text, s.start)),
            message: in_file_terms(text, &e),
        })?;
        let check = Checker { text, origin, dir };
        check.config(raw)
    }

    /// The settings of a program run: [`Config::settings`] with the parameters of
    /// `gcode.parameter_file` restored (a missing file restores nothing).
    pub fn program_settings(&self) -> Result<Settings, ConfigError> {
        let mut settings = self.settings();
        if let Some(path) = &self.parameter_file {
            settings.parameters =
                tooltable::load_parameter_file(path, &path.display().to_string())?;
        }
        Ok(settings)
    }

    /// The settings the G-code interpreter needs from this configuration.
    pub fn settings(&self) -> Settings {
        Settings {
            work_offsets_mm: self.work_offsets_mm,
            tools: self.tools.clone(),
            arc_tolerance_mm: self.arc_tolerance_mm,
            arc_tolerance_rel: self.arc_tolerance_rel,
            subroutine_path: self.subroutine_path.clone(),
            max_loop_iterations: self.max_loop_iterations,
            block_delete: self.block_delete,
            g28_home_mm_deg: self.g28_home_mm_deg,
            g30_home_mm_deg: self.g30_home_mm_deg,
            simulated_inputs: self.simulated_inputs(),
            ..Settings::default()
        }
    }

    /// The inputs' values at start as the simulated I/O has them (`sim` in `[io]`): what
    /// `kerf plan` and `kerf sim` answer an `M66` with (they never change offline).
    pub fn simulated_inputs(&self) -> kerf_gcode::SimulatedInputs {
        let mut inputs = kerf_gcode::SimulatedInputs::default();
        for i in self.io.digital_inputs.iter().filter(|i| i.sim) {
            inputs.digital |= 1 << i.number;
        }
        for i in &self.io.analog_inputs {
            inputs.analog[usize::from(i.number)] = i.sim;
        }
        inputs
    }
}

const FALLBACK_AXIS: LinearAxis = LinearAxis {
    velocity_mm_s: 100.0,
    acceleration_mm_s2: 1000.0,
    jerk_mm_s3: 25000.0,
    min_mm: -500.0,
    max_mm: 500.0,
};
