//! Programs and MDI lines run from the page or the API: an uploaded program is kept in the
//! machine's program directory (`Config::machine_program_directory`) and run by `kerf run`
//! itself, an MDI line by `kerf mdi LINE`, as a child process of `kerf serve`, so that
//! what is sent through the API is checked, streamed, paused and reported exactly as from
//! a terminal. One job at a time; its state, exit code and what the child said on standard
//! error (its errors as `FILE:LINE:COL: error: …`, `mdi:1:COL: error: …`) are the API's
//! `GET /api/v1/job`.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::{Arc, Mutex};

use super::link::json_string;

/// The largest program accepted, bytes.
pub const PROGRAM_LIMIT: usize = 64 * 1024 * 1024;

/// Lines of `kerf run`'s standard error kept per job (the last ones).
const MESSAGE_LINES: usize = 200;

/// The longest MDI line accepted, bytes (LinuxCNC's interpreter reads lines of up to 256).
pub const MDI_LINE_LIMIT: usize = 256;

/// What a job runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JobKind {
    /// A program, by `kerf run`.
    Program,
    /// One MDI line, by `kerf mdi LINE`.
    Mdi,
}

impl JobKind {
    fn name(self) -> &'static str {
        match self {
            JobKind::Program => "program",
            JobKind::Mdi => "mdi",
        }
    }
}

/// Where a job stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JobState {
    /// `kerf run` runs: checking, streaming, waiting for the machine to finish.
    Running,
    /// It exited 0: the program was really done.
    Finished,
    /// It exited otherwise: refused, failed, aborted, or stopped by a fault.
    Failed,
}

impl JobState {
    fn name(self) -> &'static str {
        match self {
            JobState::Running => "running",
            JobState::Finished => "finished",
            JobState::Failed => "failed",
        }
    }
}

/// One job.
#[derive(Debug, Clone)]
pub struct Job {
    /// Counts the jobs since `kerf serve` started, from 1.
    pub id: u64,
    /// What it runs.
    pub kind: JobKind,
    /// The program's file name, or the MDI line.
    pub name: String,
    /// Where it stands.
    pub state: JobState,
    /// `kerf run`'s exit code once it exited (None: killed by a signal).
    pub exit_code: Option<i32>,
    /// The last lines `kerf run` wrote on standard error.
    pub messages: Vec<String>,
    /// Its toolpath as the API's JSON ([`super::toolpath`]), once computed.
    pub toolpath: Option<Arc<String>>,
    /// The child process's id.
    pub pid: u32,
    /// The program's lines (an MDI line: 1), for its progress.
    pub lines: u32,
}

/// How many lines `text` has (a last line without its newline counts).
pub fn line_count(text: &[u8]) -> u32 {
    let newlines = text.iter().filter(|b| **b == b'\n').count();
    let unterminated = usize::from(!text.is_empty() && !text.ends_with(b"\n"));
    u32::try_from(newlines + unterminated).unwrap_or(u32::MAX)
}

/// The jobs of one `kerf serve`.
#[derive(Clone)]
pub struct Jobs {
    machine: kerf_config::Config,
    kerf: PathBuf,
    config: Option<PathBuf>,
    directory: PathBuf,
    current: Arc<Mutex<Option<Job>>>,
}

/// Why a program was not started.
#[derive(Debug, PartialEq, Eq)]
pub enum StartRefused {
    /// A job runs already.
    Busy(u64),
    /// The name is not a plain file name.
    Name(String),
    /// The MDI line is empty, too long or more than one line.
    Line(String),
    /// The program could not be kept or `kerf run` not started.
    Io(String),
}

/// Whether `name` is a plain file name: 1 to 100 of `A-Z a-z 0-9 . _ -`, not starting
/// with a dot.
pub fn valid_name(name: &str) -> bool {
    (1..=100).contains(&name.len())
        && !name.starts_with('.')
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'.' | b'_' | b'-'))
}

impl Jobs {
    /// Jobs on the machine of `machine`, run by the `kerf` binary at `kerf` with `--config
    /// config` (none: its default), their programs kept in `directory`.
    pub fn new(
        machine: kerf_config::Config,
        kerf: PathBuf,
        config: Option<PathBuf>,
        directory: PathBuf,
    ) -> Jobs {
        Jobs {
            machine,
            kerf,
            config,
            directory,
            current: Arc::new(Mutex::new(None)),
        }
    }

    /// The current (or last) job.
    pub fn current(&self) -> Option<Job> {
        self.current.lock().map(|j| j.clone()).unwrap_or(None)
    }

    /// Keeps `text` as `name` and starts `kerf run` on it, the machine standing at `start`
    /// (machine mm, where its toolpath begins); the new job's id.
    pub fn start(&self, name: &str, text: &[u8], start: [f64; 3]) -> Result<u64, StartRefused> {
        if !valid_name(name) {
            return Err(StartRefused::Name(name.to_owned()));
        }
        let mut current = self.idle()?;
        let path = self.keep(name, text).map_err(StartRefused::Io)?;
        let mut args = vec![std::ffi::OsString::from("run")];
        if let Some(c) = &self.config {
            args.extend(["--config".into(), c.clone().into_os_string()]);
        }
        args.push(path.into_os_string());
        let id = self.spawn(
            &mut current,
            JobKind::Program,
            name,
            line_count(text),
            &args,
        )?;
        // The toolpath for the page, beside the run.
        let (machine, program, text, state) = (
            self.machine.clone(),
            name.to_owned(),
            text.to_vec(),
            Arc::clone(&self.current),
        );
        std::thread::Builder::new()
            .name("kerf-serve-toolpath".into())
            .spawn(move || {
                let (lines, error) = super::toolpath::toolpath(&machine, &program, &text, start);
                let json = Arc::new(super::toolpath::toolpath_json(&lines, error.as_deref()));
                if let Ok(mut j) = state.lock()
                    && let Some(j) = j.as_mut()
                    && j.id == id
                {
                    j.toolpath = Some(json);
                }
            })
            .map_err(|e| StartRefused::Io(e.to_string()))?;
        Ok(id)
    }

    /// Starts `kerf mdi LINE` (the machine's dialect, offsets and tool; its modal state
    /// starts as a program's does); the new job's id.
    pub fn start_mdi(&self, line: &str) -> Result<u64, StartRefused> {
        // One line: no line break, nor another control character but the tab.
        let controls = line.chars().any(|c| c.is_control() && c != '\t');
        if line.trim().is_empty() || line.len() > MDI_LINE_LIMIT || controls {
            return Err(StartRefused::Line(format!(
                "an MDI line is one line of 1 to {MDI_LINE_LIMIT} bytes without control characters"
            )));
        }
        let mut current = self.idle()?;
        let mut args = vec![std::ffi::OsString::from("mdi")];
        if let Some(c) = &self.config {
            args.extend(["--config".into(), c.clone().into_os_string()]);
        }
        // After `--`, a line starting with `-` is the line, not an option.
        args.extend(["--".into(), line.into()]);
        self.spawn(&mut current, JobKind::Mdi, line, 1, &args)
    }

    /// The job state, locked, when no job runs.
    fn idle(&self) -> Result<std::sync::MutexGuard<'_, Option<Job>>, StartRefused> {
        let current = self
            .current
            .lock()
            .map_err(|_| StartRefused::Io("the job state is poisoned".into()))?;
        if let Some(j) = current.as_ref()
            && j.state == JobState::Running
        {
            return Err(StartRefused::Busy(j.id));
        }
        Ok(current)
    }

    /// Starts this binary with `args` as the next job in `current`, and a thread that
    /// keeps what it says and its exit; the job's id.
    fn spawn(
        &self,
        current: &mut Option<Job>,
        kind: JobKind,
        name: &str,
        lines: u32,
        args: &[std::ffi::OsString],
    ) -> Result<u64, StartRefused> {
        let mut child = Command::new(&self.kerf)
            .args(args)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| StartRefused::Io(format!("cannot start {}: {e}", self.kerf.display())))?;
        let id = current.as_ref().map_or(1, |j| j.id + 1);
        *current = Some(Job {
            id,
            kind,
            name: name.to_owned(),
            state: JobState::Running,
            exit_code: None,
            messages: Vec::new(),
            toolpath: None,
            pid: child.id(),
            lines,
        });
        let stderr = child.stderr.take();
        let state = Arc::clone(&self.current);
        std::thread::Builder::new()
            .name("kerf-serve-job".into())
            .spawn(move || {
                if let Some(err) = stderr {
                    for line in BufReader::new(err).lines().map_while(Result::ok) {
                        if let Ok(mut j) = state.lock()
                            && let Some(j) = j.as_mut()
                        {
                            if j.messages.len() == MESSAGE_LINES {
                                j.messages.remove(0);
                            }
                            j.messages.push(line);
                        }
                    }
                }
                let exit = child.wait().ok().and_then(|s| s.code());
                if let Ok(mut j) = state.lock()
                    && let Some(j) = j.as_mut()
                {
                    j.exit_code = exit;
                    j.state = if exit == Some(0) {
                        JobState::Finished
                    } else {
                        JobState::Failed
                    };
                }
            })
            .map_err(|e| StartRefused::Io(e.to_string()))?;
        Ok(id)
    }

    /// Stops the running job, if any, as `kerf serve` stops: its `kerf run` (or `kerf mdi`)
    /// is sent SIGTERM, so it aborts the motion on the daemon's jerk-limited stop and
    /// exits, as it does at Ctrl-C; waits up to `patience` for that. The job as it ended
    /// (or still stood), None when none ran.
    pub fn stop_running(&self, patience: std::time::Duration) -> Option<Job> {
        let pid = match self.current() {
            Some(j) if j.state == JobState::Running => j.pid,
            _ => return None,
        };
        let _ = kerf_rt::terminate(pid);
        let deadline = std::time::Instant::now() + patience;
        loop {
            let job = self.current()?;
            if job.state != JobState::Running || std::time::Instant::now() >= deadline {
                return Some(job);
            }
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
    }

    /// Writes `text` to `name` in the program directory (through a temporary file renamed
    /// over it, so `kerf run` never reads half a file); its path.
    fn keep(&self, name: &str, text: &[u8]) -> Result<PathBuf, String> {
        let fail = |e: std::io::Error, what: &Path| format!("{}: {e}", what.display());
        std::fs::create_dir_all(&self.directory).map_err(|e| fail(e, &self.directory))?;
        let path = self.directory.join(name);
        let partial = self.directory.join(format!(".{name}.partial"));
        std::fs::write(&partial, text).map_err(|e| fail(e, &partial))?;
        std::fs::rename(&partial, &path).map_err(|e| fail(e, &path))?;
        Ok(path)
    }
}

/// A job as the API's JSON: `{"id":…,"kind":…,"name":…,"lines":…,"state":…,
/// "exit_code":…,"messages":[…]}`, `null` before the first.
pub fn job_json(job: Option<&Job>) -> String {
    let Some(j) = job else {
        return "null".into();
    };
    let messages: Vec<String> = j.messages.iter().map(|m| json_string(m)).collect();
    format!(
        "{{\"id\":{},\"kind\":\"{}\",\"name\":{},\"lines\":{},\"state\":\"{}\",\"exit_code\":{},\"messages\":[{}]}}",
        j.id,
        j.kind.name(),
        json_string(&j.name),
        j.lines,
        j.state.name(),
        j.exit_code.map_or("null".into(), |c| c.to_string()),
        messages.join(",")
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_programs_lines_are_counted_as_an_editor_numbers_them() {
        assert_eq!(line_count(b""), 0);
        assert_eq!(line_count(b"G0 X1"), 1);
        assert_eq!(line_count(b"G0 X1\n"), 1);
        assert_eq!(line_count(b"G0 X1\nG0 X2"), 2);
        assert_eq!(line_count(b"%\nG0 X1\r\nM2\n%\n"), 4);
    }

    #[test]
    fn only_plain_file_names_are_kept() {
        for good in ["part.ngc", "A-1_b.nc", "x"] {
            assert!(valid_name(good), "{good}");
        }
        for bad in [
            "",
            ".hidden",
            "../etc/passwd",
            "a/b.ngc",
            "a b.ngc",
            "é.ngc",
            &"x".repeat(101),
        ] {
            assert!(!valid_name(bad), "{bad}");
        }
    }
}
