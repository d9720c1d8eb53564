//! `kerfd` refuses what it cannot run before it creates anything: a period outside the
//! daemon's range, a configuration that does not load, a second daemon for one machine.

use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

fn unique(tag: &str) -> String {
    use std::sync::atomic::{AtomicU32, Ordering};
    static N: AtomicU32 = AtomicU32::new(0);
    format!(
        "kcli{}_{}_{}",
        std::process::id(),
        tag,
        N.fetch_add(1, Ordering::Relaxed)
    )
}

/// A configuration file for a machine of its own, removed on drop.
struct TempConfig {
    dir: PathBuf,
    path: PathBuf,
    machine: String,
}

impl TempConfig {
    fn new(tag: &str, edit: impl Fn(String) -> String) -> TempConfig {
        let machine = unique(tag);
        let dir = std::env::temp_dir().join(&machine);
        std::fs::create_dir_all(&dir).unwrap();
        let base = include_str!("../../../config/kerf.toml")
            .replace("machine = \"default\"", &format!("machine = \"{machine}\""));
        let path = dir.join("kerf.toml");
        std::fs::write(&path, edit(base)).unwrap();
        TempConfig { dir, path, machine }
    }
}

impl Drop for TempConfig {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// Stops the daemon on drop with SIGTERM, so that it removes its shared memory; SIGKILL
/// only if it does not exit.
struct Guard(Child);

impl Drop for Guard {
    fn drop(&mut self) {
        let _ = Command::new("kill")
            .args(["-TERM", &self.0.id().to_string()])
            .status();
        let start = Instant::now();
        while start.elapsed() < Duration::from_secs(10) {
            if let Ok(Some(_)) = self.0.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn kerfd(config: &TempConfig) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_kerfd"));
    c.arg("--config").arg(&config.path);
    c
}

fn kerf(args: &[&str], config: &TempConfig) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_kerf"))
        .args(args)
        .arg("--config")
        .arg(&config.path)
        .output()
        .unwrap()
}

/// Waits (bounded, only to avoid a hang) until `kerf status` answers.
fn wait_ready(config: &TempConfig) {
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(30) {
        if kerf(&["status"], config).status.success() {
            return;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    panic!("kerfd for {} never answered", config.machine);
}

#[test]
fn a_period_outside_the_daemons_range_is_refused_before_anything_starts() {
    for period in ["50", "100", "20000"] {
        let config = TempConfig::new("period", |t| {
            t.replace("period_us = 1000", &format!("period_us = {period}"))
        });
        let out = kerfd(&config).output().unwrap();
        assert_eq!(out.status.code(), Some(1), "period {period}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains("period_us") && err.contains("125 to 10000"),
            "period {period}: {err}"
        );
        // Nothing was created: no daemon answers for the machine.
        let status = kerf(&["status"], &config);
        assert_eq!(status.status.code(), Some(1));
    }
}

#[test]
fn a_configuration_that_does_not_load_is_named() {
    let out = Command::new(env!("CARGO_BIN_EXE_kerfd"))
        .args(["--config", "/nonexistent/kerf.toml"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("/nonexistent/kerf.toml"), "{err}");
}

#[test]
fn a_second_daemon_or_an_embedded_run_for_the_same_machine_is_refused() {
    let config = TempConfig::new("twice", |t| t);
    let _first = Guard(
        kerfd(&config)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap(),
    );
    wait_ready(&config);
    let out = kerfd(&config).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("already running") && err.contains(&config.machine),
        "{err}"
    );
    let out = kerf(
        &["run", "--embedded", "../../config/examples/quickstart.ngc"],
        &config,
    );
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("already running"), "{err}");
    // The first one still serves.
    assert!(kerf(&["status"], &config).status.success());
}

#[test]
fn no_daemon_is_exit_1_naming_the_machine_for_every_command() {
    let config = TempConfig::new("none", |t| t);
    for args in [
        &["status"][..],
        &["status", "--json"],
        &["hold"],
        &["resume"],
        &["abort"],
        &["override", "50"],
        &["run", "../../config/examples/quickstart.ngc"],
        &["record", "--out", "/dev/null", "--cycles", "1"],
    ] {
        let out = kerf(args, &config);
        assert_eq!(out.status.code(), Some(1), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains(&config.machine) && err.contains("kerfd"),
            "{args:?}: {err}"
        );
    }
}

#[test]
fn a_daemon_killed_while_it_starts_leaves_nothing_that_stops_the_next() {
    let config = TempConfig::new("startkill", |t| t);
    // SIGKILL at staggered moments of the start-up: some before, some while, some after
    // the services are created.
    for i in 0..24u64 {
        let mut child = kerfd(&config)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(Duration::from_millis(2 + 4 * i));
        let _ = child.kill();
        let _ = child.wait();
    }
    // Files a killed creator left count as abandoned after 100 ms.
    std::thread::sleep(kerf::ipc::UNFINISHED_AFTER * 2);
    let log = config.dir.join("kerfd.log");
    let mut daemon = Guard(
        kerfd(&config)
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(&log).unwrap())
            .spawn()
            .unwrap(),
    );
    let start = Instant::now();
    while !kerf(&["status"], &config).status.success() {
        let exited = daemon.0.try_wait().unwrap();
        assert!(
            exited.is_none() && start.elapsed() < Duration::from_secs(30),
            "kerfd did not start ({exited:?}): {}\n{}",
            std::fs::read_to_string(&log).unwrap_or_default(),
            listing()
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    let program = config.dir.join("short.ngc");
    std::fs::write(&program, "G21 G90\nG1 X2 Y1 F3000\nG0 X0 Y0\nM2\n").unwrap();
    let out = kerf(&["run", program.to_str().unwrap()], &config);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// iceoryx2's files, for a failure message.
fn listing() -> String {
    let mut out = String::new();
    for dir in ["/tmp/iceoryx2/services", "/tmp/iceoryx2/nodes", "/dev/shm"] {
        let mut stack = vec![PathBuf::from(dir)];
        while let Some(d) = stack.pop() {
            for e in std::fs::read_dir(&d).into_iter().flatten().flatten() {
                let m = e.metadata().unwrap();
                if m.is_dir() {
                    stack.push(e.path());
                }
                out.push_str(&format!("{} {}\n", e.path().display(), m.len()));
            }
        }
    }
    out
}
