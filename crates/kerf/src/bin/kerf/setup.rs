//! `kerf offset` and `kerf tool`: the work offsets and the tool table of the machine, set
//! from where it stands (touch-off), kept in its parameter file and tool table
//! (`Config::machine_parameter_file`, `Config::machine_tool_table`; docs/MACHINE.md,
//! "Setting up a job").
//!
//! Every value is computed by the interpreter from the state a program starts in on the
//! machine (its parameters, its position, the tool in its spindle): `kerf offset set G54
//! X0` runs LinuxCNC's `G10 L20 P1 X0`, `kerf tool touch-off 3 --z 0` runs `G10 L10 P3
//! Z0`, so the commands and a program that does the same agree to the last bit. The
//! files are written atomically.

use std::io::{self, Write};

use clap::{Args, Subcommand};
use kerf::dro::{Offsets, SYSTEM_NAMES, system_index, system_name};
use kerf_config::Config;
use kerf_gcode::{Dialect, Interpreter, Settings, Tool};
use kerf_proto::StatusMsg;

use crate::machine::{MachineArgs, client_failure, idle_status};
use crate::{Failure, load_config};

#[derive(Args)]
pub struct OffsetArgs {
    #[command(subcommand)]
    command: OffsetCommand,
}

#[derive(Subcommand)]
enum OffsetCommand {
    /// List the work offsets G54 to G59.3 (with their XY rotations), G92 and the active
    /// coordinate system, in mm and degrees, from the machine's parameter file.
    Show(ShowArgs),
    /// Set a work offset so that the machine's current position reads the given
    /// coordinates (LinuxCNC's `G10 L20`; `G92` sets the G92 offset as `G92` does), and
    /// write the parameter file. Refused unless the machine is idle.
    Set(SetArgs),
}

#[derive(Args)]
struct ShowArgs {
    #[command(flatten)]
    machine: MachineArgs,
    /// One JSON object instead of a table for a person.
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
struct SetArgs {
    #[command(flatten)]
    machine: MachineArgs,
    /// The offset: G54, G55, G56, G57, G58, G59, G59.1, G59.2, G59.3 or G92.
    #[arg(value_name = "SYSTEM")]
    system: String,
    /// What the current position reads in it, axis by axis: `X0 Y0 Z12.5` (mm; A, B, C
    /// in degrees). Axes not named keep their offset. (Options may follow them: a word
    /// starting with `-` is an option, never an axis word.)
    #[arg(value_name = "AXIS")]
    words: Vec<String>,
    /// Zero the offset instead (every axis and the rotation; G92: `G92.1`).
    #[arg(long, conflicts_with = "words")]
    clear: bool,
    /// Count the offsets of the tool in the spindle as if G43 were in force (for tool
    /// lengths measured from the spindle's gauge line). Without it the offset is set as
    /// a program reads the position before its G43: without tool offsets.
    #[arg(long)]
    tool_length: bool,
}

#[derive(Args)]
pub struct ToolArgs {
    #[command(subcommand)]
    command: ToolCommand,
}

#[derive(Subcommand)]
enum ToolCommand {
    /// List the machine's tool table.
    Show(ToolShowArgs),
    /// Set tool T's offset so that the current position reads the given value in the
    /// current coordinate system with that tool's offset applied (LinuxCNC's
    /// `G10 L10 P<T>`): with the tool's tip on a surface at Z V, `--z V`. The tool table
    /// file is written; refused unless the machine is idle.
    #[command(name = "touch-off")]
    TouchOff(TouchOffArgs),
}

#[derive(Args)]
struct ToolShowArgs {
    #[command(flatten)]
    machine: MachineArgs,
}

#[derive(Args)]
struct TouchOffArgs {
    #[command(flatten)]
    machine: MachineArgs,
    /// The tool's number.
    #[arg(value_name = "T")]
    tool: u32,
    /// What the current Z reads with the tool's length applied, mm.
    #[arg(long, value_name = "MM", allow_hyphen_values = true)]
    z: Option<f64>,
    /// What the current X reads with the tool's X offset applied, mm (lathes).
    #[arg(long, value_name = "MM", allow_hyphen_values = true)]
    x: Option<f64>,
    /// What the current Y reads with the tool's Y offset applied, mm.
    #[arg(long, value_name = "MM", allow_hyphen_values = true)]
    y: Option<f64>,
}

/// `kerf offset`.
pub fn offset(args: &OffsetArgs) -> Result<(), Failure> {
    match &args.command {
        OffsetCommand::Show(a) => offset_show(a),
        OffsetCommand::Set(a) => offset_set(a),
    }
}

/// `kerf tool`.
pub fn tool(args: &ToolArgs) -> Result<(), Failure> {
    match &args.command {
        ToolCommand::Show(a) => tool_show(a),
        ToolCommand::TouchOff(a) => touch_off(a),
    }
}

fn config_error(e: impl std::fmt::Display) -> Failure {
    Failure::Error(e.to_string())
}

/// The axes the machine has: (letter, index) X Y Z, then A B C where configured.
fn machine_axes(config: &Config) -> Vec<(char, usize)> {
    let rotary = config.axes.rotary();
    ['X', 'Y', 'Z', 'A', 'B', 'C']
        .into_iter()
        .enumerate()
        .filter(|&(i, _)| i < 3 || rotary[i - 3].is_some())
        .map(|(i, c)| (c, i))
        .collect()
}

fn offset_show(args: &ShowArgs) -> Result<(), Failure> {
    let config = load_config(args.machine.config.as_deref())?;
    let offsets = Offsets::read(&config).map_err(config_error)?;
    let axes = machine_axes(&config);
    let file = config.machine_parameter_file();
    let mut out = String::new();
    if args.json {
        let num = |v: f64| format!("{v}");
        let fields = |v: &[f64; 6]| -> String {
            axes.iter()
                .map(|&(c, i)| format!("\"{}\":{}", c.to_ascii_lowercase(), num(v[i])))
                .collect::<Vec<_>>()
                .join(",")
        };
        let systems: Vec<String> = offsets
            .systems
            .iter()
            .zip(SYSTEM_NAMES)
            .map(|(s, name)| {
                format!(
                    "{{\"name\":\"{name}\",{},\"rotation_deg\":{}}}",
                    fields(&s.offset_mm_deg),
                    num(s.rotation_deg)
                )
            })
            .collect();
        out = format!(
            "{{\"parameter_file\":{},\"active\":\"{}\",\"systems\":[{}],\"g92\":{{{},\"applied\":{}}}}}",
            json_string(&file.display().to_string()),
            system_name(Some(offsets.active)),
            systems.join(","),
            fields(&offsets.g92_mm_deg),
            offsets.g92_enabled
        );
    } else {
        let row = |v: &[f64; 6]| -> String {
            axes.iter()
                .map(|&(c, i)| format!("  {c} {:>10.3}", v[i]))
                .collect()
        };
        for (i, s) in offsets.systems.iter().enumerate() {
            let mark = if i == offsets.active { " (active)" } else { "" };
            let name = format!("{}{mark}", SYSTEM_NAMES[i]);
            out.push_str(&format!(
                "{name:<14}{}  rotation {} deg\n",
                row(&s.offset_mm_deg),
                s.rotation_deg
            ));
        }
        let g92 = if offsets.g92_enabled {
            "G92 (applied)"
        } else {
            "G92 (off)"
        };
        out.push_str(&format!(
            "{g92:<14}{}\nparameter file: {}",
            row(&offsets.g92_mm_deg),
            file.display()
        ));
    }
    writeln!(io::stdout().lock(), "{out}")?;
    Ok(())
}

fn json_string(s: &str) -> String {
    let mut out = String::from("\"");
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            c if (c as u32) < 0x20 => out.push_str(&format!("\\u{:04x}", c as u32)),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

/// Parses `X0`, `y-12.5`: the axis's index and the value, for an axis of the machine.
fn axis_word(word: &str, axes: &[(char, usize)]) -> Result<(usize, f64), String> {
    let mut chars = word.chars();
    let letter = chars.next().map(|c| c.to_ascii_uppercase());
    let value: Option<f64> = chars.as_str().parse().ok().filter(|v: &f64| v.is_finite());
    match (letter, value) {
        (Some(l), Some(v)) => match axes.iter().find(|(c, _)| *c == l) {
            Some(&(_, i)) => Ok((i, v)),
            None => Err(format!(
                "`{word}`: the machine has no {l} axis (it has {})",
                axes.iter()
                    .map(|(c, _)| c.to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            )),
        },
        _ => Err(format!(
            "`{word}` is not an axis and a value (such as X0 or Z-12.5)"
        )),
    }
}

/// The machine idle, with the settings a program would start with there: its
/// parameters, tool table, position and the tool in its spindle (MDI input: no
/// program end needed).
fn machine_state(config: &Config) -> Result<(StatusMsg, Settings), Failure> {
    let mut client = kerf::client::Client::connect(&config.machine).map_err(client_failure)?;
    let status = idle_status(&mut client, &config.machine)?;
    crate::machine::require_homed(&status)?;
    let mut settings = config.machine_settings().map_err(config_error)?;
    settings.start_mm_deg = status.position_mm_deg;
    settings.tool_in_spindle = (status.tool_in_spindle != 0).then_some(status.tool_in_spindle);
    settings.mdi = true;
    Ok((status, settings))
}

/// Runs `lines` (LinuxCNC) through the interpreter from `settings`: the interpreter
/// afterwards, or the error of the line that failed. They must not move the machine.
fn run_lines(
    settings: Settings,
    lines: &[String],
) -> Result<Interpreter<io::Cursor<Vec<u8>>>, String> {
    let text = io::Cursor::new(lines.join("\n").into_bytes());
    let mut interp = Interpreter::new(text, Dialect::LinuxCnc, settings);
    for item in interp.by_ref() {
        match item {
            Ok(kerf_gcode::Item::Move(m)) => {
                return Err(format!(
                    "`{}` would move the machine",
                    lines[m.line as usize - 1]
                ));
            }
            Ok(_) => {}
            Err(d) => {
                let line = lines.get(d.line as usize - 1).map_or("", String::as_str);
                return Err(format!("`{line}`: {}", d.message));
            }
        }
    }
    Ok(interp)
}

/// A value for G-code text: the shortest form that reads back as `v`.
fn gcode_number(v: f64) -> String {
    format!("{v}")
}

fn offset_set(args: &SetArgs) -> Result<(), Failure> {
    let config = load_config(args.machine.config.as_deref())?;
    let axes = machine_axes(&config);
    let fail = |m: String| Failure::Error(format!("kerf: error: {m}"));
    let g92 = args.system.eq_ignore_ascii_case("G92");
    let index = system_index(&args.system);
    if !g92 && index.is_none() {
        return Err(fail(format!(
            "`{}` is not a work offset: say G54, G55, G56, G57, G58, G59, G59.1, G59.2, G59.3 or G92",
            args.system
        )));
    }
    let mut words: Vec<(usize, f64)> = Vec::new();
    for w in &args.words {
        let (i, v) = axis_word(w, &axes).map_err(&fail)?;
        if words.iter().any(|&(j, _)| j == i) {
            return Err(fail(format!(
                "axis {} given twice",
                &w[..1].to_ascii_uppercase()
            )));
        }
        words.push((i, v));
    }
    if words.is_empty() && !args.clear {
        return Err(fail(
            "say what the current position reads (such as X0 Y0 Z0), or --clear".to_string(),
        ));
    }
    let (status, settings) = machine_state(&config)?;
    let letters = ['X', 'Y', 'Z', 'A', 'B', 'C'];
    let axis_text: String = words
        .iter()
        .map(|&(i, v)| format!(" {}{}", letters[i], gcode_number(v)))
        .collect();
    let p = index.map_or(0, |i| i + 1);
    let block = match (g92, args.clear) {
        (true, true) => "G92.1".to_string(),
        (true, false) => format!("G92{axis_text}"),
        (false, true) => {
            let zeros: String = axes.iter().map(|(c, _)| format!(" {c}0")).collect();
            format!("G10 L2 P{p}{zeros} R0")
        }
        (false, false) => format!("G10 L20 P{p}{axis_text}"),
    };
    let mut lines = Vec::new();
    let tool = status.tool_in_spindle;
    if args.tool_length && tool != 0 {
        if !settings.tools.iter().any(|t| t.number == tool) {
            return Err(fail(format!(
                "--tool-length: the tool in the spindle, T{tool}, is not in the machine's tool table"
            )));
        }
        lines.push("G43".to_string());
    }
    lines.push(block);
    let interp = run_lines(settings, &lines).map_err(&fail)?;
    let file = config
        .save_machine_parameters(&interp.persistent_parameters())
        .map_err(|e| {
            Failure::Error(format!(
                "{}: error: cannot write the parameter file: {e}",
                config.machine_parameter_file().display()
            ))
        })?;
    let offsets = Offsets::from_parameters(&interp.persistent_parameters());
    let (name, values) = if g92 {
        ("G92", offsets.g92_mm_deg)
    } else {
        let i = index.unwrap_or(0);
        (SYSTEM_NAMES[i], offsets.systems[i].offset_mm_deg)
    };
    let shown: String = axes
        .iter()
        .map(|&(c, i)| format!(" {c} {:.4}", values[i]))
        .collect();
    writeln!(
        io::stdout().lock(),
        "{name} offset:{shown} (`{}`; written to {})",
        lines.join("; "),
        file.display()
    )?;
    Ok(())
}

fn tool_show(args: &ToolShowArgs) -> Result<(), Failure> {
    let config = load_config(args.machine.config.as_deref())?;
    let mut tools = config.machine_tools().map_err(config_error)?;
    tools.sort_by_key(|t| t.number);
    let mut out = io::stdout().lock();
    if tools.is_empty() {
        writeln!(out, "no tools")?;
    }
    for t in &tools {
        writeln!(out, "{}", kerf_config::tooltable::tool_table_line(t))?;
    }
    writeln!(
        out,
        "; [[tools]] of the configuration{} ({})",
        if config.tool_table.is_some() {
            " and its tool table"
        } else {
            ", replaced tool by tool by the machine's tool table"
        },
        config.machine_tool_table().display()
    )?;
    Ok(())
}

fn touch_off(args: &TouchOffArgs) -> Result<(), Failure> {
    let fail = |m: String| Failure::Error(format!("kerf: error: {m}"));
    let words: Vec<(char, f64)> = [('X', args.x), ('Y', args.y), ('Z', args.z)]
        .into_iter()
        .filter_map(|(c, v)| v.map(|v| (c, v)))
        .collect();
    if words.is_empty() {
        return Err(fail(
            "say what the current position reads with the tool, such as --z 0".to_string(),
        ));
    }
    if let Some((c, _)) = words.iter().find(|(_, v)| !v.is_finite()) {
        return Err(fail(format!(
            "--{} must be a number",
            c.to_ascii_lowercase()
        )));
    }
    let config = load_config(args.machine.config.as_deref())?;
    let (_status, settings) = machine_state(&config)?;
    let t = args.tool;
    if t == 0 || !settings.tools.iter().any(|e| e.number == t) {
        return Err(fail(format!(
            "tool {t} is not in the machine's tool table ({}): add it there or to `[[tools]]` first",
            config.machine_tool_table().display()
        )));
    }
    let axis_text: String = words
        .iter()
        .map(|&(c, v)| format!(" {c}{}", gcode_number(v)))
        .collect();
    let line = format!("G10 L10 P{t}{axis_text}");
    let interp = run_lines(settings, std::slice::from_ref(&line)).map_err(&fail)?;
    let entry: Tool = interp
        .tools()
        .iter()
        .find(|e| e.number == t)
        .copied()
        .ok_or_else(|| fail(format!("tool {t} vanished from the table")))?;
    let file = config
        .save_machine_tools(&[entry])
        .map_err(|e| Failure::Error(e.to_string()))?;
    writeln!(
        io::stdout().lock(),
        "tool {t}: {} (`{line}`; written to {})",
        kerf_config::tooltable::tool_table_line(&entry),
        file.display()
    )?;
    Ok(())
}
