//! The machine's offsets and the work position, as a DRO shows them (`kerf status`,
//! `kerf offset show`).
//!
//! The offsets live in LinuxCNC's numbered parameters, in the machine's parameter file
//! (`kerf_config::Config::machine_parameter_file`): the work offsets G54–G59.3 with their
//! XY rotations (#5221…, twenty apart), the G52/G92 offset (#5211–#5216, applied while
//! #5210 is 1) and the active system (#5220). The work position is computed by the
//! interpreter itself from the state a program starts in on this machine (the configured
//! dialect, the machine's parameters, the position): the machine position minus every
//! offset in force, rotation included, as LinuxCNC's DRO shows it, and what a program
//! reads as its current point before its first move.
//!
//! Tool offsets: a program starts in G49 (no tool offset in force) and applies the
//! tool's length with G43; the daemon does not report a program's G43. The work position
//! here is the one without tool offsets, which is what a program reads until its G43, and
//! what `kerf offset set` measures from ([`Dro::tool_offset_mm_deg`] is that offset: 0).

use kerf_config::{Config, ConfigError};
use kerf_gcode::{Dialect, Interpreter, Settings};
use kerf_geom::PerAxis;

/// The names of the coordinate systems, G54 to G59.3, by index.
pub const SYSTEM_NAMES: [&str; 9] = [
    "G54", "G55", "G56", "G57", "G58", "G59", "G59.1", "G59.2", "G59.3",
];

/// The name of coordinate system `index` (0 = G54); "none" for `None` (Sinumerik G500).
pub fn system_name(index: Option<usize>) -> &'static str {
    index
        .and_then(|i| SYSTEM_NAMES.get(i).copied())
        .unwrap_or("none")
}

/// The index (0 = G54) of a coordinate system named `G54` … `G59.3` (either case).
pub fn system_index(name: &str) -> Option<usize> {
    SYSTEM_NAMES
        .iter()
        .position(|n| n.eq_ignore_ascii_case(name))
}

/// One coordinate system's offset.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct WorkOffset {
    /// X, Y, Z mm, A, B, C degrees: where the system's zero is in machine coordinates.
    pub offset_mm_deg: PerAxis<f64>,
    /// The system's XY rotation about its zero, degrees (G10 L2 R).
    pub rotation_deg: f64,
}

/// Every offset of the machine, from its persistent parameters.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Offsets {
    /// G54 … G59.3.
    pub systems: [WorkOffset; 9],
    /// The G52/G92 offset (#5211–#5216), X Y Z mm, A B C degrees.
    pub g92_mm_deg: PerAxis<f64>,
    /// The G52/G92 offset applies (#5210 is not 0).
    pub g92_enabled: bool,
    /// The coordinate system a program starts in (#5220; 0 = G54).
    pub active: usize,
}

/// The first parameter of coordinate system `index` (0 = G54), LinuxCNC's numbering.
fn system_base(index: usize) -> u32 {
    5221 + 20 * index as u32
}

impl Offsets {
    /// The offsets in `params`, LinuxCNC's persistent parameters (number, value); a
    /// number missing is 0.
    pub fn from_parameters(params: &[(u32, f64)]) -> Offsets {
        let at = |n: u32| {
            params
                .iter()
                .find(|(k, _)| *k == n)
                .map_or(0.0, |(_, v)| *v)
        };
        let mut o = Offsets::default();
        for (i, s) in o.systems.iter_mut().enumerate() {
            let base = system_base(i);
            for (k, v) in s.offset_mm_deg.iter_mut().enumerate() {
                *v = at(base + k as u32);
            }
            s.rotation_deg = at(base + 9);
        }
        for (k, v) in o.g92_mm_deg.iter_mut().enumerate() {
            *v = at(5211 + k as u32);
        }
        o.g92_enabled = at(5210) != 0.0;
        let active = at(5220);
        o.active = if active.fract() == 0.0 && (1.0..=9.0).contains(&active) {
            active as usize - 1
        } else {
            0
        };
        o
    }

    /// The machine's offsets: the configured work offsets with the machine's parameter
    /// file over them (what a program starts with).
    pub fn read(config: &Config) -> Result<Offsets, ConfigError> {
        let interp = start_state(config, config.machine_settings()?, [0.0; 6]);
        Ok(Offsets::from_parameters(&interp.persistent_parameters()))
    }
}

/// The DRO: where the machine is, in machine and in work coordinates, and the offsets
/// between them.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Dro {
    /// The active coordinate system (0 = G54); `None` in a dialect that starts without
    /// one (Sinumerik G500, Heidenhain).
    pub system: Option<usize>,
    /// Its offset and rotation (zero without a system).
    pub work_offset: WorkOffset,
    /// The G52/G92 offset in force (zero while it does not apply).
    pub g92_mm_deg: PerAxis<f64>,
    /// The tool in the spindle (0: none).
    pub tool: u32,
    /// The tool offsets in force between programs: none (programs start in G49).
    pub tool_offset_mm_deg: PerAxis<f64>,
    /// The machine position, X Y Z mm, A B C degrees.
    pub machine_mm_deg: PerAxis<f64>,
    /// The work position: the machine position with every offset in force taken off.
    pub work_mm_deg: PerAxis<f64>,
}

/// An interpreter in the state a program starts in on the machine of `config`, standing
/// at `machine_mm_deg`: nothing is read from it, it only answers.
fn start_state(
    config: &Config,
    settings: Settings,
    machine_mm_deg: PerAxis<f64>,
) -> Interpreter<&'static [u8]> {
    let settings = Settings {
        start_mm_deg: machine_mm_deg,
        ..settings
    };
    let dialect = config.dialect.unwrap_or(Dialect::LinuxCnc);
    Interpreter::new(&[][..], dialect, settings)
}

impl Dro {
    /// The DRO of the machine of `config` (its parameter file read) at `machine_mm_deg`
    /// with `tool` in the spindle.
    pub fn read(
        config: &Config,
        machine_mm_deg: PerAxis<f64>,
        tool: u32,
    ) -> Result<Dro, ConfigError> {
        Ok(Dro::with_settings(
            config,
            config.machine_settings()?,
            machine_mm_deg,
            tool,
        ))
    }

    /// [`Dro::read`] with the machine's settings already read.
    pub fn with_settings(
        config: &Config,
        settings: Settings,
        machine_mm_deg: PerAxis<f64>,
        tool: u32,
    ) -> Dro {
        let interp = start_state(config, settings, machine_mm_deg);
        let offsets = Offsets::from_parameters(&interp.persistent_parameters());
        let system = interp.coordinate_system();
        Dro {
            system,
            work_offset: system.map_or_else(WorkOffset::default, |i| offsets.systems[i]),
            g92_mm_deg: if offsets.g92_enabled {
                offsets.g92_mm_deg
            } else {
                [0.0; 6]
            },
            tool,
            tool_offset_mm_deg: [0.0; 6],
            machine_mm_deg,
            work_mm_deg: interp.program_position(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn work_position_takes_off_the_active_offset_its_rotation_and_g92() {
        let config = Config::builtin();
        let params = vec![
            (5210, 1.0),
            (5211, 1.0),
            (5212, 2.0),
            (5213, 3.0),
            (5220, 2.0),
            // G55: zero at machine (100, 50, -10), rotated 90°.
            (5241, 100.0),
            (5242, 50.0),
            (5243, -10.0),
            (5250, 90.0),
        ];
        let settings = Settings {
            parameters: params.clone(),
            ..config.settings()
        };
        // Machine (100, 60, -20): 10 mm along +Y from the G55 zero, which its +90°
        // rotation reads as +X 10; then G92 (1, 2, 3) is taken off.
        let dro = Dro::with_settings(&config, settings, [100.0, 60.0, -20.0, 0.0, 0.0, 0.0], 3);
        assert_eq!(dro.system, Some(1));
        assert_eq!(system_name(dro.system), "G55");
        assert_eq!(dro.work_offset.offset_mm_deg[..3], [100.0, 50.0, -10.0]);
        assert_eq!(dro.work_offset.rotation_deg, 90.0);
        assert_eq!(dro.g92_mm_deg[..3], [1.0, 2.0, 3.0]);
        let w = dro.work_mm_deg;
        let expected = [10.0 - 1.0, 0.0 - 2.0, -10.0 - 3.0];
        for i in 0..3 {
            assert!((w[i] - expected[i]).abs() < 1e-9, "{w:?} vs {expected:?}");
        }
        let o = Offsets::from_parameters(&params);
        assert_eq!(o.active, 1);
        assert!(o.g92_enabled);
        assert_eq!(system_index("g59.3"), Some(8));
    }
}
