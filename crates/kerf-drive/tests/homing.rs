//! The homing sequence against a test-only axis with a home switch at a known physical
//! place: the axis moves toward its command within a velocity and an acceleration limit,
//! integrated exactly per period, and its switch is active while its physical position
//! is within the switch. The machine frame starts equal to the physical one and moves by
//! every shift the sequence asks for, so the machine coordinate of the physical switch
//! edge after homing is known from the physics alone and is compared with `home_offset`.

use kerf_drive::homing::{
    HomeCommand, HomeError, HomeInput, HomeKind, HomePhase, HomeSetup, Homing,
};
use kerf_testkit::alloc::{Count, CountingAllocator};
use proptest::prelude::*;
use proptest::test_runner::RngSeed;

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

/// What the fake axis was told last.
#[derive(Clone, Copy, Debug)]
enum Motion {
    Rest,
    Run(f64),
    MoveTo(f64, f64),
}

/// A test-only axis: velocity limited by the command's speed, acceleration by `accel`,
/// no jerk limit. `x` is in the machine frame; physical = `x - offset`.
#[derive(Clone, Copy, Debug)]
struct FakeAxis {
    x: f64,
    v: f64,
    offset: f64,
    motion: Motion,
    accel: f64,
    period_s: f64,
    /// The switch's physical extent.
    switch: (f64, f64),
    /// Forced switch state (a dead or stuck switch), else the physics.
    forced: Option<bool>,
}

impl FakeAxis {
    fn switch_active(&self) -> bool {
        let p = self.x - self.offset;
        self.forced
            .unwrap_or(self.switch.0 <= p && p <= self.switch.1)
    }

    fn at_rest(&self) -> bool {
        matches!(self.motion, Motion::Rest)
    }

    fn apply(&mut self, command: HomeCommand, at_rest: bool) {
        match command {
            HomeCommand::Hold => {}
            HomeCommand::Run(v) => self.motion = Motion::Run(v),
            HomeCommand::Stop => {
                if !self.at_rest() {
                    self.motion = Motion::Run(0.0);
                }
            }
            HomeCommand::MoveTo { position, speed } => {
                assert!(speed > 0.0 && position.is_finite());
                self.motion = Motion::MoveTo(position, speed);
            }
            HomeCommand::Shift(delta) => {
                assert!(at_rest && self.at_rest(), "shift while moving");
                self.x += delta;
                self.offset += delta;
            }
        }
    }

    /// One period: the velocity moves toward the wanted one by at most `accel·T`, the
    /// position by the mean velocity. A move ends on its target (the braking curve
    /// `sqrt(2 a d)` leads there; the last bit is taken as reached).
    fn step(&mut self) {
        let (t, a) = (self.period_s, self.accel);
        let wanted = match self.motion {
            Motion::Rest => return,
            Motion::Run(v) => v,
            Motion::MoveTo(target, speed) => {
                let d = target - self.x;
                d.signum() * speed.min((2.0 * a * d.abs()).sqrt())
            }
        };
        let v1 = self.v + (wanted - self.v).clamp(-a * t, a * t);
        let x1 = self.x + 0.5 * (self.v + v1) * t;
        match self.motion {
            Motion::Run(v) if v == 0.0 && v1 == 0.0 => {
                self.motion = Motion::Rest;
            }
            Motion::MoveTo(target, _) => {
                let passed = (target - x1) * (target - self.x) <= 0.0;
                if passed || ((target - x1).abs() < a * t * t && v1.abs() <= 2.0 * a * t) {
                    self.x = target;
                    self.v = 0.0;
                    self.motion = Motion::Rest;
                    return;
                }
            }
            _ => {}
        }
        self.x = x1;
        self.v = v1;
    }
}

/// What a homing run did.
#[derive(Debug)]
struct Outcome {
    axis: FakeAxis,
    homing: Homing,
    /// Phases in the order they were entered.
    phases: Vec<HomePhase>,
    /// The most the axis travelled in each seek phase from where the phase began.
    travel: Vec<(HomePhase, f64)>,
    /// The last command that was not `Hold`.
    last_command: HomeCommand,
}

/// Homes `axis` with `setup`, the caller's cycle of the module documentation: input,
/// cycle, apply, step.
fn home(setup: HomeSetup, mut axis: FakeAxis) -> Outcome {
    let mut homing = Homing::new(setup).unwrap();
    homing.start();
    let mut phases = vec![homing.phase()];
    let mut travel: Vec<(HomePhase, f64)> = Vec::new();
    let mut phase_start = axis.x;
    let mut last_command = HomeCommand::Hold;
    for _ in 0..5_000_000 {
        let input = HomeInput {
            switch: axis.switch_active(),
            position: axis.x,
            at_rest: axis.at_rest(),
        };
        let command = homing.cycle(&input);
        if command != HomeCommand::Hold {
            last_command = command;
        }
        axis.apply(command, input.at_rest);
        if homing.phase() != *phases.last().unwrap() {
            phases.push(homing.phase());
            phase_start = axis.x;
        }
        if matches!(
            homing.phase(),
            HomePhase::InitialBackOff | HomePhase::Search | HomePhase::BackOff | HomePhase::Latch
        ) {
            let moved = (axis.x - phase_start).abs();
            match travel.last_mut() {
                Some((p, m)) if *p == homing.phase() => *m = m.max(moved),
                _ => travel.push((homing.phase(), moved)),
            }
        }
        if matches!(homing.phase(), HomePhase::Done | HomePhase::Failed) && axis.at_rest() {
            break;
        }
        axis.step();
    }
    Outcome {
        axis,
        homing,
        phases,
        travel,
        last_command,
    }
}

fn fake(start: f64, switch: (f64, f64), accel: f64, period_s: f64) -> FakeAxis {
    FakeAxis {
        x: start,
        v: 0.0,
        offset: 0.0,
        motion: Motion::Rest,
        accel,
        period_s,
        switch,
        forced: None,
    }
}

fn switch_setup(search: f64, latch: f64) -> HomeSetup {
    HomeSetup {
        kind: HomeKind::Switch,
        search_velocity: search,
        latch_velocity: latch,
        search_distance: 1000.0,
        home_offset: 12.5,
        home_position: 2.0,
        final_speed: 40.0,
    }
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 300,
        rng_seed: RngSeed::Fixed(0x29b1),
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    /// Switches at random places and widths, the axis starting before them or on them,
    /// both search directions and both latch modes: the sequence ends homed at
    /// `home_position` exactly, and the machine coordinate of the switch edge the search
    /// meets first (known from the physics) is `home_offset` within half a period's latch
    /// travel. No phase travels further than `search_distance`, the phases are the ones of
    /// the documented sequence, and a shift is only ever asked for at rest (the fake
    /// asserts it).
    #[test]
    fn switch_homing_puts_the_switch_edge_at_home_offset(
        edge in -200.0f64..200.0,
        width in 0.2f64..30.0,
        before in 0.0f64..300.0,
        on_switch in any::<bool>(),
        inside in 0.0f64..1.0,
        positive in any::<bool>(),
        same_sign in any::<bool>(),
        search_speed in 5.0f64..60.0,
        latch_speed in 0.1f64..5.0,
        accel in 100.0f64..5000.0,
        period_s in 0.00025f64..0.004,
        home_offset in -500.0f64..500.0,
        home_position in -500.0f64..500.0,
    ) {
        let dir = if positive { 1.0 } else { -1.0 };
        // The edge the search meets first is `edge`; the switch extends beyond it.
        let switch = if positive { (edge, edge + width) } else { (edge - width, edge) };
        let start = if on_switch {
            switch.0 + inside * width
        } else {
            edge - dir * (before + 0.01)
        };
        let latch = if same_sign { dir * latch_speed } else { -dir * latch_speed };
        let setup = HomeSetup {
            kind: HomeKind::Switch,
            search_velocity: dir * search_speed,
            latch_velocity: latch,
            search_distance: 1000.0,
            home_offset,
            home_position,
            final_speed: 40.0,
        };
        let out = home(setup, fake(start, switch, accel, period_s));
        prop_assert_eq!(out.homing.phase(), HomePhase::Done, "{:?}", out.homing.error());
        prop_assert_eq!(out.homing.error(), None);
        prop_assert_eq!(out.axis.x, home_position);
        // The machine coordinate of the physical edge.
        let edge_machine = edge + out.axis.offset;
        let bound = 0.5 * latch_speed * period_s + 1e-9 * (1.0 + edge.abs() + home_offset.abs());
        prop_assert!((edge_machine - home_offset).abs() <= bound,
            "edge at {edge_machine}, home_offset {home_offset}, bound {bound}");
        for &(phase, moved) in &out.travel {
            prop_assert!(moved <= 1000.0 + 1e-9, "{phase:?} travelled {moved}");
        }
        let mut expected = vec![HomePhase::Search];
        if on_switch {
            expected.push(HomePhase::InitialBackOff);
            expected.push(HomePhase::Search);
        }
        if same_sign {
            expected.push(HomePhase::BackOff);
        }
        expected.extend([HomePhase::Latch, HomePhase::Final, HomePhase::Done]);
        prop_assert_eq!(out.phases, expected);
    }
}

/// No switch within the search distance: the sequence fails in the search phase naming
/// the distance, the last command is a stop, the axis comes to rest, and it travelled no
/// further than the search distance.
#[test]
fn switch_never_found_fails_in_the_search_with_a_stop() {
    for dir in [1.0, -1.0] {
        let mut setup = switch_setup(dir * 20.0, dir * 1.0);
        setup.search_distance = 150.0;
        let out = home(setup, fake(0.0, (500.0, 510.0), 1000.0, 0.001));
        assert_eq!(out.homing.phase(), HomePhase::Failed);
        let err = out.homing.error().unwrap();
        assert_eq!(
            err,
            HomeError::SwitchNotFound {
                phase: HomePhase::Search,
                distance: 150.0
            }
        );
        assert_eq!(
            err.to_string(),
            "home switch not found within 150 mm in the search phase"
        );
        assert_eq!(out.last_command, HomeCommand::Stop);
        assert!(out.axis.at_rest());
        // At the end of the search window, and no further.
        assert_eq!(out.axis.x, dir * 150.0);
        assert_eq!(out.travel.len(), 1);
        assert!(out.travel[0].1 <= 150.0);
    }
}

/// A switch that sticks on or dies once the search has tripped it: the phase that then
/// looks for an edge never sees it and fails naming itself (stuck on: the back-off, or the
/// latch that moves off the switch; dead: the latch that approaches it again); a switch
/// stuck on from the start fails the initial back-off.
#[test]
fn a_dead_or_stuck_switch_fails_in_the_phase_that_misses_it() {
    for (same_sign, stuck, phase) in [
        (true, true, HomePhase::BackOff),
        (true, false, HomePhase::Latch),
        (false, true, HomePhase::Latch),
    ] {
        let latch = if same_sign { 1.0 } else { -1.0 };
        let mut setup = switch_setup(20.0, latch);
        setup.search_distance = 100.0;
        let mut axis = fake(0.0, (30.0, 40.0), 1000.0, 0.001);
        let mut homing = Homing::new(setup).unwrap();
        homing.start();
        let mut last = HomeCommand::Hold;
        for _ in 0..1_000_000 {
            if homing.phase() != HomePhase::Search {
                // Stuck or dead once the search has found it.
                axis.forced = Some(stuck);
            }
            let input = HomeInput {
                switch: axis.switch_active(),
                position: axis.x,
                at_rest: axis.at_rest(),
            };
            let c = homing.cycle(&input);
            if c != HomeCommand::Hold {
                last = c;
            }
            axis.apply(c, input.at_rest);
            if homing.phase() == HomePhase::Failed && axis.at_rest() {
                break;
            }
            axis.step();
        }
        assert_eq!(
            homing.error(),
            Some(HomeError::SwitchNotFound {
                phase,
                distance: 100.0
            })
        );
        assert!(homing.error().unwrap().to_string().contains(phase.name()));
        assert_eq!(last, HomeCommand::Stop);
    }
    // Stuck on: the initial back-off never gets off it.
    let mut setup = switch_setup(-20.0, 1.0);
    setup.search_distance = 50.0;
    let mut axis = fake(0.0, (30.0, 40.0), 1000.0, 0.001);
    axis.forced = Some(true);
    let out = home(setup, axis);
    assert_eq!(
        out.homing.error(),
        Some(HomeError::SwitchNotFound {
            phase: HomePhase::InitialBackOff,
            distance: 50.0
        })
    );
    assert_eq!(
        out.homing.error().unwrap().to_string(),
        "home switch not found within 50 mm in the initial back-off phase"
    );
    // It backed off against the (negative) search, and no further than the window.
    assert!(
        out.axis.x > 0.0 && out.axis.x <= 50.0 + 1e-9,
        "{}",
        out.axis.x
    );
}

/// No switch and absolute encoders complete at once without motion; only the absolute
/// encoder has a shift (its offset).
#[test]
fn no_switch_and_absolute_complete_at_once() {
    for (kind, shift) in [(HomeKind::None, None), (HomeKind::Absolute, Some(-3.25))] {
        let setup = HomeSetup {
            kind,
            search_velocity: 0.0,
            latch_velocity: 0.0,
            search_distance: 0.0,
            home_offset: -3.25,
            home_position: 0.0,
            final_speed: 0.0,
        };
        let mut h = Homing::new(setup).unwrap();
        assert_eq!(h.phase(), HomePhase::Idle);
        h.start();
        assert_eq!(h.phase(), HomePhase::Done);
        assert_eq!(h.absolute_shift(), shift);
        let input = HomeInput {
            switch: false,
            position: 1.0,
            at_rest: true,
        };
        assert_eq!(h.cycle(&input), HomeCommand::Hold);
        assert_eq!(h.error(), None);
    }
    let h = Homing::new(switch_setup(10.0, 1.0)).unwrap();
    assert_eq!(h.absolute_shift(), None);
}

/// An abort mid-search: the sequence fails with the phase named, the next cycle commands a
/// stop and later ones nothing; an abort when idle or done does nothing.
#[test]
fn abort_stops_and_names_the_phase() {
    let mut h = Homing::new(switch_setup(10.0, 1.0)).unwrap();
    h.abort();
    assert_eq!(h.phase(), HomePhase::Idle);
    h.start();
    let rest = HomeInput {
        switch: false,
        position: 0.0,
        at_rest: true,
    };
    assert!(matches!(h.cycle(&rest), HomeCommand::MoveTo { .. }));
    let moving = HomeInput {
        at_rest: false,
        position: 0.5,
        ..rest
    };
    assert_eq!(h.cycle(&moving), HomeCommand::Hold);
    h.abort();
    assert_eq!(h.phase(), HomePhase::Failed);
    assert_eq!(
        h.error(),
        Some(HomeError::Aborted {
            phase: HomePhase::Search
        })
    );
    assert_eq!(
        h.error().unwrap().to_string(),
        "homing aborted in the search phase"
    );
    assert_eq!(h.cycle(&moving), HomeCommand::Stop);
    assert_eq!(h.cycle(&moving), HomeCommand::Hold);
    // Started again, it begins afresh.
    h.start();
    assert_eq!(h.error(), None);
    assert_eq!(h.phase(), HomePhase::Search);
}

/// Started on a moving axis, the sequence first stops it and starts its search only at
/// rest.
#[test]
fn start_on_a_moving_axis_stops_it_first() {
    let mut h = Homing::new(switch_setup(-10.0, 1.0)).unwrap();
    h.start();
    let moving = HomeInput {
        switch: false,
        position: 3.0,
        at_rest: false,
    };
    assert_eq!(h.cycle(&moving), HomeCommand::Stop);
    assert_eq!(h.cycle(&moving), HomeCommand::Stop);
    let rest = HomeInput {
        at_rest: true,
        ..moving
    };
    assert_eq!(
        h.cycle(&rest),
        HomeCommand::MoveTo {
            position: 3.0 - 1000.0,
            speed: 10.0
        }
    );
}

/// Setups that cannot home are refused with the field named.
#[test]
fn bad_setups_are_refused_naming_the_field() {
    let good = switch_setup(10.0, -1.0);
    assert!(Homing::new(good).is_ok());
    /// A field and a way to spoil it.
    type Spoil = (&'static str, fn(&mut HomeSetup));
    let cases: [Spoil; 7] = [
        ("search_velocity", |s| s.search_velocity = 0.0),
        ("latch_velocity", |s| s.latch_velocity = 0.0),
        ("search_distance", |s| s.search_distance = -1.0),
        ("final_speed", |s| s.final_speed = 0.0),
        ("home_offset", |s| s.home_offset = f64::NAN),
        ("home_position", |s| s.home_position = f64::INFINITY),
        ("search_velocity", |s| s.search_velocity = f64::NAN),
    ];
    for (field, spoil) in cases {
        let mut s = good;
        spoil(&mut s);
        let e = Homing::new(s).unwrap_err();
        assert!(
            matches!(e, HomeError::Setup { field: f, .. } if f == field),
            "{e}"
        );
        assert!(
            e.to_string()
                .starts_with(&format!("homing setup: {field} = ")),
            "{e}"
        );
    }
    // Without a switch the speeds are not used.
    let none = HomeSetup {
        kind: HomeKind::None,
        search_velocity: 0.0,
        latch_velocity: 0.0,
        search_distance: 0.0,
        final_speed: 0.0,
        ..good
    };
    assert!(Homing::new(none).is_ok());
}

/// The phases' names, as messages and progress show them.
#[test]
fn phase_names() {
    let names: Vec<_> = [
        HomePhase::Idle,
        HomePhase::InitialBackOff,
        HomePhase::Search,
        HomePhase::BackOff,
        HomePhase::Latch,
        HomePhase::Final,
        HomePhase::Done,
        HomePhase::Failed,
    ]
    .iter()
    .map(|p| p.name())
    .collect();
    assert_eq!(
        names,
        [
            "idle",
            "initial back-off",
            "search",
            "back-off",
            "latch",
            "final move",
            "done",
            "failed"
        ]
    );
}

/// `cycle` never allocates: a counting allocator armed around whole homing sequences.
#[test]
fn cycle_never_allocates() {
    for same_sign in [true, false] {
        let latch = if same_sign { 2.0 } else { -2.0 };
        let setup = switch_setup(20.0, latch);
        let mut axis = fake(5.0, (0.0, 10.0), 2000.0, 0.001);
        let mut homing = Homing::new(setup).unwrap();
        homing.start();
        let count = Count::start();
        for _ in 0..200_000 {
            let input = HomeInput {
                switch: axis.switch_active(),
                position: axis.x,
                at_rest: axis.at_rest(),
            };
            let command = homing.cycle(&input);
            axis.apply(command, input.at_rest);
            axis.step();
            if homing.phase() == HomePhase::Done {
                break;
            }
        }
        let allocations = count.stop();
        assert_eq!(homing.phase(), HomePhase::Done);
        assert_eq!(allocations, 0);
    }
}
