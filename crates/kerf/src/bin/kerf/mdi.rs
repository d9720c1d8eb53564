//! `kerf mdi`: G-code lines typed by hand, each run on the machine as a program of its own
//! (the daemon's BEGIN, the line's moves and events, END) once it has been checked like a
//! program (travel limits on the exact and the planned path, what the machine lacks),
//! and run to its end before the next line is read.
//!
//! The lines run in the machine's state: its persistent parameters (work offsets, G92,
//! the active coordinate system), its tool table, the tool in its spindle and its
//! position. In a session (`kerf mdi` without a line) one interpreter reads every line,
//! so the modal state of the lines before (G90/G91, units, plane, feed, G43, …) carries
//! over; before each line the interpreter's position is set to the machine's (after an
//! abort the machine stopped short). A one-shot `kerf mdi LINE` starts from the state a
//! program starts in, with the persisted parameters: that is what survives between
//! invocations. M2 or M30 ends the program state: the next line starts afresh.
//!
//! After every line whose persistent parameters (G10 L2/L20, G92, G54…) or tool entries
//! (G10 L1/L10/L11) changed, the parameter file and the tool table are written, so the
//! files always hold what is in force. A line that fails leaves the modal state as far as
//! the interpreter got, as LinuxCNC's MDI does; nothing of it moves.

use std::collections::VecDeque;
use std::io::{self, BufRead, BufReader, IsTerminal, Read, Write};
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use clap::Args;
use indicatif::ProgressBar;
use kerf::client::{Client, ClientError, MoveSender, SetpointReader};
use kerf::sim::{Prepass, SimOptions};
use kerf::{DialectSource, choose_dialect_from};
use kerf_config::Config;
use kerf_gcode::{Dialect, Interpreter, Item, Settings, Tool};
use kerf_pipeline::ProgramActions;
use kerf_proto::{ControlCommand, MoveMsg, PROGRAM_END_NONE, StatusMsg};

use crate::machine::{
    Recording, Watch, check_program_state, client_failure, idle_status, live_status, program_id,
    tell_pause,
};
use crate::{Failure, load_config, parse_dialect};

/// How often the status is asked while a line runs.
const STATUS_EVERY: Duration = Duration::from_millis(10);

/// The name errors give the lines: `mdi:N:COL: error: …`.
const NAME: &str = "mdi";

#[derive(Args)]
pub struct MdiArgs {
    /// The lines' dialect: linuxcnc (alias tormach), rockwell, sinumerik, heidenhain or
    /// fagor. Without it: the config's `dialect`, then linuxcnc.
    #[arg(long, value_name = "D", value_parser = parse_dialect)]
    dialect: Option<Dialect>,
    /// Machine configuration (TOML): names the machine whose daemon runs the lines.
    /// Without it: /etc/kerf/kerf.toml if present, else the built-in example machine.
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Write every cycle's setpoint of the line to this CSV (the columns of `kerf run
    /// --record`).
    #[arg(long, value_name = "FILE.csv", requires = "line")]
    record: Option<PathBuf>,
    /// The line to run; without it, lines are read one at a time (a prompt with line
    /// editing and history on a terminal), each run to its end before the next. Ctrl-C
    /// during motion aborts it (the session goes on); Ctrl-D ends the session.
    #[arg(value_name = "LINE", allow_hyphen_values = true)]
    line: Option<String>,
}

/// `kerf mdi`.
pub fn run(args: &MdiArgs) -> Result<(), Failure> {
    let config = load_config(args.config.as_deref())?;
    let (dialect, _source): (Dialect, DialectSource) =
        choose_dialect_from(args.dialect, None, config.dialect);
    let client = Client::connect(&config.machine).map_err(client_failure)?;
    let mut session = Session::start(config, dialect, client)?;
    match &args.line {
        Some(line) => {
            session.one_shot = true;
            session
                .line(line, args.record.as_ref())
                .map_err(|f| f.failure)
        }
        None => session.interactive(),
    }
}

/// Typed lines on their way to the interpreter: it reads them as its input, and the end
/// of what was typed so far is a pause (MDI mode), not the end of a program.
#[derive(Clone, Default)]
struct Typed(Arc<Mutex<VecDeque<u8>>>);

impl Typed {
    fn push(&self, line: &str) {
        if let Ok(mut q) = self.0.lock() {
            q.extend(line.as_bytes());
            q.push_back(b'\n');
        }
    }
}

impl Read for Typed {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let mut q = self
            .0
            .lock()
            .map_err(|_| io::Error::other("the typed lines' lock was poisoned"))?;
        let n = buf.len().min(q.len());
        for (slot, b) in buf.iter_mut().zip(q.drain(..n)) {
            *slot = b;
        }
        Ok(n)
    }
}

/// How a line failed: the failure, and whether the session can go on after it.
struct LineFailure {
    failure: Failure,
    /// The daemon went away or the process was told to stop: the session ends.
    fatal: bool,
}

impl From<Failure> for LineFailure {
    fn from(failure: Failure) -> Self {
        let fatal = matches!(failure, Failure::Exit(..) | Failure::BrokenPipe);
        LineFailure { failure, fatal }
    }
}

fn error(message: String) -> LineFailure {
    Failure::Error(message).into()
}

/// An MDI session: one interpreter over the typed lines, on one machine.
struct Session {
    config: Config,
    dialect: Dialect,
    client: Client,
    typed: Typed,
    interp: MdiInterpreter,
    /// The persistent parameters and the tool table as last written (or read).
    saved_parameters: Vec<(u32, f64)>,
    saved_tools: Vec<Tool>,
    /// Lines given to the interpreter so far (its line numbers).
    lines: u32,
    /// `kerf mdi LINE`: an unfinished O-word structure cannot be continued.
    one_shot: bool,
}

impl Session {
    fn start(config: Config, dialect: Dialect, mut client: Client) -> Result<Session, Failure> {
        let status = client.status().map_err(client_failure)?;
        let typed = Typed::default();
        let (interp, saved_tools) = fresh(&config, dialect, &status, &typed)?;
        let saved_parameters = interp.persistent_parameters();
        Ok(Session {
            config,
            dialect,
            client,
            typed,
            interp,
            saved_parameters,
            saved_tools,
            lines: 0,
            one_shot: false,
        })
    }

    /// Reads lines until the end of the input; each runs to its end before the next.
    fn interactive(&mut self) -> Result<(), Failure> {
        let mut failed = 0u32;
        let mut total = 0u32;
        let mut input = Input::open()?;
        loop {
            let prompt = if self.interp.unfinished_structure().is_some() {
                "mdi...> "
            } else {
                "mdi> "
            };
            let Some(text) = input.read(prompt)? else {
                break;
            };
            if text.trim().is_empty() {
                continue;
            }
            total += 1;
            if let Err(f) = self.line(&text, None) {
                failed += 1;
                let message = match &f.failure {
                    Failure::Error(m) | Failure::Exit(_, m) => m.clone(),
                    Failure::BrokenPipe => return Err(Failure::BrokenPipe),
                };
                writeln!(io::stderr().lock(), "{message}")?;
                if f.fatal {
                    return Err(f.failure);
                }
            }
        }
        if failed > 0 {
            return Err(Failure::Exit(
                2,
                format!("kerf: error: {failed} of {total} MDI lines failed"),
            ));
        }
        Ok(())
    }

    /// Runs one typed line on the machine, to its end.
    fn line(&mut self, text: &str, record: Option<&PathBuf>) -> Result<(), LineFailure> {
        let status = idle_status(&mut self.client, &self.config.machine)?;
        crate::machine::require_homed(&status)?;
        self.interp.set_position(status.position_mm_deg);
        self.lines += 1;
        let n = self.lines;
        self.typed.push(text);
        let mut items = Vec::new();
        let mut failed = None;
        for item in self.interp.by_ref() {
            match item {
                Ok(item) => items.push(item),
                Err(d) => {
                    failed = Some(d.render(NAME));
                    break;
                }
            }
        }
        // Persisted whatever became of the line: the files hold what is in force.
        let persisted = self.persist(n);
        if let Some(message) = failed {
            return Err(error(message));
        }
        persisted?;
        if items.is_empty()
            && let Some((first, what)) = self.interp.unfinished_structure()
        {
            if self.one_shot {
                let what = what.replace("at the end of the program", "at the end of the line");
                return Err(error(format!("{NAME}:{first}:1: error: {what}")));
            }
            // A session: the lines that end it follow.
            return Ok(());
        }
        let result = if items.is_empty() {
            Ok(())
        } else {
            self.check(&items, n)
                .and_then(|scan| self.stream(&items, &status, scan, n, record))
        };
        if self.interp.ended() {
            // M2/M30: the next line starts in a program's start state.
            let status = self.client.status().map_err(client_failure)?;
            let (interp, tools) = fresh(&self.config, self.dialect, &status, &self.typed)?;
            self.saved_parameters = interp.persistent_parameters();
            self.interp = interp;
            self.saved_tools = tools;
            // Its line numbers go on from the session's: blank lines it reads first.
            for _ in 0..n {
                self.typed.push("");
            }
        }
        result
    }

    /// The line checked as a program is before any motion: the travel of its moves on
    /// the exact and on the planned path, and what the machine lacks.
    fn check(&self, items: &[Item], n: u32) -> Result<kerf::sim::Scan, LineFailure> {
        let options = SimOptions {
            queue_capacity: self.config.daemon.queue_segments as usize,
            ..SimOptions::default()
        };
        let mut prepass = Prepass::new(&self.config, &options);
        let mut actions = ProgramActions::new();
        let caps = self.config.machine_check();
        let refused = |e: kerf::sim::PrepassError| error(format!("{NAME}:{n}:1: error: {e}"));
        for item in items {
            match item {
                Item::Move(m) => {
                    if let Some(wait) = actions.before_move(m) {
                        prepass.input(&wait).map_err(refused)?;
                    }
                    prepass.push(m).map_err(refused)?;
                }
                Item::Event(e) => {
                    caps.check_event(e)
                        .map_err(|why| error(format!("{NAME}:{n}:1: error: {why}")))?;
                    if let Some(input) = actions.event(e) {
                        prepass.input(&input).map_err(refused)?;
                    }
                }
            }
        }
        Ok(prepass.finish().map_err(refused)?.scan)
    }

    /// Streams the line's items to the daemon as one program and waits for its end.
    fn stream(
        &mut self,
        items: &[Item],
        status: &StatusMsg,
        scan: kerf::sim::Scan,
        n: u32,
        record: Option<&PathBuf>,
    ) -> Result<(), LineFailure> {
        let machine = self.config.machine.clone();
        let name = format!("{NAME}:{n}");
        let start = status.position_mm_deg;
        let period_s = status.period_ns as f64 * 1e-9;
        let rotary = status.axes_mask & 0b111_000 != 0 && scan.rotary_used;
        let recording = match record {
            Some(path) => Some(Recording::create(path, rotary, period_s, start)?),
            None => None,
        };
        let client = &mut self.client;
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
        // Pauses (M0, M6, …) are told on standard error.
        let bar = ProgressBar::hidden();
        let told = std::sync::atomic::AtomicU64::new(0);
        // Ctrl-C aborts the motion; the handlers are the default again at the prompt.
        let signals = kerf_rt::Signals::install()
            .map_err(|e| error(format!("kerf: error: cannot handle signals: {e}")))?;
        let interrupted = |client: &mut Client, signal: i32| {
            let _ = client.command(ControlCommand::Abort);
            let failure = Failure::Error(format!(
                "{name}: error: interrupted; the motion was aborted"
            ));
            LineFailure {
                failure,
                // SIGTERM ends the session; Ctrl-C only the line.
                fatal: signal != SIGINT,
            }
        };
        sender
            .send(MoveMsg::begin(id, start, 0))
            .map_err(client_failure)?;
        let window = status.window_items.max(1);
        let mut acked = 0u64;
        let mut seq = 0u64;
        for item in items {
            seq += 1;
            while sender.sent - acked >= window {
                if let Some(signal) = signals.stop_requested() {
                    return Err(interrupted(client, signal));
                }
                let s = live_status(client, &mut watch, &mut reader)?;
                check_program_state(client, &mut watch, &mut reader, &s, id, &name, &machine)?;
                if s.program_id == id {
                    acked = s.moves_received;
                }
                watch.take(&mut reader)?;
                if sender.sent - acked >= window {
                    std::thread::sleep(Duration::from_micros(500));
                }
            }
            sender
                .send(MoveMsg::from_item(id, seq, item))
                .map_err(client_failure)?;
        }
        sender.send(MoveMsg::end(id, seq)).map_err(client_failure)?;
        loop {
            watch.take(&mut reader)?;
            let s = live_status(client, &mut watch, &mut reader)?;
            if let Some(signal) = signals.stop_requested() {
                return Err(interrupted(client, signal));
            }
            if s.program_id == id {
                tell_pause(&bar, &told, &s)?;
            }
            if s.program_id == id && s.program_end != PROGRAM_END_NONE {
                while watch.last_seq < s.cycles {
                    std::thread::sleep(Duration::from_millis(1));
                    watch.take(&mut reader)?;
                }
                check_program_state(client, &mut watch, &mut reader, &s, id, &name, &machine)?;
                if let Some(r) = watch.recording.take() {
                    r.finish()?;
                }
                if scan.moves > 0 {
                    scan.check_end(&s.position_mm_deg)
                        .map_err(|e| error(format!("{name}: error: {e}")))?;
                }
                return Ok(());
            }
            check_program_state(client, &mut watch, &mut reader, &s, id, &name, &machine)?;
            std::thread::sleep(STATUS_EVERY);
        }
    }

    /// Writes the parameter file and the tool table when line `n` changed them.
    fn persist(&mut self, n: u32) -> Result<(), LineFailure> {
        let params = self.interp.persistent_parameters();
        if params != self.saved_parameters {
            self.config.save_machine_parameters(&params).map_err(|e| {
                error(format!(
                    "{}: error: cannot write the parameter file after line {n}: {e}",
                    self.config.machine_parameter_file().display()
                ))
            })?;
            self.saved_parameters = params;
        }
        let tools = self.interp.tools();
        let changed: Vec<Tool> = tools
            .iter()
            .filter(|t| !self.saved_tools.contains(t))
            .copied()
            .collect();
        if !changed.is_empty() {
            self.config
                .save_machine_tools(&changed)
                .map_err(|e| error(format!("{e} (after line {n})")))?;
            self.saved_tools = tools.to_vec();
        }
        Ok(())
    }
}

/// The signal number of Ctrl-C (SIGINT) on Linux.
const SIGINT: i32 = 2;

/// The interpreter of a session reading the typed lines.
type MdiInterpreter = Interpreter<BufReader<Typed>>;

/// An interpreter in the state a program starts in on the machine (its parameters, tool
/// table, position and tool in the spindle), reading `typed`; with the tool table it
/// starts with.
fn fresh(
    config: &Config,
    dialect: Dialect,
    status: &StatusMsg,
    typed: &Typed,
) -> Result<(MdiInterpreter, Vec<Tool>), Failure> {
    let mut settings: Settings = config
        .machine_settings()
        .map_err(|e| Failure::Error(e.to_string()))?;
    settings.start_mm_deg = status.position_mm_deg;
    settings.tool_in_spindle = (status.tool_in_spindle != 0).then_some(status.tool_in_spindle);
    settings.block_delete = status.switches & kerf_proto::SWITCH_BLOCK_DELETE != 0;
    settings.mdi = true;
    let tools = settings.tools.clone();
    let mut interp = Interpreter::new(BufReader::new(typed.clone()), dialect, settings);
    interp.set_input_wait(Box::new(LastInput {
        machine: config.machine.clone(),
    }));
    Ok((interp, tools))
}

/// `#5399` after an `M66` line: each line has run to its end before the next is read, so
/// the machine's last input result is that wait's.
struct LastInput {
    machine: String,
}

impl kerf_gcode::InputWait for LastInput {
    fn wait(&mut self, _event: &kerf_gcode::Event) -> Result<f64, String> {
        let mut client = Client::connect(&self.machine).map_err(|e| e.to_string())?;
        let s = client.status().map_err(|e: ClientError| e.to_string())?;
        Ok(s.input_result_value)
    }
}

/// Where the session's lines come from: a line editor on a terminal, else standard input
/// line by line (no prompt).
enum Input {
    Editor(Box<rustyline::DefaultEditor>),
    Lines(io::Lines<io::StdinLock<'static>>),
}

impl Input {
    fn open() -> Result<Input, Failure> {
        if io::stdin().is_terminal() {
            let editor = rustyline::DefaultEditor::new().map_err(|e| {
                Failure::Error(format!("kerf: error: cannot open the line editor: {e}"))
            })?;
            Ok(Input::Editor(Box::new(editor)))
        } else {
            Ok(Input::Lines(io::stdin().lock().lines()))
        }
    }

    /// The next line; `None` at the end (Ctrl-D, end of input). Ctrl-C at the prompt
    /// drops what was typed.
    fn read(&mut self, prompt: &str) -> Result<Option<String>, Failure> {
        match self {
            Input::Editor(editor) => loop {
                match editor.readline(prompt) {
                    Ok(line) => {
                        if !line.trim().is_empty() {
                            let _ = editor.add_history_entry(line.as_str());
                        }
                        return Ok(Some(line));
                    }
                    Err(rustyline::error::ReadlineError::Interrupted) => continue,
                    Err(rustyline::error::ReadlineError::Eof) => return Ok(None),
                    Err(e) => {
                        return Err(Failure::Error(format!("kerf: error: reading a line: {e}")));
                    }
                }
            },
            Input::Lines(lines) => match lines.next() {
                Some(Ok(line)) => Ok(Some(line)),
                Some(Err(e)) => Err(Failure::Error(format!(
                    "<stdin>: error: cannot read a line: {e}"
                ))),
                None => Ok(None),
            },
        }
    }
}
