//! The machine's own files, which the commands that run on the machine keep between
//! invocations and across restarts: the persistent numbered parameters (work offsets
//! G54–G59.3 with their rotations, G92, the active coordinate system, the G28/G30
//! positions) and the tool table with the lengths that `kerf tool touch-off` measured.
//!
//! - The parameter file is `gcode.parameter_file` when the configuration names one, else
//!   `MACHINE.var` (the machine's name) in the state directory ([`Config::state_file`]'s
//!   directory: `$STATE_DIRECTORY`, else /var/lib/kerf when it exists, else the temporary
//!   directory).
//! - The tool table is `gcode.tool_table` when the configuration names one (its tools are
//!   in [`Config::tools`] already), else `MACHINE.tbl` in the state directory, whose
//!   entries replace the `[[tools]]` entries of the same number (a touched-off length
//!   wins) and add the others ([`Config::machine_tools`]).
//!
//! `kerf run`, `mdi`, `offset` and `tool` read and write these ([`Config::machine_settings`]);
//! `kerf plan` and `kerf sim` read only the files the configuration names
//! ([`Config::program_settings`]): an offline tool gives the same answer on every computer,
//! whatever a machine's leftover state.

use std::path::PathBuf;

use kerf_gcode::Settings;

use crate::views::state_directory;
use crate::{Config, ConfigError, ToolEntry, tooltable};

/// The state directory of the shipped systemd unit (`StateDirectory=kerf`): the machine's
/// files are kept there when it exists and `$STATE_DIRECTORY` is not set, so that an
/// operator's `kerf` and the service use the same ones.
pub const SYSTEM_STATE_DIRECTORY: &str = "/var/lib/kerf";

/// Why a changed tool entry could not be kept ([`Config::save_machine_tools`]).
#[derive(Debug, thiserror::Error)]
pub enum ToolFileError {
    /// The tool is a `[[tools]]` entry of a configuration that names a tool table file:
    /// Kerf writes only that file, and a tool in both is an error when the configuration
    /// is read.
    #[error(
        "{table}: error: tool {tool} is in `[[tools]]` of the configuration, not in this tool table (`gcode.tool_table`), which is the file Kerf writes: move its entry to the tool table first"
    )]
    OnlyInConfig {
        /// The tool number.
        tool: u32,
        /// The configured tool table.
        table: String,
    },
    /// The tool table could not be read.
    #[error("{0}")]
    Read(#[from] ConfigError),
    /// The tool table could not be written.
    #[error("{path}: error: cannot write the tool table: {source}")]
    Write {
        /// The file.
        path: String,
        /// The underlying error.
        source: std::io::Error,
    },
}

impl Config {
    /// The machine's parameter file: `gcode.parameter_file`, else `MACHINE.var` in the
    /// state directory.
    pub fn machine_parameter_file(&self) -> PathBuf {
        match &self.parameter_file {
            Some(p) => p.clone(),
            None => state_directory().join(format!("{}.var", self.machine)),
        }
    }

    /// Where programs sent to the machine through `kerf serve` are kept: `MACHINE-programs`
    /// in the state directory.
    pub fn machine_program_directory(&self) -> PathBuf {
        state_directory().join(format!("{}-programs", self.machine))
    }

    /// The OPC UA server's certificate store (`trusted/`, `rejected/`):
    /// `serve.opcua_pki_dir`, else `MACHINE-opcua-pki` in the state directory.
    pub fn machine_opcua_pki_directory(&self) -> PathBuf {
        match &self.serve.opcua_pki_dir {
            Some(p) => p.clone(),
            None => state_directory().join(format!("{}-opcua-pki", self.machine)),
        }
    }

    /// The machine's tool table file: `gcode.tool_table`, else `MACHINE.tbl` in the state
    /// directory.
    pub fn machine_tool_table(&self) -> PathBuf {
        match &self.tool_table {
            Some(p) => p.clone(),
            None => state_directory().join(format!("{}.tbl", self.machine)),
        }
    }

    /// The machine's tool table: [`Config::tools`]; when `gcode.tool_table` is not
    /// configured, the entries of the machine's own table ([`Config::machine_tool_table`],
    /// when it exists) replace those of `[[tools]]` with the same number and add the
    /// others.
    pub fn machine_tools(&self) -> Result<Vec<ToolEntry>, ConfigError> {
        if self.tool_table.is_some() {
            return Ok(self.tools.clone());
        }
        self.tools_with_table(&self.machine_tool_table())
    }

    /// [`Config::tools`] with the entries of the tool table at `path` (when it exists) in
    /// place of those with the same number, and the others added.
    fn tools_with_table(&self, path: &std::path::Path) -> Result<Vec<ToolEntry>, ConfigError> {
        let mut tools = self.tools.clone();
        let origin = path.display().to_string();
        let text = match std::fs::read_to_string(path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(tools),
            Err(e) => {
                return Err(ConfigError::Invalid {
                    origin,
                    position: None,
                    message: format!("cannot read the machine's tool table: {e}"),
                });
            }
        };
        for entry in tooltable::parse_tool_table(&text, &origin)? {
            match tools.iter_mut().find(|t| t.number == entry.number) {
                Some(t) => *t = entry,
                None => tools.push(entry),
            }
        }
        Ok(tools)
    }

    /// The machine's persistent parameters ([`Config::machine_parameter_file`]; none when
    /// it does not exist yet).
    pub fn machine_parameters(&self) -> Result<Vec<(u32, f64)>, ConfigError> {
        let path = self.machine_parameter_file();
        tooltable::load_parameter_file(&path, &path.display().to_string())
    }

    /// The interpreter settings of a program or MDI line run on the machine:
    /// [`Config::settings`] with the machine's tool table ([`Config::machine_tools`]) and
    /// its persistent parameters ([`Config::machine_parameters`]).
    pub fn machine_settings(&self) -> Result<Settings, ConfigError> {
        let mut settings = self.settings();
        settings.tools = self.machine_tools()?;
        settings.parameters = self.machine_parameters()?;
        Ok(settings)
    }

    /// Writes the persistent parameters `params` to the machine's parameter file,
    /// atomically; returns the file.
    pub fn save_machine_parameters(&self, params: &[(u32, f64)]) -> std::io::Result<PathBuf> {
        let path = self.machine_parameter_file();
        tooltable::write_parameter_file(&path, params)?;
        Ok(path)
    }

    /// Writes the changed entries `tools` to the machine's tool table file, atomically,
    /// keeping its other lines ([`tooltable::write_tool_table`]); returns the file. A tool
    /// of `[[tools]]` in a configuration that names `gcode.tool_table` is refused
    /// ([`ToolFileError::OnlyInConfig`]) and nothing is written.
    pub fn save_machine_tools(&self, tools: &[ToolEntry]) -> Result<PathBuf, ToolFileError> {
        let path = self.machine_tool_table();
        if self.tool_table.is_some() {
            let origin = path.display().to_string();
            let in_file = tooltable::load_tool_table(&path, &origin)?;
            if let Some(t) = tools
                .iter()
                .find(|t| !in_file.iter().any(|f| f.number == t.number))
            {
                return Err(ToolFileError::OnlyInConfig {
                    tool: t.number,
                    table: origin,
                });
            }
        }
        tooltable::write_tool_table(&path, tools).map_err(|source| ToolFileError::Write {
            path: path.display().to_string(),
            source,
        })?;
        Ok(path)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("kerf-state-files-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("scratch dir");
        dir
    }

    fn config(dir: &std::path::Path, gcode: &str) -> Config {
        let text = format!(
            "machine = \"m\"\n[axes.x]\nvelocity_mm_s = 100\nacceleration_mm_s2 = 1000\njerk_mm_s3 = 10000\nmin_mm = 0\nmax_mm = 100\n\
             [axes.y]\nvelocity_mm_s = 100\nacceleration_mm_s2 = 1000\njerk_mm_s3 = 10000\nmin_mm = 0\nmax_mm = 100\n\
             [axes.z]\nvelocity_mm_s = 100\nacceleration_mm_s2 = 1000\njerk_mm_s3 = 10000\nmin_mm = -100\nmax_mm = 0\n\
             [[tools]]\nnumber = 1\nlength_mm = 10\n[[tools]]\nnumber = 2\nlength_mm = 20\n[gcode]\n{gcode}"
        );
        Config::from_toml_str_in(&text, "kerf.toml", dir).expect("valid config")
    }

    #[test]
    fn configured_files_are_the_machine_files() {
        let dir = scratch("configured");
        std::fs::write(dir.join("t.tbl"), "T5 P5 Z1 ; probe\n").expect("write");
        let c = config(&dir, "tool_table = \"t.tbl\"\nparameter_file = \"p.var\"\n");
        assert_eq!(c.machine_parameter_file(), dir.join("p.var"));
        assert_eq!(c.machine_tool_table(), dir.join("t.tbl"));
        let t5 = ToolEntry {
            number: 5,
            pocket: 5,
            length_mm: -3.5,
            ..ToolEntry::default()
        };
        c.save_machine_tools(&[t5]).expect("tool 5 is in the file");
        assert_eq!(
            std::fs::read_to_string(dir.join("t.tbl")).expect("read"),
            "T5 P5 Z-3.5 D0 ; probe\n"
        );
        let t1 = ToolEntry {
            number: 1,
            ..ToolEntry::default()
        };
        let e = c
            .save_machine_tools(&[t1])
            .expect_err("tool 1 is in [[tools]]");
        assert!(e.to_string().contains("tool 1 is in `[[tools]]`"), "{e}");
        c.save_machine_parameters(&[(5221, 1.5)]).expect("write");
        assert_eq!(
            c.machine_settings().expect("read").parameters,
            [(5221, 1.5)]
        );
        std::fs::remove_dir_all(&dir).expect("clean up");
    }

    #[test]
    fn the_machine_tool_table_replaces_config_tools_of_the_same_number() {
        let dir = scratch("machine");
        let c = config(&dir, "");
        let table = dir.join("m.tbl");
        assert_eq!(
            c.tools_with_table(&table).expect("no file: [[tools]]"),
            c.tools
        );
        std::fs::write(&table, "T2 P2 Z-7.25 D4\nT9 P9 Z1\n").expect("write");
        let tools = c.tools_with_table(&table).expect("valid");
        let lengths: Vec<(u32, f64)> = tools.iter().map(|t| (t.number, t.length_mm)).collect();
        assert_eq!(lengths, [(1, 10.0), (2, -7.25), (9, 1.0)]);
        std::fs::remove_dir_all(&dir).expect("clean up");
    }
}
