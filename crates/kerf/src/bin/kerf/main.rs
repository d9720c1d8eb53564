//! The `kerf` command: argument parsing, files, error messages and exit codes.
//!
//! Exit codes: 0 on success (and when the reader of our standard output goes away, as other
//! Unix filters do), 2 on any error. Every error is one line on standard error in the form
//! `FILE:LINE:COL: error: MESSAGE` or `FILE: error: MESSAGE`, in a program sometimes
//! followed by `note:` lines (the subroutine calls that led there; the dialect, when it was
//! assumed by default).
#![forbid(unsafe_code)]

use std::ffi::OsStr;
use std::fs::File;
use std::io::{self, BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use clap::{Args, CommandFactory, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressFinish, ProgressStyle};
use kerf::sim::{Prepass, PrepassError, SimError, SimOptions};
use kerf::{DialectSource, PlanOutputError, assumed_dialect_note, choose_dialect_from};
use kerf_config::Config;
use kerf_gcode::{Dialect, Interpreter, Item};
use kerf_pipeline::ProgramActions;

mod ethercat;
mod from_line;
mod machine;
mod manual;
mod mdi;
mod output;
mod serve;
mod setup;

use output::Output;

/// Read buffer for program files: large enough that a 1 GB program costs few system calls,
/// small enough to keep the resident set tiny.
const READ_BUFFER_BYTES: usize = 256 * 1024;

#[derive(Parser)]
#[command(
    name = "kerf",
    version,
    about = "Kerf CNC trajectory interpolator tools"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Resolve a G-code program and print every move and event as one JSON object per line.
    Plan(PlanArgs),
    /// Run a program through the planner and motion core in virtual time and write the
    /// setpoints of every period as CSV.
    Sim(SimArgs),
    /// Check a program, then stream it to the machine's daemon and wait until it has
    /// finished moving.
    Run(machine::RunArgs),
    /// Print the daemon's status.
    Status(machine::StatusArgs),
    /// Run G-code lines typed by hand on the machine, each to its end, in the machine's
    /// state (its offsets, tool and position): one LINE, or a session reading lines.
    Mdi(mdi::MdiArgs),
    /// Show the work offsets, or set one from where the machine stands (touch-off).
    Offset(setup::OffsetArgs),
    /// Show the tool table, or set a tool's length from where the machine stands
    /// (touch-off).
    Tool(setup::ToolArgs),
    /// Feed hold: a jerk-limited stop on the path.
    Hold(machine::MachineArgs),
    /// Cycle start: resume after a hold, or go on after a pause that waits for the
    /// operator (M0, M1, M60, a manual tool change, single block).
    Resume(machine::MachineArgs),
    /// The optional-stop switch: while on, M1 pauses the program like M0.
    #[command(name = "optional-stop")]
    OptionalStop(machine::SwitchArgs),
    /// The single-block switch: while on, the program pauses after every block (blocks
    /// the daemon plans from now on; `kerf resume` runs the next).
    #[command(name = "single-block")]
    SingleBlock(machine::SwitchArgs),
    /// The block-delete switch: while on, programs sent from now on skip the lines that
    /// start with `/`.
    #[command(name = "block-delete")]
    BlockDelete(machine::SwitchArgs),
    /// Set the spindle override, 0 to 200 percent (it applies while enabled: M48, M51).
    #[command(name = "spindle-override")]
    SpindleOverride(machine::SpindleOverrideArgs),
    /// Set a simulated input (the machine's own inputs are set by its wiring): `kerf input
    /// 3 on`, `kerf input 0 --analog 2.5`.
    Input(machine::InputArgs),
    /// Stop on the path and drop the rest of the program (and any jog or homing).
    Abort(machine::MachineArgs),
    /// Jog an axis by hand: `kerf jog X+` moves while the command runs (Ctrl-C stops it;
    /// `--for S` after S seconds), `kerf jog X --step 0.1`, `kerf jog X --to 12.5`.
    Jog(manual::JogArgs),
    /// Home axes (`kerf home Z`, `kerf home --all`) in the configured home sequence, with
    /// the progress on standard error.
    Home(manual::HomeArgs),
    /// Set the feed override, 0 to 200 percent.
    Override(machine::OverrideArgs),
    /// Write the daemon's setpoint stream to CSV.
    Record(machine::RecordArgs),
    /// Serve the machine's web page and JSON API (docs/API.md): watching for everybody,
    /// control with the configured token.
    Serve(serve::ServeArgs),
    /// Clear the drive side's latched fault once its cause is gone (refused, with the
    /// reason, while it persists).
    Reset(machine::MachineArgs),
    /// Write the daemon's black box (the last seconds of every cycle: commanded and actual
    /// positions, following errors, drive words) to CSV.
    Dump(machine::DumpArgs),
    /// Commission the EtherCAT bus without the daemon: scan it, read and write SDOs.
    Ethercat(ethercat::EthercatArgs),
    /// Draw a black-box file (from `kerf dump`, or the one written at a fault) as SVG: per
    /// axis the commanded against the actual position and the following error over time.
    Plot(PlotArgs),
    /// Print the shell completion script of `kerf` (bash, zsh or fish) on standard output
    /// (for packaging: `kerf completions bash > /usr/share/bash-completion/completions/kerf`).
    #[command(hide = true)]
    Completions {
        /// The shell.
        #[arg(value_name = "SHELL")]
        shell: kerf::clidoc::Shell,
    },
    /// Write the man pages of `kerf`, each of its subcommands (`kerf.1`, `kerf-plan.1`,
    /// ...) and the daemon (`kerfd.1`) into DIR (for packaging).
    #[command(hide = true)]
    Man {
        /// The directory, created when missing.
        #[arg(value_name = "DIR")]
        dir: PathBuf,
    },
}

#[derive(Args)]
struct PlotArgs {
    /// The black-box CSV.
    #[arg(value_name = "FILE.csv")]
    input: PathBuf,
    /// Where to write the SVG; `-` writes it to standard output.
    #[arg(long, value_name = "FILE.svg")]
    out: PathBuf,
}

/// The program and how to read it: shared by every subcommand.
#[derive(Args)]
pub struct ProgramArgs {
    /// The program's dialect: linuxcnc (alias tormach), rockwell, sinumerik, heidenhain or
    /// fagor. Without it: the file extension where unambiguous, then the config's
    /// `dialect`, then linuxcnc.
    #[arg(long, value_name = "D", value_parser = parse_dialect)]
    dialect: Option<Dialect>,
    /// Machine configuration (TOML). Without it: /etc/kerf/kerf.toml if present, else the
    /// bundled config/kerf.toml.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// The G-code program; `-` reads standard input.
    #[arg(value_name = "PROGRAM")]
    program: PathBuf,
}

#[derive(Args)]
struct PlanArgs {
    #[command(flatten)]
    program: ProgramArgs,
}

#[derive(Args)]
struct SimArgs {
    #[command(flatten)]
    program: ProgramArgs,
    /// Feed override in percent, 0.1 to 200 (0 would hold the machine forever).
    #[arg(
        long = "override",
        value_name = "PCT",
        default_value_t = 100.0,
        value_parser = parse_override,
        allow_hyphen_values = true
    )]
    override_pct: f64,
    /// Where to write the CSV: `t,x,y,z` (then `a,b,c` when used), `line`, `feed_mm_s`.
    #[arg(long, value_name = "FILE.csv")]
    out: PathBuf,
    /// Also draw the toolpath (XY, XZ, YZ; rapids in orange), the feed, and each axis's
    /// velocity, acceleration and jerk against its limits over time: an SVG or PNG image by
    /// the extension (`-`: SVG on standard output).
    #[arg(long, value_name = "FILE.svg|FILE.png")]
    plot: Option<PathBuf>,
}

/// The smallest feed override accepted, percent. Below it a simulation runs for more than a
/// thousand times the program's own time, and a tiny value such as 1e-300 would never end.
const MIN_OVERRIDE_PCT: f64 = 0.1;

/// The largest feed override accepted, percent (the machine's, as the daemon takes it).
const MAX_OVERRIDE_PCT: f64 = kerf_proto::MAX_OVERRIDE_PCT;

/// A feed override in percent, [`MIN_OVERRIDE_PCT`] to [`MAX_OVERRIDE_PCT`] (a trailing `%`
/// is allowed).
///
/// A control at 0 % feed override holds: it does not move. Offline, that simulation could
/// never reach the end of the program, so 0 is refused before anything runs rather than
/// reported as a finished run that never moved.
fn parse_override(text: &str) -> Result<f64, String> {
    match text.trim_end_matches('%').parse::<f64>() {
        Ok(pct) if (MIN_OVERRIDE_PCT..=MAX_OVERRIDE_PCT).contains(&pct) => Ok(pct),
        Ok(0.0) => Err(format!(
            "--override 0 would hold the machine before the first move; the simulation could never finish (use {MIN_OVERRIDE_PCT} to {MAX_OVERRIDE_PCT})"
        )),
        _ => Err(format!(
            "`{text}` is not a feed override: it must be {MIN_OVERRIDE_PCT} to {MAX_OVERRIDE_PCT} percent"
        )),
    }
}

pub(crate) fn parse_dialect(name: &str) -> Result<Dialect, String> {
    Dialect::from_name(name).ok_or_else(|| {
        let known: Vec<&str> = Dialect::ALL.iter().map(|d| d.name()).collect();
        format!(
            "unknown dialect `{name}`, expected one of: {} (or tormach)",
            known.join(", ")
        )
    })
}

/// How a command ended when it did not succeed.
pub enum Failure {
    /// Print this line on standard error and exit with status 2.
    Error(String),
    /// Print this line on standard error and exit with this status (1: no daemon answers,
    /// or it stopped).
    Exit(u8, String),
    /// The reader of standard output went away: stop quietly.
    BrokenPipe,
}

impl From<io::Error> for Failure {
    fn from(e: io::Error) -> Self {
        if e.kind() == io::ErrorKind::BrokenPipe {
            Failure::BrokenPipe
        } else {
            Failure::Error(format!("<stdout>: error: {e}"))
        }
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Plan(args) => run_plan(&args),
        Command::Sim(args) => run_sim(&args),
        Command::Run(args) => machine::run(&args),
        Command::Status(args) => machine::status(&args),
        Command::Mdi(args) => mdi::run(&args),
        Command::Offset(args) => setup::offset(&args),
        Command::Tool(args) => setup::tool(&args),
        Command::Hold(args) => machine::command(&args, kerf_proto::ControlCommand::Hold),
        Command::Resume(args) => machine::command(&args, kerf_proto::ControlCommand::Resume),
        Command::OptionalStop(args) => machine::switch(&args, kerf_proto::Switch::OptionalStop),
        Command::SingleBlock(args) => machine::switch(&args, kerf_proto::Switch::SingleBlock),
        Command::BlockDelete(args) => machine::switch(&args, kerf_proto::Switch::BlockDelete),
        Command::SpindleOverride(args) => machine::command(
            &args.machine,
            kerf_proto::ControlCommand::SpindleOverride {
                percent: args.percent,
            },
        ),
        Command::Input(args) => machine::input(&args),
        Command::Abort(args) => machine::command(&args, kerf_proto::ControlCommand::Abort),
        Command::Jog(args) => manual::jog(&args),
        Command::Home(args) => manual::home(&args),
        Command::Override(args) => machine::command(
            &args.machine,
            kerf_proto::ControlCommand::Override {
                percent: args.percent,
            },
        ),
        Command::Record(args) => machine::record(&args),
        Command::Serve(args) => serve::run(&args),
        Command::Reset(args) => machine::reset(&args),
        Command::Dump(args) => machine::dump(&args),
        Command::Plot(args) => run_plot(&args),
        Command::Ethercat(args) => ethercat::run(&args),
        Command::Completions { shell } => {
            let mut out = Vec::new();
            kerf::clidoc::write_completions(Cli::command(), shell, &mut out);
            io::stdout().lock().write_all(&out).map_err(Failure::from)
        }
        Command::Man { dir } => kerf::clidoc::write_man_pages(Cli::command(), &dir)
            .and_then(|_| kerf::clidoc::write_man_pages(kerfd::cli::Args::command(), &dir))
            .map(|_| ())
            .map_err(|e| Failure::Error(format!("{}: error: {e}", dir.display()))),
    };
    match result {
        Ok(()) | Err(Failure::BrokenPipe) => ExitCode::SUCCESS,
        Err(Failure::Error(message)) => {
            // Standard error may be closed too; there is nobody left to tell then.
            let _ = writeln!(io::stderr().lock(), "{message}");
            ExitCode::from(2)
        }
        Err(Failure::Exit(code, message)) => {
            let _ = writeln!(io::stderr().lock(), "{message}");
            ExitCode::from(code)
        }
    }
}

/// The machine configuration: `path`, else the system's, else the built-in example.
pub fn load_config(path: Option<&Path>) -> Result<Config, Failure> {
    let (mut config, origin) =
        kerf_config::load_default(path).map_err(|e| Failure::Error(e.to_string()))?;
    // The bundled example names LinuxCNC, the default anyway: nobody chose it for this
    // machine, so a program that fails in it gets the note on how to choose another.
    if origin == kerf_config::BUILTIN_ORIGIN && config.dialect == Some(Dialect::LinuxCnc) {
        config.dialect = None;
    }
    Ok(config)
}

/// The interpreter settings of `kerf plan` and `kerf sim`: the configuration's, with the
/// numbered parameters of `gcode.parameter_file` restored (the files the configuration
/// names only; `kerf run` and `kerf mdi` use the machine's, `Config::machine_settings`).
pub fn program_settings(config: &Config) -> Result<kerf_gcode::Settings, Failure> {
    config
        .program_settings()
        .map_err(|e| Failure::Error(e.to_string()))
}

/// An opened program: its reader, the name errors use, and its dialect.
struct Program {
    reader: Box<dyn BufRead + Send>,
    name: String,
    dialect: Dialect,
    /// The dialect was nobody's choice (see [`with_dialect_note`]).
    assumed: bool,
    /// The program's file (`None` for standard input): LinuxCNC subroutine files are
    /// looked for in its directory first.
    path: Option<PathBuf>,
}

/// `settings` with the program's directory first on the LinuxCNC subroutine search path,
/// where LinuxCNC's interpreter finds `NAME.ngc` files next to the program.
pub(crate) fn settings_for(
    mut settings: kerf_gcode::Settings,
    program: &Path,
) -> kerf_gcode::Settings {
    if program.as_os_str() != OsStr::new("-") {
        let dir = program
            .parent()
            .filter(|d| !d.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        settings.subroutine_path.insert(0, dir.to_path_buf());
        if program.is_file() {
            // Read again for subs called before their definition (never a pipe).
            settings.program_file = Some(program.to_path_buf());
        }
    }
    settings
}

fn open_program(args: &ProgramArgs, config: &Config) -> Result<Program, Failure> {
    if args.program.as_os_str() == OsStr::new("-") {
        // `Stdin` rather than its lock: the interpreter may run on its own thread.
        let reader = BufReader::with_capacity(READ_BUFFER_BYTES, io::stdin());
        let (dialect, source) = choose_dialect_from(args.dialect, None, config.dialect);
        return Ok(Program {
            reader: Box::new(reader),
            name: "<stdin>".to_string(),
            dialect,
            assumed: source == DialectSource::Default,
            path: None,
        });
    }
    let name = args.program.display().to_string();
    let cannot_read =
        |e: io::Error| Failure::Error(format!("{name}: error: cannot read program: {e}"));
    let file = File::open(&args.program).map_err(cannot_read)?;
    let mut reader = BufReader::with_capacity(READ_BUFFER_BYTES, file);
    // The first bytes tell an ISO Heidenhain `.h` file from a conversational one; peeking
    // at the buffer leaves them in place for the interpreter.
    let (dialect, source) = {
        let head = reader.fill_buf().map_err(cannot_read)?;
        choose_dialect_from(args.dialect, Some((&args.program, head)), config.dialect)
    };
    Ok(Program {
        reader: Box::new(reader),
        name,
        dialect,
        assumed: source == DialectSource::Default,
        path: Some(args.program.clone()),
    })
}

fn run_plot(args: &PlotArgs) -> Result<(), Failure> {
    let name = args.input.display().to_string();
    let file =
        File::open(&args.input).map_err(|e| Failure::Error(format!("{name}: error: {e}")))?;
    let bb = kerf::blackbox::read(BufReader::new(file))
        .map_err(|e| Failure::Error(format!("{name}:{}: error: {}", e.line, e.message)))?;
    let mut out = Output::create(&args.out)?;
    kerf::blackbox::write_svg(&bb, &mut out).map_err(|e| out.error(e))?;
    out.commit()
}

fn run_plan(args: &PlanArgs) -> Result<(), Failure> {
    let config = load_config(args.program.config.as_deref())?;
    let program = open_program(&args.program, &config)?;
    let stdout = io::stdout().lock();
    let settings = program_settings(&config)?;
    let settings = match &program.path {
        Some(path) => settings_for(settings, path),
        None => settings,
    };
    match kerf::plan_counted(program.reader, stdout, program.dialect, settings) {
        Ok(written) if written.moves == 0 => {
            // Standard output stays JSON lines only.
            writeln!(io::stderr().lock(), "note: no motion in {}", program.name)?;
            Ok(())
        }
        Ok(_) => Ok(()),
        Err(PlanOutputError::Output(e)) => Err(e.into()),
        // A LinuxCNC subroutine error names its file and the calls that led there.
        Err(PlanOutputError::Program(d)) => Err(Failure::Error(with_dialect_note(
            d.render(&program.name),
            program.dialect,
            program.assumed,
        ))),
        // These carry their own `LINE:COL: error: ...`.
        Err(e @ PlanOutputError::NonFinite { .. }) => {
            Err(Failure::Error(format!("{}:{e}", program.name)))
        }
        Err(e) => Err(Failure::Error(format!("{}: error: {e}", program.name))),
    }
}

fn run_sim(args: &SimArgs) -> Result<(), Failure> {
    let plot_format = match &args.plot {
        Some(path) => Some(
            kerf::sim_plot::PlotFormat::of_path(path)
                .map_err(|e| Failure::Error(format!("{}: error: {e}", path.display())))?,
        ),
        None => None,
    };
    let config = load_config(args.program.config.as_deref())?;
    let source = SimSource::open(&args.program, &config)?;
    let name = &source.name;
    let options = SimOptions {
        feed_override: args.override_pct / 100.0,
        // The daemon's lookahead window: the same setpoints as `kerfd` on this machine.
        queue_capacity: config.daemon.queue_segments as usize,
        ..SimOptions::default()
    };

    // Pass 1: the whole program is resolved, planned and checked against the travel
    // limits (the programmed moves and the planned path) before the first setpoint: a
    // program that would leave the machine's travel never starts.
    let settings = settings_for(program_settings(&config)?, &args.program.program);
    let (checked, _) = check_program(&source, &config, settings.clone(), &options, false, false)?;
    let scan = checked.scan;

    if args.plot.as_deref().is_some_and(output::is_stdout) && output::is_stdout(&args.out) {
        return Err(Failure::Error(
            "kerf: error: --out - and --plot - cannot both write to standard output".to_string(),
        ));
    }
    // Both are written beside their targets and renamed there only when the run succeeds.
    let file = Output::create(&args.out)?;
    let mut plot = match &args.plot {
        Some(path) => Some(Output::create(path)?),
        None => None,
    };
    // An output error is in the CSV or in the plot; both names are given when there are two.
    let outputs = match &plot {
        Some(plot) => format!("{}, {}", file.name, plot.name),
        None => file.name.clone(),
    };
    let mut out = ProgressWriter::new(file, scan.estimated_rows(&config));

    // Pass 2: the run. A program small enough was kept by pass 1, moves and planned
    // segments; a larger one is read again and streamed into the run. Those are the moves
    // pass 1 checked unless the file changed in between, which stops the run.
    let axes = config.axes;
    let changed = AtomicBool::new(false);
    let mut seen = scan.moves;
    let plot_out = plot
        .as_mut()
        .zip(plot_format)
        .map(|(w, format)| kerf::sim_plot::PlotOutput {
            format,
            out: w,
            title: name.clone(),
        });
    let result = match checked.kept {
        Some(kept) => kerf::sim::simulate_kept(kept, &scan, &config, &options, &mut out, plot_out),
        None => {
            seen = 0;
            let mut actions = ProgramActions::new();
            let moves = Interpreter::new(source.reader()?, source.dialect, settings)
                .map_while(|item| match item {
                    Ok(Item::Move(m)) => {
                        seen += 1;
                        if seen > scan.moves || kerf_config::travel::check_move(&m, &axes).is_err()
                        {
                            changed.store(true, Ordering::Relaxed);
                            return None;
                        }
                        Some(actions.item(&Item::Move(m)))
                    }
                    Ok(item) => Some(actions.item(&item)),
                    Err(_) => {
                        changed.store(true, Ordering::Relaxed);
                        None
                    }
                })
                .flatten()
                .flatten();
            kerf::sim::simulate_stream(
                moves,
                scan.rotary_used,
                &config,
                &options,
                &mut out,
                plot_out,
            )
        }
    };
    out.finish();
    let changed = changed.load(Ordering::Relaxed) || (result.is_ok() && seen != scan.moves);
    let summary = match result {
        Ok(_) | Err(SimError::Fault { .. }) if changed => {
            return Err(Failure::Error(format!(
                "{name}: error: {}",
                SimError::Changed
            )));
        }
        Ok(summary) => summary,
        Err(SimError::Io(e)) if e.kind() == io::ErrorKind::BrokenPipe => {
            return Err(Failure::BrokenPipe);
        }
        Err(SimError::Io(e)) => return Err(Failure::Error(format!("{outputs}: error: {e}"))),
        // The CSV up to and including the setpoint that broke the limit is the diagnosis:
        // it replaces the target (the plot does not).
        Err(e @ SimError::Fault { .. }) => {
            out.inner.commit()?;
            return Err(Failure::Error(format!("{name}: error: {e}")));
        }
        Err(e) => return Err(Failure::Error(format!("{name}: error: {e}"))),
    };
    // Exit 0 means the program ran to its end: the last setpoint is its end point.
    scan.check_end(&summary.raw.last.position)
        .map_err(|e| Failure::Error(format!("{name}: error: {e}")))?;
    let csv_to_stdout = out.inner.is_stdout() || plot.as_ref().is_some_and(Output::is_stdout);
    out.inner.commit()?;
    if let Some(plot) = plot {
        plot.commit()?;
    }
    if scan.moves == 0 {
        writeln!(io::stderr().lock(), "note: no motion in {name}")?;
    }
    // Standard output carries the CSV with `--out -` (the plot with `--plot -`): the
    // summary goes to standard error.
    if csv_to_stdout {
        writeln!(io::stderr().lock(), "{summary}")?;
    } else {
        writeln!(io::stdout().lock(), "{summary}")?;
    }
    Ok(())
}

/// `error` (a program's error, `FILE:LINE:COL: error: ...` first) with a second line
/// saying which dialect was assumed and how to choose another, when nobody chose it (not
/// `--dialect`, not the file's extension, not the configuration's `dialect`).
fn with_dialect_note(error: String, dialect: Dialect, assumed: bool) -> String {
    if assumed {
        format!("{error}\n{}", assumed_dialect_note(dialect))
    } else {
        error
    }
}

/// Pass 1 of `kerf sim` and `kerf run`: the whole program is resolved with `settings`
/// and checked against the travel limits (the programmed moves and the planned path).
/// Returns what the check kept and the last source line with a move or event.
///
/// With `machine_inputs` (`kerf run`), the inputs an `M66` waits on are the machine's:
/// the check ends at the first line that reads `#5399` after an `M66` (what follows
/// depends on the input's value, which only the machine knows), and the scan says so
/// ([`kerf::sim::Scan::checked_to_line`]).
///
/// Without `quick` (`kerf sim`) every move is planned and every planned segment checked
/// (and a small program's segments are kept for the run). With `quick` (`kerf run`) the
/// program is first read without planning ([`kerf::sim::QuickCheck`]: the exact path of
/// every move, and which moves come within twice the tolerance of an edge); only if some
/// do is it read again and planned, up to where the planned path has passed the last of
/// them. The guarantee is the same (no part of the planned path leaves the travel), and a
/// program that stays clear of the edges starts at the speed of reading it.
pub fn check_program(
    source: &SimSource,
    config: &Config,
    settings: kerf_gcode::Settings,
    options: &SimOptions,
    machine_inputs: bool,
    quick: bool,
) -> Result<(kerf::sim::Checked, u32), Failure> {
    let name = &source.name;
    let refused = |e: PrepassError| match e.line() {
        Some(line) => Failure::Error(format!("{name}:{line}:1: error: {e}")),
        None => Failure::Error(format!("{name}: error: {e}")),
    };
    if !quick {
        let mut prepass = Prepass::new(config, options);
        let mut actions = ProgramActions::new();
        let walked = walk(
            source,
            config,
            settings,
            machine_inputs,
            "checking the program",
            |item| {
                plan_item(&mut prepass, &mut actions, item).map_err(refused)?;
                Ok(true)
            },
        )?;
        let mut checked = prepass.finish().map_err(refused)?;
        checked.scan.checked_to_line = walked.checked_to;
        return Ok((checked, walked.last_line));
    }

    // The quick pass: no planning.
    let mut quick_check = kerf::sim::QuickCheck::new(config);
    let walked = walk(
        source,
        config,
        settings.clone(),
        machine_inputs,
        "checking the program",
        |item| {
            if let Walked::Move(m) = item {
                quick_check.push(m).map_err(refused)?;
            }
            Ok(true)
        },
    )?;
    let mut scan = quick_check.scan();
    scan.checked_to_line = walked.checked_to;
    if let Some((last_near, line)) = quick_check.last_near() {
        // The planned path near the edges: planned and checked exactly, from the start
        // (the planner is deterministic: these are the segments the run will plan) until
        // it has passed the last move near an edge.
        let mut prepass = Prepass::new(config, options);
        let mut actions = ProgramActions::new();
        let mut passed = false;
        let label =
            format!("checking the planned path near the edge of the travel (to line {line})");
        walk(source, config, settings, machine_inputs, &label, |item| {
            plan_item(&mut prepass, &mut actions, item).map_err(refused)?;
            passed = prepass.has_passed(last_near);
            Ok(!passed)
        })?;
        if !passed {
            prepass.finish().map_err(refused)?;
        }
    }
    Ok((kerf::sim::Checked { scan, kept: None }, walked.last_line))
}

/// Hands one item of the walk to the planned check: a move after the stop or wait the
/// program's actions put before it, an event as the input it makes, if any.
fn plan_item(
    prepass: &mut Prepass,
    actions: &mut ProgramActions,
    item: Walked<'_>,
) -> Result<(), PrepassError> {
    match item {
        Walked::Move(m) => {
            if let Some(wait) = actions.before_move(m) {
                prepass.input(&wait)?;
            }
            prepass.push(m)
        }
        Walked::Event(e) => match actions.event(e) {
            Some(input) => prepass.input(&input),
            None => Ok(()),
        },
    }
}

/// An item of the program for [`walk`]'s callback.
enum Walked<'a> {
    Move(&'a kerf_geom::Move),
    Event(&'a kerf_gcode::Event),
}

/// What [`walk`] saw.
struct WalkEnd {
    /// The last source line with a move or event.
    last_line: u32,
    /// The line the walk stopped at because the program reads a machine input there.
    checked_to: Option<u32>,
}

/// Reads the program of `source` with `settings` and hands every move and event to
/// `each` (which returns `false` to stop early), after checking each event against what
/// the machine has. A program error ends the walk with its message; with
/// `machine_inputs`, the first read of `#5399` after an `M66` ends it quietly (see
/// [`check_program`]). A long walk shows a spinner labelled `label` on a terminal.
fn walk(
    source: &SimSource,
    config: &Config,
    settings: kerf_gcode::Settings,
    machine_inputs: bool,
    label: &str,
    mut each: impl FnMut(Walked<'_>) -> Result<bool, Failure>,
) -> Result<WalkEnd, Failure> {
    let name = &source.name;
    let started = Instant::now();
    let mut spinner: Option<ProgressBar> = None;
    let mut moves = 0u64;
    let mut last_line = 0;
    let caps = config.machine_check();
    let mut interpreter = Interpreter::new(source.reader()?, source.dialect, settings);
    let read_input = Arc::new(AtomicBool::new(false));
    if machine_inputs {
        interpreter.set_input_wait(Box::new(StopAtInput(read_input.clone())));
    }
    let mut checked_to = None;
    for item in interpreter {
        let go_on = match item {
            Ok(Item::Move(m)) => {
                last_line = m.line;
                moves += 1;
                // A long program takes a while to check: say so on a terminal.
                if moves.is_multiple_of(16384) && started.elapsed() > PROGRESS_AFTER {
                    let bar = spinner.get_or_insert_with(|| {
                        // Cleared when dropped, also when the check fails.
                        let bar = ProgressBar::new_spinner().with_finish(ProgressFinish::AndClear);
                        if let Ok(style) = ProgressStyle::with_template(&format!(
                            "{label} {{spinner}} {{pos}} moves, {{elapsed}}"
                        )) {
                            bar.set_style(style);
                        }
                        bar
                    });
                    bar.set_position(moves);
                }
                each(Walked::Move(&m))?
            }
            Ok(Item::Event(e)) => {
                last_line = e.line;
                caps.check_event(&e)
                    .map_err(|why| Failure::Error(format!("{name}:{}:1: error: {why}", e.line)))?;
                each(Walked::Event(&e))?
            }
            Err(d) if read_input.load(Ordering::Acquire) => {
                // The program reads an input here: the check covers what comes before.
                checked_to = Some(d.line);
                break;
            }
            Err(diagnostic) => {
                return Err(Failure::Error(with_dialect_note(
                    diagnostic.render(name),
                    source.dialect,
                    source.assumed_dialect,
                )));
            }
        };
        if !go_on {
            break;
        }
    }
    if let Some(bar) = spinner {
        bar.finish_and_clear();
    }
    Ok(WalkEnd {
        last_line,
        checked_to,
    })
}

/// The input wait of pass 1 in `kerf run`: the machine's inputs are not known before the
/// program runs, so the first read of `#5399` after an `M66` ends the check there.
struct StopAtInput(Arc<AtomicBool>);

impl kerf_gcode::InputWait for StopAtInput {
    fn wait(&mut self, _event: &kerf_gcode::Event) -> Result<f64, String> {
        self.0.store(true, Ordering::Release);
        Err("the input's value is the machine's: the check before motion ends here".to_string())
    }
}

/// The program of `kerf sim`, which may be read twice (a checking pass, then the run): a
/// file is opened again; standard input, pipes and devices are first copied to a temporary
/// file (removed when this is dropped), so that memory does not grow with the program.
pub struct SimSource {
    path: PathBuf,
    /// The program's name in messages (its path, or `stdin`).
    pub name: String,
    /// The dialect it is read in.
    pub dialect: Dialect,
    /// The dialect was nobody's choice (see [`with_dialect_note`]).
    pub assumed_dialect: bool,
    /// The spooled standard input, removed on drop.
    spool: Option<PathBuf>,
}

impl SimSource {
    /// Opens the program `args` names, in the dialect they and `config` choose.
    pub fn open(args: &ProgramArgs, config: &Config) -> Result<SimSource, Failure> {
        if args.program.as_os_str() == OsStr::new("-") {
            let name = "<stdin>".to_string();
            let path = spool(&name, &mut io::stdin().lock())?;
            let (dialect, source) = choose_dialect_from(args.dialect, None, config.dialect);
            return Ok(SimSource {
                path: path.clone(),
                name,
                dialect,
                assumed_dialect: source == DialectSource::Default,
                spool: Some(path),
            });
        }
        let name = args.program.display().to_string();
        let cannot_read =
            |e: io::Error| Failure::Error(format!("{name}: error: cannot read program: {e}"));
        let file = File::open(&args.program).map_err(cannot_read)?;
        let regular = file.metadata().map_err(cannot_read)?.is_file();
        let mut reader = BufReader::with_capacity(READ_BUFFER_BYTES, file);
        // The first bytes tell an ISO Heidenhain `.h` file from a conversational one.
        let (dialect, source) = {
            let head = reader.fill_buf().map_err(cannot_read)?;
            choose_dialect_from(args.dialect, Some((&args.program, head)), config.dialect)
        };
        // A pipe or device (`<(...)`, `/dev/stdin`) cannot be read twice: copy it first.
        let spooled = if regular {
            None
        } else {
            Some(spool(&name, &mut reader)?)
        };
        Ok(SimSource {
            path: spooled.clone().unwrap_or_else(|| args.program.clone()),
            name,
            dialect,
            assumed_dialect: source == DialectSource::Default,
            spool: spooled,
        })
    }

    /// A reader from the start of the program.
    pub fn reader(&self) -> Result<Box<dyn BufRead + Send>, Failure> {
        let file = File::open(&self.path).map_err(|e| {
            Failure::Error(format!("{}: error: cannot read program: {e}", self.name))
        })?;
        Ok(Box::new(BufReader::with_capacity(READ_BUFFER_BYTES, file)))
    }
}

/// Copies `input` to a new temporary file and returns its path.
fn spool(name: &str, input: &mut dyn io::Read) -> Result<PathBuf, Failure> {
    let path = std::env::temp_dir().join(format!(
        "kerf-sim-input-{}-{}",
        std::process::id(),
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_nanos())
            .unwrap_or(0)
    ));
    let mut file = File::options()
        .write(true)
        .create_new(true)
        .open(&path)
        .map_err(|e| {
            Failure::Error(format!(
                "{name}: error: cannot create a temporary copy of the program in {}: {e}",
                path.display()
            ))
        })?;
    let copied = io::copy(input, &mut file).and_then(|_| file.flush());
    if let Err(e) = copied {
        let _ = std::fs::remove_file(&path);
        return Err(Failure::Error(format!(
            "{name}: error: cannot read program: {e}"
        )));
    }
    Ok(path)
}

impl Drop for SimSource {
    fn drop(&mut self) {
        if let Some(path) = &self.spool {
            let _ = std::fs::remove_file(path);
        }
    }
}

/// Counts the CSV rows going to the file and shows a progress bar on standard error once
/// the simulation has taken more than a moment (never on a non-terminal).
struct ProgressWriter<W: Write> {
    inner: W,
    rows: u64,
    estimate_rows: u64,
    started: Instant,
    bar: Option<ProgressBar>,
}

/// How long a simulation runs before it gets a progress bar.
const PROGRESS_AFTER: Duration = Duration::from_millis(500);

impl<W: Write> ProgressWriter<W> {
    fn new(inner: W, estimate_rows: u64) -> Self {
        ProgressWriter {
            inner,
            rows: 0,
            estimate_rows,
            started: Instant::now(),
            bar: None,
        }
    }

    fn update(&mut self) {
        match &self.bar {
            Some(bar) => {
                // The estimate ignores acceleration, so the real run may be longer.
                if self.rows > bar.length().unwrap_or(0) {
                    bar.set_length(self.rows + self.rows / 10);
                }
                bar.set_position(self.rows);
            }
            None if self.started.elapsed() > PROGRESS_AFTER => {
                let bar = ProgressBar::new(self.estimate_rows.max(self.rows + 1))
                    .with_elapsed(self.started.elapsed());
                let style = ProgressStyle::with_template(
                    "simulating [{bar:40}] {percent:>3}% {pos}/~{len} periods, {elapsed} (eta {eta})",
                )
                .map(|style| style.progress_chars("=> "))
                .unwrap_or_else(|_| ProgressStyle::default_bar());
                bar.set_style(style);
                bar.set_position(self.rows);
                self.bar = Some(bar);
            }
            None => {}
        }
    }

    fn finish(&mut self) {
        if let Some(bar) = self.bar.take() {
            bar.finish_and_clear();
        }
    }
}

impl<W: Write> Write for ProgressWriter<W> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        let n = self.inner.write(buf)?;
        let before = self.rows;
        self.rows += buf[..n].iter().filter(|&&b| b == b'\n').count() as u64;
        // Redrawing is rate-limited by indicatif; checking the clock every few thousand
        // rows keeps the counting cheap.
        if self.rows / 4096 != before / 4096 {
            self.update();
        }
        Ok(n)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.inner.flush()
    }
}
