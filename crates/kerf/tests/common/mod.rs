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

/// Upper bound on any wait of a [`MachineEnv`], so that a broken daemon fails a test
/// instead of hanging it.
pub const MACHINE_PATIENCE: Duration = Duration::from_secs(60);

/// One test's machine: a scratch directory `CARGO_TARGET_TMPDIR/GROUP/NAME` holding a copy
/// of the bundled configuration under a machine name of its own, `NAME`, which is also the
/// machine's state directory (`STATE_DIRECTORY` of every command it starts: its parameter
/// file, tool table and state file stay there).
pub struct MachineEnv {
    /// The scratch directory.
    pub dir: PathBuf,
    /// Its configuration file.
    pub config_path: PathBuf,
    /// The machine's name.
    pub machine: String,
}

impl MachineEnv {
    /// The machine `PREFIX<pid>_TAG` in the scratch group `group`; with `homing` the
    /// bundled configuration as it is (it refuses programs until homed), else without its
    /// homing and limit switch tables (`kerf_testkit::config_text::without_homing`).
    pub fn new(group: &str, prefix: &str, tag: &str, homing: bool) -> MachineEnv {
        let machine = format!("{prefix}{}_{tag}", std::process::id());
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
            .join(group)
            .join(&machine);
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let bundled = fs::read_to_string(root.join("config/kerf.toml")).unwrap();
        let text = if homing {
            bundled
        } else {
            kerf_testkit::config_text::without_homing(&bundled)
        };
        let from = "machine = \"default\"";
        assert!(text.contains(from), "config/kerf.toml has no `{from}`");
        let text = text.replacen(from, &format!("machine = \"{machine}\""), 1);
        let config_path = dir.join("kerf.toml");
        fs::write(&config_path, text).unwrap();
        MachineEnv {
            dir,
            config_path,
            machine,
        }
    }

    /// A file of the scratch directory.
    pub fn path(&self, name: &str) -> PathBuf {
        self.dir.join(name)
    }

    /// Writes `text` to the scratch file `name`; its path.
    pub fn write(&self, name: &str, text: &str) -> PathBuf {
        let p = self.path(name);
        fs::write(&p, text).unwrap();
        p
    }

    /// `program ARGS` as a command of this machine (its state directory set).
    pub fn command(&self, program: &str, args: &[&str]) -> Command {
        let mut c = Command::new(program);
        c.args(args).env("STATE_DIRECTORY", &self.dir);
        c
    }

    /// `kerf SUB… --config C ARGS…` (`sub`: the words before the options, such as
    /// `offset set`) as a command of this machine.
    pub fn kerf_command(&self, sub: &[&str], args: &[&str]) -> Command {
        let mut all: Vec<&str> = sub.to_vec();
        all.extend(["--config", self.config_path.to_str().unwrap()]);
        all.extend_from_slice(args);
        self.command(env!("CARGO_BIN_EXE_kerf"), &all)
    }

    /// `kerf SUB… --config C ARGS…` to completion (failed after [`MACHINE_PATIENCE`]).
    pub fn kerf(&self, sub: &[&str], args: &[&str]) -> std::process::Output {
        static RUNS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let n = RUNS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let name = format!("kerf-{}-{n}", sub.join("-"));
        let mut p = Proc::start(&name, &self.dir, self.kerf_command(sub, args));
        let status = p.wait_within(MACHINE_PATIENCE);
        let out = std::process::Output {
            status,
            stdout: fs::read(&p.stdout).unwrap(),
            stderr: fs::read(&p.stderr).unwrap(),
        };
        let _ = fs::remove_file(&p.stdout);
        let _ = fs::remove_file(&p.stderr);
        out
    }

    /// [`MachineEnv::kerf`], asserted to exit 0.
    pub fn kerf_ok(&self, sub: &[&str], args: &[&str]) -> std::process::Output {
        let o = self.kerf(sub, args);
        assert!(
            o.status.success(),
            "kerf {sub:?} {args:?} failed ({}): {}",
            o.status,
            String::from_utf8_lossy(&o.stderr)
        );
        o
    }

    /// Starts `kerfd --config C` as `name` and waits until its drives are enabled.
    pub fn start_daemon(&self, name: &str) -> Proc {
        self.start_daemon_with(name, &[])
    }

    /// Starts `kerfd --config C EXTRA…` as `name` and waits until its drives are enabled.
    pub fn start_daemon_with(&self, name: &str, extra: &[&str]) -> Proc {
        let mut args = vec!["--config", self.config_path.to_str().unwrap()];
        args.extend_from_slice(extra);
        let mut d = Proc::start(name, &self.dir, self.command(kerfd(), &args));
        let deadline = Instant::now() + MACHINE_PATIENCE;
        loop {
            if let Some(status) = d.try_wait() {
                panic!("kerfd exited at start ({status}): {}", d.stderr());
            }
            let o = self.kerf(&["status"], &["--json"]);
            if o.status.success()
                && serde_json::from_slice::<serde_json::Value>(&o.stdout)
                    .is_ok_and(|s| s["drives"] == "running")
            {
                return d;
            }
            assert!(
                Instant::now() < deadline,
                "kerfd never got ready: {}",
                d.stderr()
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// `kerf status --json`, parsed.
    pub fn status(&self) -> serde_json::Value {
        let o = self.kerf_ok(&["status"], &["--json"]);
        serde_json::from_slice(&o.stdout)
            .unwrap_or_else(|e| panic!("not JSON ({e}): {}", String::from_utf8_lossy(&o.stdout)))
    }
}
