//! What the tests that start `kerf` and `kerfd` as processes share: where `kerfd` is,
//! and a child process that cleans up after itself.
#![allow(dead_code)]

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

/// The `kerfd` binary beside `kerf` in the target directory. It belongs to the `kerfd`
/// package, whose binary cargo builds for the workspace's tests (`cargo test --workspace`)
/// but not for `cargo test -p kerf` alone: then this fails and says so.
pub fn kerfd() -> &'static str {
    static PATH: OnceLock<String> = OnceLock::new();
    PATH.get_or_init(|| {
        let path = Path::new(env!("CARGO_BIN_EXE_kerf")).with_file_name("kerfd");
        assert!(
            path.is_file(),
            "{} is missing: these tests start the daemon of the `kerfd` package; run \
             `cargo test --workspace`, or `cargo build -p kerfd` before `cargo test -p kerf`",
            path.display()
        );
        path.display().to_string()
    })
}

/// A child process that is stopped (SIGTERM, then SIGKILL) and reaped when dropped, with
/// its standard output and error in files of the test's scratch directory.
pub struct Proc {
    name: String,
    child: Option<Child>,
    /// How it exited, once it has.
    exited: Option<ExitStatus>,
    /// The file of its standard output.
    pub stdout: PathBuf,
    /// The file of its standard error.
    pub stderr: PathBuf,
}

impl Proc {
    /// Starts `command` (standard input closed) with its output in `dir/NAME.stdout` and
    /// `dir/NAME.stderr`.
    pub fn start(name: &str, dir: &Path, mut command: Command) -> Proc {
        let stdout = dir.join(format!("{name}.stdout"));
        let stderr = dir.join(format!("{name}.stderr"));
        let child = command
            .stdin(Stdio::null())
            .stdout(fs::File::create(&stdout).unwrap())
            .stderr(fs::File::create(&stderr).unwrap())
            .spawn()
            .unwrap_or_else(|e| panic!("cannot start {name} ({command:?}): {e}"));
        Proc {
            name: name.to_string(),
            child: Some(child),
            exited: None,
            stdout,
            stderr,
        }
    }

    /// Its process id.
    pub fn pid(&self) -> u32 {
        self.child.as_ref().expect("running").id()
    }

    /// Sends a signal by name (`INT`, `TERM`, `KILL`).
    pub fn signal(&self, signal: &str) {
        let status = Command::new("kill")
            .arg(format!("-{signal}"))
            .arg(self.pid().to_string())
            .status()
            .unwrap();
        assert!(status.success(), "kill -{signal} {} failed", self.name);
    }

    /// `Some(status)` once the process has exited (and been reaped).
    pub fn try_wait(&mut self) -> Option<ExitStatus> {
        if self.exited.is_none() {
            let child = self.child.as_mut().expect("started");
            if let Some(status) = child.try_wait().unwrap() {
                self.exited = Some(status);
                self.child = None;
            }
        }
        self.exited
    }

    /// Waits for the process to exit; panics with its standard error after `patience`.
    pub fn wait_within(&mut self, patience: Duration) -> ExitStatus {
        let deadline = Instant::now() + patience;
        loop {
            if let Some(status) = self.try_wait() {
                return status;
            }
            assert!(
                Instant::now() < deadline,
                "{} did not exit; stderr: {}",
                self.name,
                self.stderr()
            );
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    /// Its standard error so far.
    pub fn stderr(&self) -> String {
        read_text(&self.stderr)
    }
}

impl Drop for Proc {
    /// SIGTERM first, so that a daemon or client removes its shared memory as it exits;
    /// SIGKILL if it has not exited within a few seconds.
    fn drop(&mut self) {
        if let Some(mut child) = self.child.take() {
            if let Ok(None) = child.try_wait() {
                let _ = Command::new("kill")
                    .args(["-TERM", &child.id().to_string()])
                    .status();
                let start = Instant::now();
                while start.elapsed() < Duration::from_secs(5) {
                    if let Ok(Some(_)) = child.try_wait() {
                        return;
                    }
                    std::thread::sleep(Duration::from_millis(10));
                }
            }
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

/// A file's text, empty when it cannot be read.
pub fn read_text(path: &Path) -> String {
    fs::read_to_string(path).unwrap_or_default()
}
