//! The commands that talk to a machine's daemon: `kerf run`, `status`, `hold`, `resume`,
//! `abort`, `override` and `record`.

use kerf_geom::PerAxis;
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use kerf::client::{Client, ClientError, MoveSender, SetpointReader};
use kerf::sim::{SimOptions, csv_header, write_row};
use kerf_gcode::{EventCode, Interpreter, Item};
use kerf_motion::Setpoint;
use kerf_proto::{
    ControlCommand, MoveMsg, PROGRAM_END_ABORTED, PROGRAM_END_NONE, PROGRAM_END_REFUSED,
    SetpointMsg, StatusMsg,
};

use crate::output::Output;
use crate::{Failure, ProgramArgs, SimSource, check_program, load_config};

/// How often `kerf run` asks for the status while it waits.
const STATUS_EVERY: Duration = Duration::from_millis(10);

/// How long `kerf run` waits for one status answer before it looks at the setpoint
/// stream to tell a slow daemon from a dead one.
const LIVE_REQUEST_TIMEOUT: Duration = Duration::from_millis(50);

/// Messages sent between two looks at the setpoint stream while streaming.
const DRAIN_EVERY: u64 = 256;

#[derive(Args)]
pub struct RunArgs {
    #[command(flatten)]
    pub program: ProgramArgs,
    /// Start the daemon's loop in this process (on its own threads, over the same
    /// services) instead of using a running `kerfd`.
    #[arg(long)]
    pub embedded: bool,
    /// Write every cycle's setpoint of the program to this CSV (the columns of `kerf sim`);
    /// when the safety layer stops the program, the rows up to its trip are kept.
    #[arg(long, value_name = "FILE.csv")]
    pub record: Option<PathBuf>,
    /// Run from line N: the program is read from its start without motion (modal state,
    /// offsets, tool, spindle, coolant), then the machine retracts Z to the top of its
    /// travel, changes the tool if needed, moves over the start of line N, restores the
    /// spindle and coolant, comes down (the last 5 mm at line N's feed) and runs on
    /// (docs/MACHINE.md).
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    pub from_line: Option<u32>,
}

#[derive(Args)]
pub struct MachineArgs {
    /// Machine configuration (TOML): names the machine whose daemon is asked. Without it:
    /// /etc/kerf/kerf.toml if present, else the built-in example machine.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
}

#[derive(Args)]
pub struct StatusArgs {
    #[command(flatten)]
    pub machine: MachineArgs,
    /// One JSON object instead of a line for a person.
    #[arg(long)]
    pub json: bool,
}

#[derive(Args)]
pub struct OverrideArgs {
    #[command(flatten)]
    pub machine: MachineArgs,
    /// Feed override in percent, 0 to 200 (0 stops on the path until raised again).
    #[arg(value_name = "PCT", value_parser = parse_live_override, allow_hyphen_values = true)]
    pub percent: f64,
}

#[derive(Args)]
pub struct SpindleOverrideArgs {
    #[command(flatten)]
    pub machine: MachineArgs,
    /// Spindle override in percent, 0 to 200.
    #[arg(value_name = "PCT", value_parser = parse_spindle_override, allow_hyphen_values = true)]
    pub percent: f64,
}

fn parse_spindle_override(text: &str) -> Result<f64, String> {
    parse_percent(text, "spindle", kerf_proto::MAX_SPINDLE_OVERRIDE_PCT)
}

#[derive(Args)]
pub struct SwitchArgs {
    #[command(flatten)]
    pub machine: MachineArgs,
    /// `on` or `off`.
    #[arg(value_name = "on|off", value_parser = parse_on_off, action = clap::ArgAction::Set)]
    pub on: bool,
}

#[derive(Args)]
pub struct InputArgs {
    #[command(flatten)]
    pub machine: MachineArgs,
    /// The input's number (as M66 P or E names it).
    #[arg(value_name = "N")]
    pub number: u32,
    /// A digital input's new state: `on` or `off`.
    #[arg(value_name = "on|off", value_parser = parse_on_off, required_unless_present = "analog")]
    pub on: Option<bool>,
    /// An analog input's new value.
    #[arg(
        long,
        value_name = "VALUE",
        conflicts_with = "on",
        allow_hyphen_values = true
    )]
    pub analog: Option<f64>,
}

fn parse_on_off(text: &str) -> Result<bool, String> {
    match text {
        "on" | "1" | "true" => Ok(true),
        "off" | "0" | "false" => Ok(false),
        _ => Err(format!("`{text}`: say `on` or `off`")),
    }
}

#[derive(Args)]
pub struct RecordArgs {
    #[command(flatten)]
    pub machine: MachineArgs,
    /// Where to write the CSV (`t,x,y,z`, `a,b,c` when the machine has rotary axes,
    /// `line,feed_mm_s`; `t` in s from the first recorded cycle).
    #[arg(long, value_name = "FILE.csv")]
    pub out: PathBuf,
    /// Stop after this many cycles (else at SIGINT or SIGTERM).
    #[arg(long, value_name = "N")]
    pub cycles: Option<u64>,
}

#[derive(Args)]
pub struct DumpArgs {
    #[command(flatten)]
    pub machine: MachineArgs,
    /// Where to write the CSV (the columns are in docs/DRIVES.md, "Black-box recorder");
    /// `-` writes it to standard output.
    #[arg(long, value_name = "FILE.csv")]
    pub out: PathBuf,
}

fn parse_live_override(text: &str) -> Result<f64, String> {
    parse_percent(text, "feed", kerf_proto::MAX_OVERRIDE_PCT)
}

/// An override of `what` ("feed", "spindle"): 0 to `max` percent, `%` allowed.
fn parse_percent(text: &str, what: &str, max: f64) -> Result<f64, String> {
    match text.trim_end_matches('%').parse::<f64>() {
        Ok(pct) if (0.0..=max).contains(&pct) => Ok(pct),
        _ => Err(format!(
            "`{text}` is not a {what} override: it must be 0 to {max} percent"
        )),
    }
}

pub(crate) fn client_failure(e: ClientError) -> Failure {
    match e {
        ClientError::NoDaemon { .. } | ClientError::Gone { .. } => {
            Failure::Exit(1, format!("kerf: error: {e}"))
        }
        _ => Failure::Error(format!("kerf: error: {e}")),
    }
}

pub(crate) fn connect(args: &MachineArgs) -> Result<(Client, kerf_config::Config), Failure> {
    let config = load_config(args.config.as_deref())?;
    let client = Client::connect(&config.machine).map_err(client_failure)?;
    Ok((client, config))
}

/// `kerf status`.
pub fn status(args: &StatusArgs) -> Result<(), Failure> {
    let (mut client, config) = connect(&args.machine)?;
    let s = client.status().map_err(client_failure)?;
    let names = kerf::status_view::subdevice_names(&config);
    // The DRO from the machine's parameter file: a file that cannot be read is said,
    // and the rest of the status shown.
    let dro = match kerf::dro::Dro::read(&config, s.position_mm_deg, s.tool_in_spindle) {
        Ok(d) => Some(d),
        Err(e) => {
            writeln!(io::stderr().lock(), "{e} (no work coordinates shown)")?;
            None
        }
    };
    let line = if args.json {
        kerf::status_view::status_json(&config.machine, &names, &s, dro.as_ref())
    } else {
        kerf::status_view::status_text(&config.machine, &names, &s, dro.as_ref())
    };
    writeln!(io::stdout().lock(), "{line}")?;
    Ok(())
}

/// `kerf optional-stop`, `single-block`, `block-delete`.
pub fn switch(args: &SwitchArgs, switch: kerf_proto::Switch) -> Result<(), Failure> {
    command(
        &args.machine,
        ControlCommand::Switch {
            switch,
            on: args.on,
        },
    )
}

/// `kerf input`.
pub fn input(args: &InputArgs) -> Result<(), Failure> {
    let (analog, value) = match (args.analog, args.on) {
        (Some(v), _) => (true, v),
        (None, on) => (false, if on == Some(true) { 1.0 } else { 0.0 }),
    };
    command(
        &args.machine,
        ControlCommand::SetInput {
            analog,
            index: args.number,
            value,
        },
    )
}

/// `kerf hold`, `resume`, `abort`, `override`.
pub fn command(args: &MachineArgs, command: ControlCommand) -> Result<(), Failure> {
    let (mut client, _) = connect(args)?;
    client.command(command).map_err(refused)?;
    Ok(())
}

/// A command's failure: the daemon's refusal in its words, else as [`client_failure`].
pub(crate) fn refused(e: ClientError) -> Failure {
    match e {
        ClientError::Refused(m) => Failure::Error(format!("kerf: error: refused: {m}")),
        e => client_failure(e),
    }
}

/// Sends `command` and waits for its answer as long as `patience` says the daemon may
/// take on this machine; an answer other than OK is an error with the daemon's message.
fn request_answered(
    args: &MachineArgs,
    command: ControlCommand,
    patience: fn(&kerf_config::Config) -> Duration,
) -> Result<kerf_proto::Response, Failure> {
    let (mut client, config) = connect(args)?;
    let r = client
        .request_within(command, patience(&config))
        .map_err(client_failure)?;
    if r.reason != kerf_proto::REASON_OK {
        return Err(Failure::Error(format!("kerf: error: {}", r.message())));
    }
    Ok(r)
}

/// `kerf reset`: answered once the reset has ended.
pub fn reset(args: &MachineArgs) -> Result<(), Failure> {
    request_answered(args, ControlCommand::Reset, kerfd::reset_patience)?;
    Ok(())
}

/// `kerf dump`: the daemon writes its black box to a file in its dump directory; the file
/// is copied to `--out`.
pub fn dump(args: &DumpArgs) -> Result<(), Failure> {
    let r = request_answered(&args.machine, ControlCommand::Dump, kerfd::dump_patience)?;
    let written = PathBuf::from(r.message());
    let mut out = Output::create(&args.out)?;
    let copied = std::fs::File::open(&written).and_then(|mut f| io::copy(&mut f, &mut out));
    if let Err(e) = copied {
        return Err(Failure::Error(format!(
            "{}: error: cannot copy the black box the daemon wrote to {}: {e}",
            out.name,
            written.display()
        )));
    }
    out.commit()
}

/// Stops a command at SIGINT or SIGTERM (the first; a second one ends the process as
/// usual).
pub(crate) fn stop_flag() -> Result<Arc<AtomicBool>, Failure> {
    let signals = kerf_rt::Signals::install()
        .map_err(|e| Failure::Error(format!("kerf: error: cannot handle signals: {e}")))?;
    let flag = Arc::new(AtomicBool::new(false));
    let f = flag.clone();
    std::thread::spawn(move || {
        loop {
            if signals.stop_requested().is_some() {
                f.store(true, Ordering::Release);
                return;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    });
    Ok(flag)
}

/// `kerf record`.
pub fn record(args: &RecordArgs) -> Result<(), Failure> {
    let (mut client, config) = connect(&args.machine)?;
    let status = client.status().map_err(client_failure)?;
    let stop = stop_flag()?;
    let rotary = status.axes_mask & 0b111_000 != 0;
    let mut reader =
        SetpointReader::open(client.node(), &config.machine).map_err(client_failure)?;
    // Written as it goes, so that it can be watched (`-`: standard output).
    let mut out = Output::create_live(&args.out)?;
    let name = out.name.clone();
    let to_stdout = out.is_stdout();
    let write_error = |e: io::Error| {
        if to_stdout {
            Failure::from(e)
        } else {
            Failure::Error(format!("{name}: error: {e}"))
        }
    };
    writeln!(out, "{}", csv_header(rotary)).map_err(write_error)?;
    let period_s = status.period_ns as f64 * 1e-9;
    let mut first: Option<u64> = None;
    let mut written = 0u64;
    let limit = args.cycles.unwrap_or(u64::MAX);
    let mut io_error = None;
    while written < limit && !stop.load(Ordering::Acquire) {
        let result = reader.drain(true, |m| {
            if written >= limit {
                return Ok(());
            }
            let base = *first.get_or_insert(m.seq);
            let t = kerf_pipeline::cycle_time_s(m.seq - base, period_s);
            if let Err(e) = write_row(&mut out, t, &setpoint_of(m), rotary) {
                io_error.get_or_insert(e);
            }
            written += 1;
            Ok(())
        });
        if let Some(e) = io_error.take() {
            return Err(write_error(e));
        }
        if let Err(e) = result {
            // What was recorded before the daemon went away is kept.
            out.commit()?;
            return Err(client_failure(e));
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    out.commit()
}

pub(crate) fn setpoint_of(m: &SetpointMsg) -> Setpoint {
    Setpoint {
        position: m.position_mm_deg,
        line: m.line,
        move_index: 0,
        move_count: 1,
        feed_mm_s: m.feed_mm_s,
        rapid: false,
    }
}

/// The program's rows of the setpoint stream as `kerf sim` writes them: the row at t = 0
/// at the start position, then one per cycle of the program. It replaces its target when
/// the program has run to its end, or when the safety layer stopped it (then it ends with
/// the cycle of the trip: the diagnosis, as `kerf sim` keeps the CSV of a run stopped by a
/// limit fault); a run that fails otherwise leaves the target as it was.
pub(crate) struct Recording {
    out: Output,
    rotary: bool,
    period_s: f64,
}

impl Recording {
    pub(crate) fn create(
        path: &Path,
        rotary: bool,
        period_s: f64,
        start: PerAxis<f64>,
    ) -> Result<Self, Failure> {
        // Written beside `path` and renamed there when the program has run to its end.
        let mut r = Recording {
            out: Output::create(path)?,
            rotary,
            period_s,
        };
        let first = Setpoint {
            position: start,
            ..Setpoint::default()
        };
        writeln!(r.out, "{}", csv_header(rotary)).map_err(|e| r.error(e))?;
        write_row(&mut r.out, 0.0, &first, rotary).map_err(|e| r.error(e))?;
        Ok(r)
    }

    fn error(&self, e: io::Error) -> Failure {
        self.out.error(e)
    }

    fn row(&mut self, m: &SetpointMsg) -> Result<(), Failure> {
        let t = kerf_pipeline::cycle_time_s(m.program_cycle, self.period_s);
        write_row(&mut self.out, t, &setpoint_of(m), self.rotary).map_err(|e| self.error(e))
    }

    pub(crate) fn finish(self) -> Result<(), Failure> {
        self.out.commit()
    }
}

/// What `kerf run` watches on the setpoint stream.
pub(crate) struct Watch {
    pub(crate) program_id: u64,
    pub(crate) recording: Option<Recording>,
    /// Highest program cycle seen.
    pub(crate) cycle: u64,
    pub(crate) line: u32,
    pub(crate) feed_mm_s: f64,
    pub(crate) last_seq: u64,
}

impl Watch {
    pub(crate) fn take(&mut self, reader: &mut SetpointReader) -> Result<(), Failure> {
        let mut failure = None;
        let result = reader.drain(true, |m| {
            self.last_seq = m.seq;
            if m.program_id == self.program_id && m.program_cycle > self.cycle {
                self.cycle = m.program_cycle;
                self.line = m.line;
                self.feed_mm_s = m.feed_mm_s;
                if let Some(r) = self.recording.as_mut()
                    && let Err(e) = r.row(m)
                {
                    failure.get_or_insert(e);
                }
            }
            Ok(())
        });
        if let Some(f) = failure {
            return Err(f);
        }
        result.map(|_| ()).map_err(client_failure)
    }

    /// The program was stopped by the safety layer, as the status `s` reports: the
    /// recording takes every setpoint up to that status (the last of the program is the
    /// cycle of the trip, with what the drives were sent: a setpoint that breaks a limit
    /// never reaches them, the quick stop does) and replaces its target. An error names
    /// why the recording could not be kept.
    fn keep_to_trip(&mut self, reader: &mut SetpointReader, s: &StatusMsg) -> Result<(), Failure> {
        if self.recording.is_none() {
            return Ok(());
        }
        self.take(reader)?;
        while self.last_seq < s.cycles {
            std::thread::sleep(Duration::from_millis(1));
            self.take(reader)?;
        }
        match self.recording.take() {
            Some(r) => r.finish(),
            None => Ok(()),
        }
    }
}

/// The status while a program runs: a request that goes unanswered for
/// [`LIVE_REQUEST_TIMEOUT`] is retried as long as the setpoint stream shows the daemon
/// alive; a stalled stream ([`kerf::client::STREAM_TIMEOUT`]) ends the run.
pub(crate) fn live_status(
    client: &mut Client,
    watch: &mut Watch,
    reader: &mut SetpointReader,
) -> Result<StatusMsg, Failure> {
    loop {
        match client.request_within(ControlCommand::Status, LIVE_REQUEST_TIMEOUT) {
            Ok(r) => return Ok(r.status),
            Err(ClientError::NoDaemon { .. }) => watch.take(reader)?,
            Err(e) => return Err(client_failure(e)),
        }
    }
}

/// A program id no other run on this PC picks: the process id and the time.
pub(crate) fn program_id() -> u64 {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64);
    ((std::process::id() as u64) << 40 ^ nanos) | 1
}

/// `kerf run`.
pub fn run(args: &RunArgs) -> Result<(), Failure> {
    let config = load_config(args.program.config.as_deref())?;
    let source = SimSource::open(&args.program, &config)?;
    let name = source.name.clone();
    let _embedded = if args.embedded {
        Some(kerfd::start(&config, false).map_err(|e| match e {
            kerfd::StartError::AlreadyRunning(_) => Failure::Exit(1, format!("kerf: error: {e}")),
            e => Failure::Error(format!("kerf: error: {e}")),
        })?)
    } else {
        None
    };
    let mut client = Client::connect(&config.machine).map_err(client_failure)?;
    let mut status = idle_status(&mut client, &config.machine)?;
    if !args.embedded {
        require_homed(&status)?;
    }
    let unhomed = unhomed_axes(&status);
    if unhomed != 0 {
        // The embedded daemon is a machine just switched on: it homes first, as the
        // machinist would.
        eprintln!("kerf: the machine is not homed: homing every axis first");
        crate::manual::home_axes(&mut client, unhomed, &*stop_flag()?)?;
        status = idle_status(&mut client, &config.machine)?;
    }
    let start = status.position_mm_deg;
    // The machine's own files: its parameter file and tool table (docs/MACHINE.md).
    let machine_settings = config
        .machine_settings()
        .map_err(|e| Failure::Error(e.to_string()))?;
    let mut settings = crate::settings_for(machine_settings, &args.program.program);
    // The persistent parameters the program starts with: the file is written only when
    // the program changed them.
    let start_parameters =
        Interpreter::new(&[][..], source.dialect, settings.clone()).persistent_parameters();
    settings.start_mm_deg = start;
    // Block delete is the operator's switch on the machine (`kerf block-delete on|off`),
    // and the current tool is the one in its spindle.
    settings.block_delete = status.switches & kerf_proto::SWITCH_BLOCK_DELETE != 0;
    settings.tool_in_spindle = (status.tool_in_spindle != 0).then_some(status.tool_in_spindle);
    let options = SimOptions {
        queue_capacity: config.daemon.queue_segments as usize,
        ..SimOptions::default()
    };
    // Pass 1: the whole program, checked before any motion.
    let (checked, last_line) =
        check_program(&source, &config, settings.clone(), &options, true, true)?;
    let scan = checked.scan;
    drop(checked.kept);
    if let (Some(n), Some(read)) = (args.from_line, scan.checked_to_line) {
        return Err(Failure::Error(format!(
            "{name}:{read}:1: error: run from line {n}: the program reads #5399 after an M66 here, so its path depends on the machine's inputs; run it from the start"
        )));
    }

    let period_s = status.period_ns as f64 * 1e-9;
    let rotary = status.axes_mask & 0b111_000 != 0 && scan.rotary_used;
    let recording = match &args.record {
        Some(path) => Some(Recording::create(path, rotary, period_s, start)?),
        None => None,
    };
    let machine = config.machine.clone();
    let mut reader = SetpointReader::open(client.node(), &machine).map_err(client_failure)?;
    let mut sender = MoveSender::open(client.node(), &machine).map_err(client_failure)?;
    let id = program_id();
    let mut watch = Watch {
        program_id: id,
        recording,
        cycle: 0,
        line: 0,
        feed_mm_s: 0.0,
        last_seq: 0,
    };
    let bar = progress_bar(last_line);
    // A program that ended early, or another one, is reported at once; a pause of this
    // program is told once, when it begins.
    // The pause told last (its reason and line); the thread that waits for an input's
    // answer tells pauses too, while the interpreter waits.
    let told_pause = Arc::new(std::sync::atomic::AtomicU64::new(0));
    let check =
        |client: &mut Client, watch: &mut Watch, reader: &mut SetpointReader, s: &StatusMsg| {
            if s.program_id == id {
                tell_pause(&bar, &told_pause, s)?;
            }
            check_program_state(client, watch, reader, s, id, &name, &machine)
        };
    let window = status.window_items.max(1);
    let mut acked = 0u64;
    let mut last_status = Instant::now();

    // Pass 2: stream the program.
    let stop = stop_flag()?;
    sender
        .send(MoveMsg::begin(id, start, 0))
        .map_err(client_failure)?;
    let mut seq = 0u64;
    let mut interpreter = Interpreter::new(source.reader()?, source.dialect, settings);
    // `#5399` after an M66: the daemon's answer, asked by a thread of its own.
    let m66_sent = Arc::new(std::sync::atomic::AtomicU64::new(0));
    if scan.checked_to_line.is_some() {
        interpreter.set_input_wait(Box::new(DaemonInputs::start(
            &machine,
            id,
            status.input_result_seq,
            m66_sent.clone(),
            stop.clone(),
            (bar.clone(), told_pause.clone()),
        )));
    }
    let items: Box<dyn Iterator<Item = Result<Item, kerf_gcode::Diagnostic>>> = match args.from_line
    {
        Some(n) => Box::new(crate::from_line::FromLine::new(
            interpreter.by_ref(),
            n,
            &config,
            start,
            status.tool_in_spindle,
        )),
        None => Box::new(interpreter.by_ref()),
    };
    for item in items {
        let item = match item {
            // The approach of `--from-line` could not be made.
            Err(d) if args.from_line == Some(d.line) => {
                let _ = client.command(ControlCommand::Abort);
                return Err(Failure::Error(d.render(&name)));
            }
            Ok(item) => item,
            // Past the line pass 1 stopped at (a read of `#5399`), errors are the program's.
            Err(d) if scan.checked_to_line.is_some_and(|l| d.line >= l) => {
                let _ = client.command(ControlCommand::Abort);
                return Err(Failure::Error(format!(
                    "{} (the motion was aborted)",
                    d.render(&name)
                )));
            }
            // Pass 1 read it without an error: the file changed in between.
            Err(d) => {
                let _ = client.command(ControlCommand::Abort);
                return Err(Failure::Error(format!(
                    "{} (the file changed after it was checked; the motion was aborted)",
                    d.render(&name)
                )));
            }
        };
        seq += 1;
        let msg = MoveMsg::from_item(id, seq, &item);
        // Flow control: never more than the daemon's window unacknowledged.
        while sender.sent - acked >= window {
            if stop.load(Ordering::Acquire) {
                let _ = client.command(ControlCommand::Abort);
                return Err(Failure::Error(format!(
                    "{name}: error: interrupted; the motion was aborted on the path"
                )));
            }
            let s = live_status(&mut client, &mut watch, &mut reader)?;
            check(&mut client, &mut watch, &mut reader, &s)?;
            if s.program_id == id {
                acked = s.moves_received;
            }
            watch.take(&mut reader)?;
            if sender.sent - acked >= window {
                std::thread::sleep(Duration::from_micros(500));
            }
        }
        sender.send(msg).map_err(client_failure)?;
        if let Item::Event(e) = &item
            && matches!(e.code, EventCode::M66 | EventCode::M66Analog)
        {
            m66_sent.fetch_add(1, Ordering::AcqRel);
        }
        if sender.sent % DRAIN_EVERY == 0 {
            watch.take(&mut reader)?;
            update_bar(&bar, &watch, last_line, None);
        }
        if stop.load(Ordering::Acquire) {
            let _ = client.command(ControlCommand::Abort);
            return Err(Failure::Error(format!(
                "{name}: error: interrupted; the motion was aborted on the path"
            )));
        }
        if last_status.elapsed() > STATUS_EVERY * 10 {
            last_status = Instant::now();
            let s = live_status(&mut client, &mut watch, &mut reader)?;
            check(&mut client, &mut watch, &mut reader, &s)?;
        }
    }
    sender.send(MoveMsg::end(id, seq)).map_err(client_failure)?;

    // Wait for the motion to finish.
    loop {
        watch.take(&mut reader)?;
        let s = live_status(&mut client, &mut watch, &mut reader)?;
        update_bar(&bar, &watch, last_line, Some(&s));
        if stop.load(Ordering::Acquire) {
            let _ = client.command(ControlCommand::Abort);
            return Err(Failure::Error(format!(
                "{name}: error: interrupted; the motion was aborted on the path"
            )));
        }
        if s.program_id == id && s.program_end != PROGRAM_END_NONE {
            // Every setpoint up to the one that finished the program.
            while watch.last_seq < s.cycles {
                std::thread::sleep(Duration::from_millis(1));
                watch.take(&mut reader)?;
            }
            bar.finish_and_clear();
            check(&mut client, &mut watch, &mut reader, &s)?;
            if let Some(r) = watch.recording.take() {
                r.finish()?;
            }
            return program_ended(&scan, &s, &config, &interpreter, &start_parameters, &name);
        }
        check(&mut client, &mut watch, &mut reader, &s)?;
        std::thread::sleep(STATUS_EVERY);
    }
}

/// The answer to `#5399` in `kerf run`: the daemon's result of the program's M66 wait.
/// The interpreter asks once the M66 event (and everything before it) has been sent; a
/// thread with its own connection (the control client cannot leave the main thread)
/// polls the status until the daemon reports that many waits of this program ended.
struct DaemonInputs {
    ask: std::sync::mpsc::Sender<u64>,
    answer: std::sync::mpsc::Receiver<Result<f64, String>>,
    /// M66 events this program has sent so far (counted by the streaming loop).
    m66_sent: Arc<std::sync::atomic::AtomicU64>,
    /// `input_result_seq` before the program began.
    start_seq: u64,
}

impl DaemonInputs {
    fn start(
        machine: &str,
        program_id: u64,
        start_seq: u64,
        m66_sent: Arc<std::sync::atomic::AtomicU64>,
        stop: Arc<AtomicBool>,
        tell: (ProgressBar, Arc<std::sync::atomic::AtomicU64>),
    ) -> DaemonInputs {
        let (ask, asked) = std::sync::mpsc::channel::<u64>();
        let (answer_tx, answer) = std::sync::mpsc::channel();
        let machine = machine.to_string();
        std::thread::spawn(move || {
            let mut client = None;
            while let Ok(want) = asked.recv() {
                let result = wait_for_input(&machine, &mut client, program_id, want, &stop, &tell);
                if answer_tx.send(result).is_err() {
                    return;
                }
            }
        });
        DaemonInputs {
            ask,
            answer,
            m66_sent,
            start_seq,
        }
    }
}

impl kerf_gcode::InputWait for DaemonInputs {
    fn wait(&mut self, _event: &kerf_gcode::Event) -> Result<f64, String> {
        let want = self.start_seq + self.m66_sent.load(Ordering::Acquire);
        self.ask
            .send(want)
            .map_err(|_| "the thread that asks the daemon ended".to_string())?;
        self.answer
            .recv()
            .map_err(|_| "the thread that asks the daemon ended".to_string())?
    }
}

/// Polls the daemon until its `want`-th wait on an input (counted since it started) has
/// ended in program `program_id`: its result. An error when the program ends first, the
/// daemon goes away, or `kerf run` is interrupted.
fn wait_for_input(
    machine: &str,
    client: &mut Option<Client>,
    program_id: u64,
    want: u64,
    stop: &AtomicBool,
    tell: &(ProgressBar, Arc<std::sync::atomic::AtomicU64>),
) -> Result<f64, String> {
    loop {
        if stop.load(Ordering::Acquire) {
            return Err("interrupted while the machine waited on the input".to_string());
        }
        if client.is_none() {
            *client = Some(Client::connect(machine).map_err(|e| e.to_string())?);
        }
        let Some(c) = client.as_mut() else { continue };
        let s = c.status().map_err(|e| e.to_string())?;
        if s.program_id == program_id {
            // The program may pause before it gets to the M66: the operator must know.
            let _ = tell_pause(&tell.0, &tell.1, &s);
        }
        if s.input_result_program == program_id && s.input_result_seq >= want {
            return Ok(s.input_result_value);
        }
        if s.program_id == program_id && s.program_end != PROGRAM_END_NONE {
            return Err("the program ended before the machine answered the M66".to_string());
        }
        std::thread::sleep(Duration::from_millis(2));
    }
}

/// Tells a pause of the program once, when it begins: "paused at line 12 (M0, program
/// stop): `kerf resume` to continue" (above the progress bar on a terminal, else on
/// standard error). `kerf run` keeps waiting: it ends only when the program does.
pub(crate) fn tell_pause(
    bar: &ProgressBar,
    told: &std::sync::atomic::AtomicU64,
    s: &StatusMsg,
) -> Result<(), Failure> {
    let now = u64::from(s.pause_reason) << 32 | u64::from(s.pause_line);
    if told.swap(now, Ordering::AcqRel) == now {
        return Ok(());
    }
    if let Some(text) = kerf::status_view::pause_text(s) {
        let text = format!("kerf: {text}");
        if bar.is_hidden() {
            writeln!(io::stderr().lock(), "{text}")?;
        } else {
            bar.println(text);
        }
    }
    Ok(())
}

/// The machine's status when it can take a program: idle (no other program unfinished)
/// and not in fault; otherwise the error that says what to do.
pub(crate) fn idle_status(client: &mut Client, machine: &str) -> Result<StatusMsg, Failure> {
    let status = client.status().map_err(client_failure)?;
    if status.program_id != 0 && status.program_end == PROGRAM_END_NONE {
        return Err(Failure::Error(format!(
            "kerf: error: machine `{}` is busy with another program (`kerf status`; `kerf abort` ends it)",
            machine
        )));
    }
    if let Some(fault) = kerf::client::safety_text(&status) {
        return Err(Failure::Error(format!(
            "kerf: error: machine `{}` is in fault: {fault}; `kerf reset` clears it once its cause is gone (`kerf status` says more)",
            machine
        )));
    }
    if status.state == kerf_proto::STATE_MANUAL {
        return Err(Failure::Error(format!(
            "kerf: error: machine `{machine}` is moving by hand (a jog or homing): wait until it is at rest"
        )));
    }
    Ok(status)
}

/// The axes (bit i: axis i) that keep programs from running because the machine requires
/// homing and they are not homed; 0 when none does.
fn unhomed_axes(status: &StatusMsg) -> u32 {
    if status.homing_required == 0 {
        return 0;
    }
    status.axes_mask & 0b11_1111 & !status.homed
}

/// Refuses a machine whose axes are not all homed when it requires homing (programs,
/// MDI, touch-off: its machine coordinates are not known yet).
pub(crate) fn require_homed(status: &StatusMsg) -> Result<(), Failure> {
    let unhomed = unhomed_axes(status);
    if unhomed != 0 {
        let axis = kerf_geom::AXIS_NAMES[unhomed.trailing_zeros() as usize];
        return Err(Failure::Error(format!(
            "kerf: error: the machine is not homed (axis {axis}): run `kerf home --all` first"
        )));
    }
    Ok(())
}

/// What `kerf run` does once the daemon reports the program over and every setpoint has
/// been read: the end point checked (exit 0 means the program ran to it), the persistent
/// parameters written when the program changed them, a program without motion noted.
fn program_ended(
    scan: &kerf::sim::Scan,
    s: &StatusMsg,
    config: &kerf_config::Config,
    interpreter: &Interpreter<Box<dyn io::BufRead + Send>>,
    start_parameters: &[(u32, f64)],
    name: &str,
) -> Result<(), Failure> {
    // Exit 0 means the program ran to its end point (known when the whole program was
    // checked; after a read of `#5399` the end depends on the machine's input, and the
    // daemon's own report that the program finished is the proof).
    if scan.checked_to_line.is_none() {
        scan.check_end(&s.position_mm_deg)
            .map_err(|e| Failure::Error(format!("{name}: error: {e}")))?;
    }
    // The program ended normally: its persistent parameters (G28/G30 positions,
    // work offsets, G92) are kept for the next one, as LinuxCNC keeps its .var file
    // (written when the program changed them).
    let parameters = interpreter.persistent_parameters();
    if parameters != start_parameters {
        config.save_machine_parameters(&parameters).map_err(|e| {
            Failure::Error(format!(
                "{}: error: cannot write the parameter file: {e}",
                config.machine_parameter_file().display()
            ))
        })?;
    }
    if scan.moves == 0 {
        writeln!(io::stderr().lock(), "note: no motion in {name}")?;
    }
    Ok(())
}

/// A program that ended early (aborted, or refused by the daemon) or that another
/// client's program replaced is reported at once.
pub(crate) fn check_program_state(
    client: &mut Client,
    watch: &mut Watch,
    reader: &mut SetpointReader,
    s: &StatusMsg,
    id: u64,
    name: &str,
    machine: &str,
) -> Result<(), Failure> {
    if s.program_id != id {
        // Not (or no longer) the daemon's current program: its own fate says why.
        if let Ok(r) = client.request(ControlCommand::Program { program_id: id }) {
            match r.program_fate {
                kerf_proto::PROGRAM_FATE_REFUSED => {
                    return Err(Failure::Error(format!(
                        "{name}: error: the daemon refused the program: {}",
                        r.message()
                    )));
                }
                kerf_proto::PROGRAM_FATE_ABORTED => {
                    return Err(Failure::Error(format!(
                        "{name}: error: the program was aborted (kerf abort, or the daemon stopped); the machine stopped on the path"
                    )));
                }
                _ => {}
            }
        }
        if s.program_id != 0 && s.program_end == PROGRAM_END_NONE {
            return Err(Failure::Error(format!(
                "{name}: error: machine `{machine}` started another program"
            )));
        }
    }
    if s.program_id == id {
        match s.program_end {
            PROGRAM_END_ABORTED => {
                return Err(Failure::Error(format!(
                    "{name}: error: the program was aborted (kerf abort, or the daemon stopped); the machine stopped on the path at line {}",
                    s.line
                )));
            }
            PROGRAM_END_REFUSED if s.safety_check != kerf_proto::SAFETY_NONE => {
                // The recording up to the trip is the diagnosis: kept before anything else,
                // while the setpoints it needs are still in the reader's buffer.
                let recording = match watch.keep_to_trip(reader, s) {
                    Ok(()) => String::new(),
                    Err(Failure::Error(e) | Failure::Exit(_, e)) => {
                        let why = e.split_once("error: ").map_or(e.as_str(), |(_, why)| why);
                        format!("; the recording was not written: {why}")
                    }
                    Err(Failure::BrokenPipe) => return Err(Failure::BrokenPipe),
                };
                // The black box is written once the quick stop is at rest: wait for it
                // (a few seconds at most) to name it.
                let deadline = Instant::now() + Duration::from_secs(5);
                let mut s = *s;
                while s.fault_dump().is_empty() && Instant::now() < deadline {
                    std::thread::sleep(STATUS_EVERY);
                    match client.status() {
                        Ok(now) if now.safety_check != kerf_proto::SAFETY_NONE => s = now,
                        _ => break,
                    }
                }
                let dump = match s.fault_dump() {
                    "" => String::new(),
                    path => format!("; black box: {path}"),
                };
                return Err(Failure::Error(format!(
                    "{name}: error: the safety layer stopped the machine at line {}: {}; the axes came to rest on the quick stop and the rest of the program was dropped{dump}; `kerf reset` clears the fault once its cause is gone{recording}",
                    s.safety_line,
                    s.fault_text()
                )));
            }
            PROGRAM_END_REFUSED => {
                return Err(Failure::Error(format!(
                    "{name}: error: the daemon refused the program and stopped it at the end of the last valid move: {}",
                    s.fault_text()
                )));
            }
            _ => {}
        }
    }
    Ok(())
}

fn progress_bar(last_line: u32) -> ProgressBar {
    // Hidden when standard error is not a terminal.
    let bar = ProgressBar::new(u64::from(last_line.max(1)));
    if let Ok(style) =
        ProgressStyle::with_template("{bar:30} {percent:>3}% line {pos}/{len} {msg} {elapsed}")
    {
        bar.set_style(style);
    }
    bar
}

fn update_bar(bar: &ProgressBar, watch: &Watch, last_line: u32, s: Option<&StatusMsg>) {
    bar.set_position(u64::from(watch.line.min(last_line)));
    match s {
        Some(s) => bar.set_message(format!(
            "feed {:.1} mm/s, queued {:.1} s",
            watch.feed_mm_s, s.queued_s
        )),
        None => bar.set_message(format!("feed {:.1} mm/s", watch.feed_mm_s)),
    }
}
