//! The EtherCAT test bench: the emulated network `kerf-ecat-sim` on one end of a veth pair
//! in a private network namespace, a machine whose X, Y and Z drives are on it, and the
//! daemon on the other end. Shared by the EtherCAT test files (`mod ethercat_bench;`).
//!
//! Needs root and iproute2 (CI runs as root); the namespace fixture fails the test, with
//! the reason, where it cannot make a namespace.

#![allow(dead_code)]

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use kerf_testkit::netns::{MAIN_IF, NETWORK_IF, Netns};

use crate::common::{Proc, kerfd, read_text};

pub const KERF: &str = env!("CARGO_BIN_EXE_kerf");
pub const PATIENCE: Duration = Duration::from_secs(30);

/// The emulator beside `kerf` in the target directory (built by `cargo test --workspace`).
pub fn emulator() -> String {
    let path = Path::new(KERF).with_file_name("kerf-ecat-sim");
    assert!(
        path.is_file(),
        "{} is missing: run `cargo test --workspace` or `cargo build -p kerf-ecat-sim` first",
        path.display()
    );
    path.display().to_string()
}

pub struct Bench {
    pub dir: PathBuf,
    pub config: PathBuf,
    /// The emulator's standard input: its control commands (`mute`, `unmute`, ...).
    pub emulator_stdin: std::process::ChildStdin,
    _emulator: std::process::Child,
    /// Subdevices on the emulated ring.
    pub subdevices: usize,
    /// Declared last: dropped after the processes, it kills what still runs inside.
    pub ns: Netns,
}

impl Bench {
    /// A namespace with the emulator (3 drives and an I/O terminal) and a machine whose
    /// X, Y and Z drives are on it, without distributed clocks.
    pub fn new(tag: &str) -> Bench {
        Bench::with(tag, "dc = false\n", &[])
    }

    /// [`Bench::new`] with `bus` for the `[ethercat]` table's settings (besides the
    /// interface) and `emulator_args` for the emulator.
    pub fn with(tag: &str, bus: &str, emulator_args: &[&str]) -> Bench {
        Bench::with_x_drive(tag, bus, "", emulator_args)
    }

    /// [`Bench::with`] with `x_drive` appended to the X drive's `[[ethercat.drives]]`
    /// table (more keys, e.g. `sdo = [...]`, each line ended by `\n`). The emulator has 3
    /// drives and 1 I/O subdevice unless `emulator_args` gives `--drives` or `--io`.
    pub fn with_x_drive(tag: &str, bus: &str, x_drive: &str, emulator_args: &[&str]) -> Bench {
        Bench::build(
            tag,
            bus,
            x_drive,
            "[[ethercat.io]]\nposition = 3\nvendor_id = 0x4B52\nproduct_code = 0x10\n",
            "",
            emulator_args,
            [("--drives", "3"), ("--io", "1")],
        )
    }

    /// [`Bench::new`] with `io_keys` appended to the I/O terminal's `[[ethercat.io]]`
    /// (e.g. `inputs = { ... }`), `sections` to the machine's configuration (more
    /// tables, e.g. `[axes.x.homing]`) and `emulator_args` for the emulator.
    pub fn with_sections(
        tag: &str,
        io_keys: &str,
        sections: &str,
        emulator_args: &[&str],
    ) -> Bench {
        Bench::build(
            tag,
            "dc = false\n",
            "",
            &format!(
                "[[ethercat.io]]\nposition = 3\nvendor_id = 0x4B52\nproduct_code = 0x10\n{io_keys}"
            ),
            sections,
            emulator_args,
            [("--drives", "3"), ("--io", "1")],
        )
    }

    /// A namespace with the emulator (4 drives and an I/O terminal, the 4th drive's motor
    /// ramping at `velocity_accel_counts_s2` in velocity mode) and a machine whose X, Y and
    /// Z drives are at positions 0 to 2, its spindle's drive (`axis = "s"`, cyclic
    /// synchronous velocity, 10000 counts per revolution) at 3 and its I/O terminal at 4,
    /// without distributed clocks, with a process-data watchdog of 500 ms. The terminal's
    /// bits and the machine's `[io]`:
    ///
    /// | `[io]`                | number | terminal bit |
    /// |-----------------------|--------|--------------|
    /// | output `flood` (M8)   | 1      | output 0     |
    /// | output `clamp`        | 2      | output 1     |
    /// | output `blast`        | 3      | output 5     |
    /// | input `part_present`  | 0      | input 0      |
    /// | input `door_closed`   | 4      | input 1      |
    ///
    /// The spindle: `max_rpm` 12000, `acceleration_rpm_s` 12000, at-speed band 2 %,
    /// `spindle` appended (more `[spindle]` keys). A manual tool changer.
    pub fn machine(tag: &str, spindle: &str, velocity_accel_counts_s2: f64) -> Bench {
        let accel = velocity_accel_counts_s2.to_string();
        Bench::machine_with(tag, spindle, &["--velocity-accel", &accel])
    }

    /// The machine of [`Bench::machine`] on an emulator started with `emulator_args` (4
    /// drives and 1 I/O subdevice unless they say otherwise).
    pub fn machine_on(tag: &str, emulator_args: &[&str]) -> Bench {
        Bench::machine_with(tag, "", emulator_args)
    }

    fn machine_with(tag: &str, spindle: &str, emulator_args: &[&str]) -> Bench {
        Bench::build(
            tag,
            // These tests are about the machine on the bus, not about the load: a debug
            // build on a busy two-core machine stalls for tens of ms now and then, which
            // the default 20 ms watchdog would take for a lost master.
            "dc = false\nwatchdog_us = 500000\n",
            "",
            "[[ethercat.drives]]\naxis = \"s\"\nposition = 3\nvendor_id = 0x4B52\nproduct_code = 0x402\n\
             [[ethercat.io]]\nposition = 4\nvendor_id = 0x4B52\nproduct_code = 0x10\n\
             inputs = { part_present = 0, door_closed = 1 }\n\
             outputs = { flood = 0, clamp = 1, blast = 5 }\n",
            &format!(
                "\n[io]\ndigital_outputs = [\n    {{ number = 1, name = \"flood\" }},\n    \
                 {{ number = 2, name = \"clamp\" }},\n    {{ number = 3, name = \"blast\" }},\n]\n\
                 digital_inputs = [\n    {{ number = 0, name = \"part_present\" }},\n    \
                 {{ number = 4, name = \"door_closed\" }},\n]\n\
                 \n[spindle]\nkind = \"drive\"\nmax_rpm = 12000.0\nacceleration_rpm_s = 12000.0\n\
                 at_speed_tolerance = 0.02\nat_speed_timeout_s = 10.0\ncounts_per_rev = 10000.0\n{spindle}\
                 \n[coolant]\nflood = \"flood\"\n"
            ),
            emulator_args,
            [("--drives", "4"), ("--io", "1")],
        )
    }

    /// The bench of `config/kerf.toml` (its simulated I/O, spindle, coolant and tool
    /// changer taken out, a manual tool changer) with `bus` for the `[ethercat]` table's
    /// settings, `x_drive` appended to the X drive's table, `ring_tail` the subdevices
    /// after the X, Y and Z drives (`[[ethercat.drives]]`, `[[ethercat.io]]`),
    /// `sections` more tables at the end; the emulator with `emulator_args` and the
    /// `defaults` of the options they do not give.
    fn build(
        tag: &str,
        bus: &str,
        x_drive: &str,
        ring_tail: &str,
        sections: &str,
        emulator_args: &[&str],
        defaults: [(&str, &str); 2],
    ) -> Bench {
        let machine = format!("t{}_{tag}", std::process::id());
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
            .join("kerf-ethercat-tests")
            .join(&machine);
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let mut text = kerf_testkit::config_text::without_homing(
            &fs::read_to_string(root.join("config/kerf.toml")).unwrap(),
        );
        text = text.replacen(
            "machine = \"default\"",
            &format!("machine = \"{machine}\""),
            1,
        );
        // 4 ms: a frame has half a period, 2 ms, to come back. The debug builds of the daemon
        // and of the emulator on a busy two-core machine answer within it (over veth their
        // round trip's 99.9th percentile was 1.5 ms), not within 0.5 ms at 1 ms.
        text = text.replacen("period_us = 1000", "period_us = 4000", 1);
        // The bundled machine's simulated I/O, spindle, coolant and tool changer: on a bus
        // they would be bits and drives of its own, which this bench's bus does not have.
        let io = text
            .find("# Inputs and outputs.")
            .expect("config/kerf.toml's [io]");
        let changer = text
            .find("# The tool change M6")
            .expect("its [tool_changer]");
        let operator = text.find("# The runtime switches").expect("its [operator]");
        // Its automatic tool changer uses the simulated I/O too: a manual one instead.
        text.replace_range(changer..operator, "[tool_changer]\nkind = \"manual\"\n\n");
        text.replace_range(io..changer, "");
        text.push_str(&format!(
            // A debug build on a busy two-core machine misses periods now and then; the
            // drives on the bus keep their own time, so a late cycle is a missed setpoint
            // for them: a stall limit of 50 keeps the test about the bus, not the load;
            // likewise a frame now and then comes back after its half period, so five
            // incomplete exchanges in a row are allowed, not two.
            "\n[safety]\nstall_cycles = 50\n\n[ethercat]\ninterface = \"{MAIN_IF}\"\nmax_missed_cycles = 5\n{bus}\
             [[ethercat.drives]]\naxis = \"x\"\nposition = 0\nvendor_id = 0x4B52\nproduct_code = 0x402\n{x_drive}\
             [[ethercat.drives]]\naxis = \"y\"\nposition = 1\nvendor_id = 0x4B52\nproduct_code = 0x402\n\
             [[ethercat.drives]]\naxis = \"z\"\nposition = 2\nvendor_id = 0x4B52\nproduct_code = 0x402\n\
             {ring_tail}{sections}"
        ));
        let config = dir.join("kerf.toml");
        fs::write(&config, text).unwrap();
        let ns = Netns::new("kerf-e2e");
        // The emulator stands for drives, whose answers never wait for a busy CPU: it runs
        // at a real-time priority (below kerfd's cycle), as root runs these tests.
        let mut c = ns.command("chrt");
        c.args(["-f", "40", &emulator()]);
        c.args(["--interface", NETWORK_IF]);
        let mut subdevices = 0;
        for (option, default) in defaults {
            let value = match emulator_args.iter().position(|a| *a == option) {
                Some(i) => emulator_args[i + 1],
                None => {
                    c.args([option, default]);
                    default
                }
            };
            subdevices += value.parse::<usize>().expect("a number of subdevices");
        }
        c.args(emulator_args);
        let log = dir.join("emulator.stderr");
        let mut emulator = c
            .stdin(std::process::Stdio::piped())
            .stdout(fs::File::create(dir.join("emulator.stdout")).unwrap())
            .stderr(fs::File::create(&log).unwrap())
            .spawn()
            .expect("cannot start the emulator");
        let emulator_stdin = emulator.stdin.take().expect("piped");
        let deadline = Instant::now() + PATIENCE;
        while !read_text(&log).contains(" on ") {
            assert!(
                Instant::now() < deadline,
                "the emulator never said it listens: {}",
                read_text(&log)
            );
            std::thread::sleep(Duration::from_millis(20));
        }
        Bench {
            dir,
            config,
            emulator_stdin,
            _emulator: emulator,
            subdevices,
            ns,
        }
    }

    /// Sends a control line to the emulator.
    pub fn emulator_says(&mut self, line: &str) {
        use std::io::Write;
        writeln!(self.emulator_stdin, "{line}").expect("emulator's stdin");
        self.emulator_stdin.flush().expect("emulator's stdin");
    }

    /// The emulator's `state` answer: one line per subdevice, in ring order, e.g.
    /// `subdevice 0 kind=drive al=OP al_error=0 … cia402=operation_enabled …`.
    pub fn emulator_state(&mut self) -> Vec<String> {
        let path = self.dir.join("emulator.stdout");
        let before = read_text(&path).lines().count();
        self.emulator_says("state");
        let deadline = Instant::now() + PATIENCE;
        loop {
            let text = read_text(&path);
            let lines: Vec<String> = text.lines().skip(before).map(str::to_owned).collect();
            if lines.len() >= self.subdevices {
                return lines[..self.subdevices].to_vec();
            }
            assert!(
                Instant::now() < deadline,
                "the emulator did not answer `state`"
            );
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    /// The value of `field` in an emulator `state` line (`al=OP` → "OP").
    pub fn field<'a>(line: &'a str, field: &str) -> &'a str {
        line.split(' ')
            .find_map(|w| w.strip_prefix(field)?.strip_prefix('='))
            .unwrap_or_else(|| panic!("no {field} in {line}"))
    }

    /// `kerf status --json`, parsed.
    pub fn status(&self) -> serde_json::Value {
        let out = self.kerf(&["status", "--json"]);
        assert!(
            out.status.success(),
            "kerf status: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        serde_json::from_slice(&out.stdout).expect("status JSON")
    }

    pub fn kerf(&self, args: &[&str]) -> std::process::Output {
        Command::new(KERF)
            .args(args)
            .args(["--config", self.config.to_str().unwrap()])
            .output()
            .unwrap()
    }

    /// `kerf status --json` polled until `done` holds (panics after [`PATIENCE`], naming
    /// `what` and the last status).
    pub fn status_until(
        &self,
        what: &str,
        done: impl Fn(&serde_json::Value) -> bool,
    ) -> serde_json::Value {
        let deadline = Instant::now() + PATIENCE;
        loop {
            let s = self.status();
            if done(&s) {
                return s;
            }
            assert!(Instant::now() < deadline, "never {what}: {s}");
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Starts the daemon inside the namespace and waits for it to exit, as it does when
    /// the bus's bring-up is refused: its exit status and standard error. Panics when it
    /// has not exited within [`PATIENCE`].
    pub fn daemon_refused(&self) -> (std::process::ExitStatus, String) {
        let mut c = self.ns.command(kerfd());
        c.args(["--config", self.config.to_str().unwrap()]);
        let mut d = Proc::start("kerfd", &self.dir, c);
        let status = d.wait_within(PATIENCE);
        (status, d.stderr())
    }

    /// Starts the daemon inside the namespace; waits until it answers.
    pub fn daemon(&self) -> Proc {
        let mut c = self.ns.command(kerfd());
        c.args(["--config", self.config.to_str().unwrap()]);
        let mut d = Proc::start("kerfd", &self.dir, c);
        let deadline = Instant::now() + PATIENCE;
        loop {
            if let Some(status) = d.try_wait() {
                panic!("kerfd exited at start ({status}): {}", d.stderr());
            }
            if self.kerf(&["status"]).status.success() {
                return d;
            }
            assert!(
                Instant::now() < deadline,
                "kerfd never answered: {}",
                d.stderr()
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}
