//! Test fixture: a private network namespace with a veth pair (`ecatA` for the
//! MainDevice, `ecatB` for the emulator), the emulator process running in it, and a way to
//! run a thread inside it. Everything is removed on drop, even after a failed assertion.

use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// Interface of the MainDevice's side.
pub use kerf_testkit::netns::MAIN_IF;
/// Interface of the emulator's side.
pub use kerf_testkit::netns::NETWORK_IF as SIM_IF;

/// A namespace with the veth pair up (`kerf_testkit::netns`), and the emulator in it.
pub struct Netns {
    /// The emulator, stopped on drop before the namespace is removed.
    emulator: Option<Child>,
    ns: kerf_testkit::netns::Netns,
}

impl Netns {
    /// Creates the namespace and the veth pair; panics with the reason where it cannot
    /// (this test needs root and `ip`: it fails rather than passing silently).
    pub fn new() -> Netns {
        Netns {
            emulator: None,
            ns: kerf_testkit::netns::Netns::new("kerf-ecs"),
        }
    }

    /// Starts the emulator in the namespace with these arguments (after `--interface
    /// ecatB`) and waits until it says it is listening.
    pub fn start_emulator(&mut self, args: &[&str]) {
        let mut child = self
            .ns
            .command(env!("CARGO_BIN_EXE_kerf-ecat-sim"))
            .args(["--interface", SIM_IF])
            .args(args)
            .stdin(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("cannot start the emulator");
        let stderr = child.stderr.take().expect("piped stderr");
        self.emulator = Some(child);
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stderr).lines().map_while(Result::ok) {
                eprintln!("[emulator] {line}");
                let _ = tx.send(line);
            }
        });
        let deadline = Instant::now() + Duration::from_secs(30);
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match rx.recv_timeout(left) {
                Ok(line) if line.contains(" on ") => break,
                Ok(_) => {}
                Err(_) => panic!("the emulator did not report it was listening within 30 s"),
            }
        }
    }

    /// Takes the emulator's standard input (its control commands).
    pub fn take_emulator_stdin(&mut self) -> std::process::ChildStdin {
        self.emulator
            .as_mut()
            .and_then(|c| c.stdin.take())
            .expect("emulator running, stdin not taken yet")
    }

    /// Runs `f` on a new thread that has joined the namespace (threads it spawns are in
    /// it too) and returns its result, re-raising its panic.
    pub fn run_inside<T: Send + 'static>(&self, f: impl FnOnce() -> T + Send + 'static) -> T {
        let path = format!("/var/run/netns/{}", self.ns.name());
        std::thread::spawn(move || {
            let file = std::fs::File::open(&path).expect("open the namespace");
            nix::sched::setns(&file, nix::sched::CloneFlags::CLONE_NEWNET)
                .expect("setns into the namespace");
            f()
        })
        .join()
        .unwrap_or_else(|e| std::panic::resume_unwind(e))
    }

    /// Stops the emulator with SIGTERM and returns whether it exited successfully.
    pub fn stop_emulator(&mut self) -> bool {
        let Some(mut child) = self.emulator.take() else {
            return false;
        };
        // `ip netns exec` execs the emulator, so the child's pid is the emulator's.
        let _ = Command::new("kill")
            .args(["-TERM", &child.id().to_string()])
            .status();
        let deadline = Instant::now() + Duration::from_secs(10);
        while Instant::now() < deadline {
            if let Ok(Some(status)) = child.try_wait() {
                return status.success();
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = child.kill();
        false
    }
}

impl Drop for Netns {
    fn drop(&mut self) {
        // Reaped here; the namespace (dropped after) kills whatever else runs inside.
        if let Some(mut child) = self.emulator.take() {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}
