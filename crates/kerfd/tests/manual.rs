//! Jogging, homing and the hard limit switches in the daemon's cycle, measured from what
//! the cycle sends out every period (the setpoint positions) and from the simulated
//! motors themselves (where the machine physically is), cycle by cycle, in one thread so
//! that every test is deterministic.
//!
//! - homing with home switches at random places (both search directions, both latch
//!   modes, a switch already active at the start, home sequences) ends at the home
//!   position, and the machine coordinate of the physical switch point is the configured
//!   home offset within one count; the limits hold throughout;
//! - a continuous jog whose renewals stop at a random instant stops within the dead-man
//!   time plus a jerk-limited stop, within the limits;
//! - step and absolute jogs end exactly where asked; a continuous jog on a homed axis
//!   stops exactly at the soft limit;
//! - programs are refused until the machine is homed; a switch that is never found is a
//!   fault naming the axis and the distance; a hard limit switch stops the machine, and
//!   after a reset the axis may be jogged off it only away from it.

use kerf_config::Config;
use kerf_drive::safety::Check;
use kerf_proto::{Jog, MachineState};
use kerfd::worker::fieldbus::MachineDrive;
use kerfd::worker::{Cycle, CycleCommand, CycleOutput, Planning, PlanningCounters, Snapshot};

mod common;

/// Counts per mm of the test machine's simulated drives (the default).
const COUNTS_PER_MM: f64 = 1000.0;

/// One axis of the test machine: limits and its homing table's body.
struct AxisSpec {
    v: f64,
    a: f64,
    j: f64,
    min: f64,
    max: f64,
    /// `[axes.N.homing]` and `[axes.N.sim]` and `[axes.N.limit_switches]` text, or "".
    extra: String,
}

fn machine_toml(axes: &[AxisSpec; 3], top: &str) -> String {
    let mut t = format!(
        "machine = \"manual-test\"\nperiod_us = 1000\ntolerance_mm = 0.01\n[daemon]\nstate_file = \"{}\"\n{top}\n",
        std::env::temp_dir()
            .join(format!("kerfd-manual-test-{}.state", std::process::id()))
            .display()
    );
    t.push_str(
        "[io]\ndigital_inputs = [\n { number = 0, name = \"x_home\" },\n { number = 1, name = \"y_home\" },\n { number = 2, name = \"z_home\" },\n { number = 3, name = \"x_min\" },\n { number = 4, name = \"x_max\" },\n]\n",
    );
    for (name, ax) in ["x", "y", "z"].iter().zip(axes.iter()) {
        t.push_str(&format!(
            "[axes.{name}]\nvelocity_mm_s = {}\nacceleration_mm_s2 = {}\njerk_mm_s3 = {}\nmin_mm = {}\nmax_mm = {}\n{}\n",
            ax.v, ax.a, ax.j, ax.min, ax.max, ax.extra
        ));
    }
    t
}

fn config(text: &str) -> Config {
    Config::from_toml_str(text, "manual-test.toml")
        .unwrap_or_else(|e| panic!("the test machine: {e}\n{text}"))
}

/// A small deterministic generator (xorshift), so that the "random" cases repeat.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }

    /// Uniform in [lo, hi).
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * ((self.next() >> 11) as f64 / (1u64 << 53) as f64)
    }

    fn coin(&mut self) -> bool {
        self.next() & 1 == 1
    }
}

struct Machine {
    cycle: Cycle,
    planning: Planning,
    commands: rtrb::Producer<CycleCommand>,
    status: rtrb::Consumer<Snapshot>,
    config: Config,
    _counters: PlanningCounters,
    last: Option<Snapshot>,
    /// Every cycle's output, with each axis's drive offset at that cycle (machine = drive
    /// + offset) and the simulated motors' positions, mm.
    log: Vec<(CycleOutput, [f64; 6], [f64; 6])>,
}

impl Machine {
    fn new(config: Config) -> Machine {
        let w = common::wire(&config, 1 << 14);
        let mut m = Machine {
            cycle: w.cycle,
            planning: w.planning,
            commands: w.commands,
            status: w.status,
            config,
            _counters: w.counters,
            last: None,
            log: Vec::new(),
        };
        for _ in 0..100 {
            m.run();
            if m.cycle.stage().ready() {
                m.log.clear();
                return m;
            }
        }
        panic!(
            "the drives did not enable: {:?} {:?}",
            m.cycle.stage().phase(),
            m.cycle.stage().fault()
        );
    }

    fn run(&mut self) -> CycleOutput {
        let out = self.cycle.run();
        while let Ok(s) = self.status.pop() {
            self.last = Some(s);
        }
        let stage = self.cycle.stage();
        let mut offsets = [0.0; 6];
        let mut motors = [0.0; 6];
        for i in 0..3 {
            offsets[i] = stage.offset(i);
            if let Some(MachineDrive::Sim(d)) = stage.drive(i) {
                motors[i] = d.motor_position_counts() / COUNTS_PER_MM;
            }
        }
        self.log.push((out, offsets, motors));
        out
    }

    fn command(&mut self, c: CycleCommand) {
        self.commands.push(c).expect("room for a command");
    }

    fn snapshot(&self) -> Snapshot {
        self.last.expect("a snapshot")
    }

    fn position(&self) -> [f64; 6] {
        self.log.last().map_or([0.0; 6], |r| r.0.setpoint.position)
    }

    /// Runs until `done` or `max` cycles; returns whether `done` came.
    fn run_until(&mut self, max: usize, done: impl Fn(&Snapshot) -> bool) -> bool {
        for _ in 0..max {
            self.run();
            if self.last.as_ref().is_some_and(&done) {
                return true;
            }
        }
        false
    }

    /// Runs until no axis moves by hand any more.
    fn settle(&mut self, max: usize) {
        // The command is applied in the next cycle: run it first.
        self.run();
        assert!(
            self.run_until(max, |s| s.state != MachineState::Manual),
            "the manual motion did not end within {max} cycles"
        );
    }
}

/// Checks every axis's velocity, acceleration and jerk by finite differences of the
/// positions sent (in the drives' own frame: a homing shift redefines the coordinates
/// without motion) against the limits, 1 % plus rounding.
fn assert_limits(log: &[(CycleOutput, [f64; 6], [f64; 6])], axes: &[AxisSpec; 3], what: &str) {
    let t = 1e-3;
    for (i, ax) in axes.iter().enumerate() {
        let x: Vec<f64> = log
            .iter()
            .map(|(o, off, _)| o.setpoint.position[i] - off[i])
            .collect();
        let scale = x.iter().fold(1.0f64, |m, v| m.max(v.abs()));
        let eps = 8.0 * f64::EPSILON * scale;
        for k in 3..x.len() {
            let v = (x[k] - x[k - 1]) / t;
            let a = (x[k] - 2.0 * x[k - 1] + x[k - 2]) / (t * t);
            let j = (x[k] - 3.0 * x[k - 1] + 3.0 * x[k - 2] - x[k - 3]) / (t * t * t);
            assert!(
                v.abs() <= ax.v * 1.01 + eps / t,
                "{what}: axis {i} cycle {k}: v {v} > {}",
                ax.v
            );
            assert!(
                a.abs() <= ax.a * 1.01 + 4.0 * eps / (t * t),
                "{what}: axis {i} cycle {k}: a {a} > {}",
                ax.a
            );
            assert!(
                j.abs() <= ax.j * 1.01 + 8.0 * eps / (t * t * t),
                "{what}: axis {i} cycle {k}: j {j} > {}",
                ax.j
            );
        }
    }
}

fn plain_axis(v: f64, a: f64, j: f64, min: f64, max: f64) -> AxisSpec {
    AxisSpec {
        v,
        a,
        j,
        min,
        max,
        extra: String::new(),
    }
}

#[test]
fn homing_finds_switches_at_random_places_and_sets_the_machine_coordinates() {
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    for case in 0..12 {
        let mut axes = [
            plain_axis(100.0, 1000.0, 20_000.0, -500.0, 500.0),
            plain_axis(80.0, 800.0, 10_000.0, -300.0, 300.0),
            plain_axis(50.0, 600.0, 15_000.0, -200.0, 200.0),
        ];
        // Per axis: the switch (drive frame), where the motor starts, the directions.
        let mut expect = Vec::new();
        for (i, ax) in axes.iter_mut().enumerate() {
            let name = ["x", "y", "z"][i];
            let positive = rng.coin();
            let search = rng.range(5.0, ax.v * 0.5);
            // At most 1 µm (one count) per period at the latch: the edge is found within
            // half a count, and the drive's whole counts add at most another half.
            let latch = rng.range(0.2, 1.0) * if rng.coin() { 1.0 } else { -1.0 };
            let switch = rng.range(-150.0, 150.0);
            // Mostly away from the switch on the search's near side; sometimes on it.
            let on_it = case % 4 == 3 && i == 0;
            let gap = rng.range(1.0, 200.0);
            let start = match (positive, on_it) {
                (true, false) => switch - gap,
                (false, false) => switch + gap,
                (true, true) => switch + rng.range(0.5, 5.0),
                (false, true) => switch - rng.range(0.5, 5.0),
            };
            let home_offset = rng.range(-50.0, 50.0);
            let home = rng.range(ax.min + 1.0, ax.max - 1.0);
            let seq = rng.next() % 3;
            ax.extra = format!(
                "[axes.{name}.homing]\nkind = \"switch\"\nswitch = \"{name}_home\"\nsearch_velocity_mm_s = {}\nlatch_velocity_mm_s = {}\nsearch_distance_mm = 1000.0\nhome_offset_mm = {home_offset}\nhome_mm = {home}\nsequence = {seq}\n[axes.{name}.sim]\nstart_mm = {start}\nhome_switch_mm = {switch}\n",
                if positive { search } else { -search },
                if positive { latch } else { -latch },
            );
            expect.push((switch, home_offset, home, seq));
        }
        let text = machine_toml(&axes, "[homing]\nrequired = true\n");
        let mut m = Machine::new(config(&text));
        assert_eq!(
            m.snapshot().manual.homed,
            0,
            "case {case}: nothing homed at start"
        );
        m.command(CycleCommand::Home(0b111));
        m.run();
        assert!(
            m.run_until(2_000_000, |s| s.manual.homing == 0),
            "case {case}: homing did not end"
        );
        // The simulated servos settle at rest.
        for _ in 0..1000 {
            m.run();
        }
        let s = m.snapshot();
        assert!(
            s.drives.fault.is_none(),
            "case {case}: {:?}",
            s.drives.fault
        );
        assert_eq!(s.manual.homed, 0b111, "case {case}: every axis homed");
        let last = *m.log.last().unwrap();
        for (i, &(switch, home_offset, home, _)) in expect.iter().enumerate() {
            // The machine coordinate after homing is the home position.
            assert_eq!(
                last.0.setpoint.position[i], home,
                "case {case} axis {i}: the machine coordinate after homing"
            );
            // The physical switch point reads as the home offset: the motor stands at
            // `switch + (home - home_offset)` in its own frame.
            let motor = last.2[i];
            let want = switch + (home - home_offset);
            assert!(
                (motor - want).abs() <= 1.0 / COUNTS_PER_MM + 1e-9,
                "case {case} axis {i}: the motor at {motor}, the switch's coordinate says {want}"
            );
        }
        // Home sequences: an axis of a later sequence starts moving only once every axis
        // of an earlier one is done.
        let first_move = |i: usize| {
            m.log.windows(2).position(|w| {
                w[1].0.setpoint.position[i] - w[1].1[i] != w[0].0.setpoint.position[i] - w[0].1[i]
            })
        };
        let last_move = |i: usize| {
            m.log.windows(2).rposition(|w| {
                w[1].0.setpoint.position[i] - w[1].1[i] != w[0].0.setpoint.position[i] - w[0].1[i]
            })
        };
        for i in 0..3 {
            for k in 0..3 {
                if expect[k].3 < expect[i].3 {
                    assert!(
                        first_move(i) > last_move(k),
                        "case {case}: axis {i} (sequence {}) moved before axis {k} (sequence {}) was done",
                        expect[i].3,
                        expect[k].3
                    );
                }
            }
        }
        assert_limits(&m.log, &axes, &format!("homing case {case}"));
    }
}

/// The time a jerk-limited stop from speed `v` takes at most, s: written here from the
/// limits (not taken from the code under test): with a ≤ a_max and j ≤ j_max, from
/// constant speed v, the fastest stop takes 2·sqrt(v/j) when v ≤ a²/j, else v/a + a/j.
fn stop_time_s(v: f64, a: f64, j: f64) -> f64 {
    if v <= a * a / j {
        2.0 * (v / j).sqrt()
    } else {
        v / a + a / j
    }
}

#[test]
fn a_continuous_jog_stops_when_its_renewals_stop() {
    let mut rng = Rng(0x1234_5678_9abc_def1);
    for case in 0..10 {
        let axes = [
            plain_axis(
                rng.range(20.0, 300.0),
                rng.range(200.0, 5000.0),
                rng.range(2000.0, 200_000.0),
                -1e5,
                1e5,
            ),
            plain_axis(100.0, 1000.0, 20_000.0, -1e5, 1e5),
            plain_axis(100.0, 1000.0, 20_000.0, -1e5, 1e5),
        ];
        let deadman_ms = 100.0;
        let text = machine_toml(&axes, "[jog]\ndeadman_ms = 100\n");
        let mut m = Machine::new(config(&text));
        let speed = rng.range(1.0, axes[0].v);
        let positive = rng.coin();
        let jog = CycleCommand::Jog {
            axis: 0,
            jog: Jog::Continuous(positive),
            speed,
        };
        // Renewed every 30 cycles for a random time, then the client goes silent.
        let renewals = 1 + rng.next() % 60;
        let mut last_renewal = 0;
        for _ in 0..renewals {
            m.command(jog);
            last_renewal = m.log.len();
            for _ in 0..30 {
                m.run();
            }
        }
        m.settle(1_000_000);
        let x: Vec<f64> = m.log.iter().map(|r| r.0.setpoint.position[0]).collect();
        let stopped = x
            .windows(2)
            .rposition(|w| w[1] != w[0])
            .map_or(0, |k| k + 1);
        // From any state with |v| ≤ speed and |a| ≤ a_max: the acceleration back to 0
        // (a/j, while the speed still rises by at most a²/2j), then the stop from there.
        let (a, j) = (axes[0].a, axes[0].j);
        // Moves by hand brake at 95 % of the acceleration and jerk limits
        // (docs/MACHINE.md).
        let (a, j) = (0.95 * a, 0.95 * j);
        let bound_s =
            deadman_ms * 1e-3 + a / j + stop_time_s(speed + a * a / (2.0 * j), a, j) + 3e-3;
        let took_s = (stopped as f64 - last_renewal as f64) * 1e-3;
        assert!(
            took_s <= bound_s,
            "case {case}: at rest {took_s} s after the last renewal, bound {bound_s} s"
        );
        assert!(
            (x[stopped] - x[0]) * if positive { 1.0 } else { -1.0 } > 0.0,
            "case {case}: it moved the way asked"
        );
        assert_limits(&m.log, &axes, &format!("jog case {case}"));
    }
}

#[test]
fn step_and_absolute_jogs_end_exactly_and_a_continuous_one_stops_at_the_soft_limit() {
    let axes = [
        plain_axis(150.0, 1500.0, 30_000.0, -100.0, 250.0),
        plain_axis(100.0, 1000.0, 20_000.0, -100.0, 100.0),
        plain_axis(100.0, 1000.0, 20_000.0, -100.0, 100.0),
    ];
    let mut m = Machine::new(config(&machine_toml(&axes, "")));
    let x0 = m.position()[0];
    m.command(CycleCommand::Jog {
        axis: 0,
        jog: Jog::Step(0.1),
        speed: 10.0,
    });
    m.settle(100_000);
    assert_eq!(m.position()[0], x0 + 0.1, "a step of 0.1 ends exactly");
    m.command(CycleCommand::Jog {
        axis: 0,
        jog: Jog::To(12.5),
        speed: 0.0,
    });
    m.settle(100_000);
    assert_eq!(m.position()[0], 12.5, "a jog to 12.5 ends there exactly");
    // Continuous towards the upper soft limit at full speed, renewed throughout.
    for _ in 0..400 {
        m.command(CycleCommand::Jog {
            axis: 0,
            jog: Jog::Continuous(true),
            speed: 150.0,
        });
        for _ in 0..20 {
            m.run();
        }
    }
    let peak = m
        .log
        .iter()
        .map(|r| r.0.setpoint.position[0])
        .fold(f64::NEG_INFINITY, f64::max);
    assert_eq!(peak, 250.0, "it reached the soft limit and never passed it");
    assert_eq!(m.position()[0], 250.0);
    assert!(m.snapshot().drives.fault.is_none());
    // A step or a target beyond the soft limit is refused: nothing moves.
    let before = m.log.len();
    m.command(CycleCommand::Jog {
        axis: 0,
        jog: Jog::Step(1.0),
        speed: 10.0,
    });
    for _ in 0..50 {
        m.run();
    }
    assert!(
        m.log[before..]
            .iter()
            .all(|r| r.0.setpoint.position[0] == 250.0),
        "a step beyond the soft limit does not move"
    );
    assert_limits(&m.log, &axes, "jogs");
}

#[test]
fn programs_wait_for_homing_and_a_switch_never_found_is_a_fault() {
    let mut axes = [
        plain_axis(100.0, 1000.0, 20_000.0, -500.0, 500.0),
        plain_axis(100.0, 1000.0, 20_000.0, -500.0, 500.0),
        plain_axis(100.0, 1000.0, 20_000.0, -500.0, 500.0),
    ];
    axes[0].extra = "[axes.x.homing]\nkind = \"switch\"\nswitch = \"x_home\"\nsearch_velocity_mm_s = -50.0\nlatch_velocity_mm_s = 1.0\nsearch_distance_mm = 100.0\n[axes.x.sim]\nhome_switch_mm = -300.0\n".to_string();
    let text = machine_toml(&axes, "[homing]\nrequired = true\n");
    let mut m = Machine::new(config(&text));
    // A program on an unhomed machine is refused and nothing moves.
    let start = m.position();
    common::feed_program(&mut m.planning, &m.config, 1, start, "G0 X10\nM2\n");
    assert!(m.run_until(1000, |s| s.program_id == 1 && s.program_done));
    let s = m.snapshot();
    assert!(
        s.refusal
            .is_some_and(|r| r.to_string().contains("axis X is not homed")),
        "{:?}",
        s.refusal
    );
    assert!(m.log.iter().all(|r| r.0.setpoint.position[0] == 0.0));
    // Homing searches 100 mm for a switch 300 mm away: a fault naming the axis and the
    // distance, and the axis stays unhomed.
    m.command(CycleCommand::Home(0b001));
    m.run();
    assert!(m.run_until(100_000, |s| s.drives.fault.is_some()));
    let f = m.snapshot().drives.fault.unwrap();
    assert_eq!(f.check, Check::HomeSearch);
    assert_eq!(f.axis, Some(0));
    assert_eq!(f.limit, 100.0);
    assert!(f.value >= 100.0, "travelled {}", f.value);
    assert_eq!(m.snapshot().manual.homed & 1, 0);
}

#[test]
fn a_hard_limit_switch_stops_the_machine_and_the_axis_jogs_off_it_the_other_way_only() {
    let mut axes = [
        plain_axis(100.0, 1000.0, 20_000.0, -500.0, 500.0),
        plain_axis(100.0, 1000.0, 20_000.0, -500.0, 500.0),
        plain_axis(100.0, 1000.0, 20_000.0, -500.0, 500.0),
    ];
    axes[0].extra =
        "[axes.x.limit_switches]\nmin = \"x_min\"\nmax = \"x_max\"\n[axes.x.sim]\nmin_limit_mm = -20.0\nmax_limit_mm = 30.0\n"
            .to_string();
    let mut m = Machine::new(config(&machine_toml(&axes, "")));
    // Jogging up runs into the upper switch at 30: a fault, all axes stop.
    m.command(CycleCommand::Jog {
        axis: 0,
        jog: Jog::To(100.0),
        speed: 20.0,
    });
    m.run();
    assert!(m.run_until(100_000, |s| s.drives.fault.is_some()));
    let f = m.snapshot().drives.fault.unwrap();
    assert_eq!((f.check, f.axis, f.value), (Check::HardLimit, Some(0), 1.0));
    m.run_until(10_000, |s| {
        s.drives.state == kerf_drive::safety::SafetyState::Stopped
    });
    let x_stop = m.position()[0];
    assert!((30.0..31.0).contains(&x_stop), "stopped at {x_stop}");
    // Reset: allowed on the switch; then up is refused, down moves off it.
    m.command(CycleCommand::Reset(1));
    m.run();
    assert!(m.run_until(10_000, |s| s.reset.is_some_and(|r| r.0 == 1)));
    assert!(
        m.snapshot().reset.unwrap().1.is_ok(),
        "{:?}",
        m.snapshot().reset
    );
    assert_eq!(m.snapshot().manual.limit_released, 1);
    let before = m.log.len();
    m.command(CycleCommand::Jog {
        axis: 0,
        jog: Jog::Step(1.0),
        speed: 5.0,
    });
    for _ in 0..200 {
        m.run();
    }
    assert!(
        m.log[before..]
            .iter()
            .all(|r| r.0.setpoint.position[0] == x_stop),
        "a jog further onto the switch does not move"
    );
    m.command(CycleCommand::Jog {
        axis: 0,
        jog: Jog::Step(-5.0),
        speed: 5.0,
    });
    m.settle(100_000);
    assert_eq!(m.position()[0], x_stop - 5.0);
    let s = m.snapshot();
    assert!(s.drives.fault.is_none());
    assert_eq!(s.manual.limit_released, 0, "off the switch: released ends");
    assert_eq!(s.manual.max_limit_switches, 0);
}

#[test]
fn jogs_in_a_pause_return_z_last_before_the_program_goes_on_unchanged() {
    let axes = [
        plain_axis(100.0, 1000.0, 20_000.0, -100.0, 100.0),
        plain_axis(100.0, 1000.0, 20_000.0, -100.0, 100.0),
        plain_axis(100.0, 1000.0, 20_000.0, -100.0, 100.0),
    ];
    let text = machine_toml(&axes, "");
    let program = "G21 G90\nG1 X10 F600\nM0\nG1 X20 Y5\nM2\n";
    // `jog`: jog in the pause (else cycle start at once). The positions after the program
    // resumed (from its first cycle that moves on the path after the pause).
    let run = |jog: bool| {
        let mut m = Machine::new(config(&text));
        let start = m.position();
        common::feed_program(&mut m.planning, &m.config, 1, start, program);
        assert!(m.run_until(100_000, |s| s.waits_for_operator()));
        let paused_at = m.position();
        if jog {
            m.command(CycleCommand::Jog {
                axis: 2,
                jog: Jog::Step(5.0),
                speed: 20.0,
            });
            m.run();
            assert!(m.run_until(100_000, |s| s.manual.jogging == 0));
            m.command(CycleCommand::Jog {
                axis: 0,
                jog: Jog::Step(-3.0),
                speed: 20.0,
            });
            m.run();
            assert!(m.run_until(100_000, |s| s.manual.jogging == 0));
            let p = m.position();
            assert_eq!((p[0], p[2]), (paused_at[0] - 3.0, paused_at[2] + 5.0));
        }
        let from = m.log.len();
        m.command(CycleCommand::Resume);
        assert!(m.run_until(100_000, |s| s.program_id == 1 && s.program_done));
        let s = m.snapshot();
        assert!(s.refusal.is_none() && !s.aborted, "{:?}", s.refusal);
        let tail: Vec<[f64; 6]> = m.log[from..]
            .iter()
            .map(|r| r.0.setpoint.position)
            .collect();
        (paused_at, tail, m.log.clone())
    };
    let (paused_ref, reference, _) = run(false);
    let (paused_at, jogged, log) = run(true);
    assert_eq!(paused_ref, paused_at);
    // The way back: X returns while Z is still up; Z comes down last.
    let back = jogged
        .iter()
        .position(|p| p[0] == paused_at[0] && p[2] == paused_at[2])
        .expect("back at the pause position");
    let x_home = jogged.iter().position(|p| p[0] == paused_at[0]).unwrap();
    assert!(
        jogged[..=x_home].iter().all(|p| p[2] == paused_at[2] + 5.0),
        "Z stays up until X is back"
    );
    assert!(x_home < back, "Z comes down after X is back");
    // Then the program goes on as if nobody had jogged: the same positions, cycle for
    // cycle, from its first move after the pause.
    let first_move = |t: &[[f64; 6]], from: usize| {
        (from..t.len())
            .find(|&k| t[k] != t[from])
            .expect("it moves on")
            - 1
    };
    let a = first_move(&reference, 0);
    let b = first_move(&jogged, back);
    assert_eq!(&reference[a..], &jogged[b..], "the program after the pause");
    assert_limits(&log, &axes, "jog in a pause");
}

#[test]
fn an_axis_whose_drive_homes_itself_is_homed_and_moves_to_its_home_position() {
    let mut rng = Rng(0x5151_7a7a_0102_0304);
    for case in 0..6 {
        let mut axes = [
            plain_axis(100.0, 1000.0, 20_000.0, -500.0, 500.0),
            plain_axis(100.0, 1000.0, 20_000.0, -500.0, 500.0),
            plain_axis(100.0, 1000.0, 20_000.0, -500.0, 500.0),
        ];
        // Methods 19/20 search towards increasing counts, 21/22 towards decreasing ones:
        // the switch is placed on that side of where the motor powers up.
        let method = [19, 20, 21, 22, 35, 37][case];
        let gap = rng.range(5.0, 100.0);
        let switch = if method <= 20 { gap } else { -gap };
        let home_offset = rng.range(-50.0, 50.0);
        let home = rng.range(-100.0, 100.0);
        let speeds = if method >= 35 {
            String::new()
        } else {
            "search_velocity_mm_s = 40.0\nlatch_velocity_mm_s = 2.0\n".to_string()
        };
        axes[0].extra = format!(
            "[axes.x.homing]\nkind = \"drive\"\nmethod = {method}\n{speeds}home_offset_mm = {home_offset}\nhome_mm = {home}\nfinal_speed_mm_s = 50.0\n[axes.x.sim]\nhome_switch_mm = {switch}\n"
        );
        if method >= 35 {
            // No switch for the methods that take the current position.
            axes[0].extra = axes[0]
                .extra
                .replace(&format!("home_switch_mm = {switch}\n"), "");
            axes[0].extra = axes[0].extra.replace("[axes.x.sim]\n", "");
        }
        let text = machine_toml(&axes, "[homing]\nrequired = true\n");
        let mut m = Machine::new(config(&text));
        assert_eq!(
            m.snapshot().manual.homed & 1,
            0,
            "case {case}: X not homed at start"
        );
        m.command(CycleCommand::Home(0b001));
        m.run();
        // The cycle after which the drive handed the axis back (its homing mode left).
        let (mut was_homing, mut back) = (false, None);
        for _ in 0..1_000_000 {
            m.run();
            let homing = m.cycle.stage().drive_homing_active(0);
            if was_homing && !homing && back.is_none() {
                back = Some(m.log.len() - 1);
            }
            was_homing |= homing;
            if m.last.is_some_and(|s| s.manual.homing == 0) {
                break;
            }
        }
        let back = back.expect("the drive homed and handed the axis back");
        let s = m.snapshot();
        assert!(
            s.drives.fault.is_none(),
            "case {case}: {:?}",
            s.drives.fault
        );
        assert_eq!(
            s.manual.homed & 1,
            1,
            "case {case} (method {method}): X homed"
        );
        assert_eq!(m.position()[0], home, "case {case}: at the home position");
        // Kerf's move to the home position, after the drive's own homing (whose motion is
        // the drive's), within the limits: from the cycle the drive handed the axis back
        // in its new coordinates.
        assert_limits(&m.log[back..], &axes, &format!("drive homing case {case}"));
        // A program now runs.
        let start = m.position();
        common::feed_program(&mut m.planning, &m.config, 1, start, "G0 X0\nM2\n");
        assert!(m.run_until(100_000, |s| s.program_id == 1 && s.program_done));
        assert!(m.snapshot().refusal.is_none(), "{:?}", m.snapshot().refusal);
    }
}

#[test]
fn an_absolute_encoder_is_homed_from_the_start_with_its_offset() {
    let mut axes = [
        plain_axis(100.0, 1000.0, 20_000.0, -500.0, 500.0),
        plain_axis(100.0, 1000.0, 20_000.0, -500.0, 500.0),
        plain_axis(100.0, 1000.0, 20_000.0, -500.0, 500.0),
    ];
    // The encoder reads 10 mm at power-up; machine = encoder + 123.5.
    axes[0].extra =
        "[axes.x.homing]\nkind = \"absolute\"\nhome_offset_mm = 123.5\n[axes.x.sim]\nstart_mm = 10.0\n"
            .to_string();
    let text = machine_toml(&axes, "[homing]\nrequired = true\n");
    let mut m = Machine::new(config(&text));
    m.run();
    assert_eq!(m.snapshot().manual.homed, 0b111, "homed without motion");
    assert_eq!(m.position()[0], 133.5);
    // And a program runs at once, in those coordinates.
    let start = m.position();
    common::feed_program(&mut m.planning, &m.config, 1, start, "G0 X100\nM2\n");
    assert!(m.run_until(100_000, |s| s.program_id == 1 && s.program_done));
    assert!(m.snapshot().refusal.is_none(), "{:?}", m.snapshot().refusal);
    assert_eq!(m.position()[0], 100.0);
    let motor = m.log.last().unwrap().2[0];
    assert!(
        (motor - (100.0 - 123.5)).abs() < 0.01,
        "the motor at {motor}"
    );
}
