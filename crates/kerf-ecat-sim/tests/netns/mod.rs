//! Test fixture: a private network namespace with a veth pair (`ecatA` for the
//! MainDevice, `ecatB` for the emulator), the emulator process running in it, its control
//! (standard input, and the answers to `state` on its standard output), and a way to run
//! a thread inside it. Everything is removed on drop, even after a failed assertion.
// Each test binary uses part of the fixture.
#![allow(dead_code)]

use std::io::{BufRead, BufReader, Write};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc::{self, Receiver};
use std::time::{Duration, Instant};

/// Interface of the MainDevice's side.
pub use kerf_testkit::netns::MAIN_IF;
/// Interface of the emulator's side.
pub use kerf_testkit::netns::NETWORK_IF as SIM_IF;

/// A namespace with the veth pair up (`kerf_testkit::netns`), and the emulator in it.
pub struct Netns {
    /// The emulator, stopped on drop before the namespace is removed.
    emulator: Option<Child>,
    /// The lines of the emulator's standard output.
    emulator_stdout: Option<Receiver<String>>,
    ns: kerf_testkit::netns::Netns,
}

/// The emulator's control: commands to its standard input, the answers to `state` from
/// its standard output.
pub struct Control {
    stdin: ChildStdin,
    stdout: Receiver<String>,
}

impl Control {
    /// Sends one command line.
    pub fn send(&mut self, command: &str) {
        writeln!(self.stdin, "{command}").expect("the emulator's standard input");
    }

    /// Sends `state` and returns its answer, `count` lines (the subdevices on the line);
    /// since the emulator handles its commands in order, the commands sent before have
    /// been carried out.
    pub fn state(&mut self, count: usize) -> Vec<String> {
        self.send("state");
        let deadline = Instant::now() + Duration::from_secs(10);
        (0..count)
            .map(|n| {
                let left = deadline.saturating_duration_since(Instant::now());
                self.stdout
                    .recv_timeout(left)
                    .unwrap_or_else(|e| panic!("line {n} of the answer to `state`: {e}"))
            })
            .collect()
    }
}

/// The value of `key` in a `state` line (`key=value` fields separated by spaces).
pub fn field<'a>(line: &'a str, key: &str) -> &'a str {
    line.split(' ')
        .find_map(|word| word.strip_prefix(key)?.strip_prefix('='))
        .unwrap_or_else(|| panic!("no {key}= in {line:?}"))
}

impl Netns {
    /// Creates the namespace and the veth pair; panics with the reason where it cannot
    /// (this test needs root and `ip`: it fails rather than passing silently).
    pub fn new() -> Netns {
        let ns = Netns {
            emulator: None,
            emulator_stdout: None,
            ns: kerf_testkit::netns::Netns::new("kerf-ecs"),
        };
        ns.wait_until_up();
        ns
    }

    /// Waits until both ends of the veth pair are operationally up: the kernel marks
    /// them so, and starts their transmit queues, a moment after they are set up (later
    /// on a busy machine), and frames sent before are dropped.
    fn wait_until_up(&self) {
        let deadline = Instant::now() + Duration::from_secs(10);
        for interface in [MAIN_IF, SIM_IF] {
            loop {
                let out = Command::new("ip")
                    .args(["-n", self.ns.name(), "-o", "link", "show", "dev", interface])
                    .output()
                    .expect("run ip link show");
                let text = String::from_utf8_lossy(&out.stdout);
                if text.contains("state UP") {
                    break;
                }
                assert!(
                    Instant::now() < deadline,
                    "{interface} is not up after 10 s: {text}"
                );
                std::thread::sleep(Duration::from_millis(10));
            }
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
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("cannot start the emulator");
        let stderr = child.stderr.take().expect("piped stderr");
        let stdout = child.stdout.take().expect("piped stdout");
        let (out_tx, out_rx) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                eprintln!("[emulator stdout] {line}");
                let _ = out_tx.send(line);
            }
        });
        self.emulator_stdout = Some(out_rx);
        self.emulator = Some(child);
        let (tx, rx) = mpsc::channel();
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
    pub fn take_emulator_stdin(&mut self) -> ChildStdin {
        self.emulator
            .as_mut()
            .and_then(|c| c.stdin.take())
            .expect("emulator running, stdin not taken yet")
    }

    /// Takes the emulator's control: its standard input and output.
    pub fn take_emulator_control(&mut self) -> Control {
        let stdin = self.take_emulator_stdin();
        let stdout = self
            .emulator_stdout
            .take()
            .expect("emulator running, stdout not taken yet");
        Control { stdin, stdout }
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

/// A MainDevice on [`MAIN_IF`] (the caller runs inside the namespace) with the tests'
/// generous timeouts (a busy two-core machine), its frames moved by ethercrab's own
/// TX/RX task on a thread of its own. `storage` can be split once.
pub fn maindevice<const FRAMES: usize, const FRAME_BYTES: usize>(
    storage: &'static ethercrab::PduStorage<FRAMES, FRAME_BYTES>,
) -> ethercrab::MainDevice<'static> {
    let (tx, rx, pdu_loop) = storage.try_split().expect("split once");
    let timeouts = ethercrab::Timeouts {
        state_transition: Duration::from_secs(10),
        pdu: Duration::from_millis(200),
        eeprom: Duration::from_millis(500),
        wait_loop_delay: Duration::from_millis(1),
        mailbox_echo: Duration::from_millis(500),
        mailbox_response: Duration::from_millis(1000),
    };
    let maindevice =
        ethercrab::MainDevice::new(pdu_loop, timeouts, ethercrab::MainDeviceConfig::default());
    // Kerf's own pump, not ethercrab's `tx_rx_task`: that task ends at the first late
    // answer to a frame already given up (a refused transition's last read, on a busy
    // machine), and every exchange after it times out. The pump counts such an answer
    // and goes on, as the daemon does.
    let socket = kerf_ethercat::socket::RawSocket::open(MAIN_IF).expect("raw socket");
    std::thread::spawn(move || {
        let mut pump = kerf_ethercat::pump::Pump::new(socket, tx, rx);
        // Runs for the rest of the test process: nothing to wait for but the frames.
        while let Err(kerf_ethercat::pump::PumpError::Timeout { .. }) =
            pump.block_on(std::future::pending::<()>(), Duration::from_secs(3600))
        {}
    });
    maindevice
}
