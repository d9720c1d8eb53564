//! The motion core's state: [`MotionCore`] with its constructor, its read-only
//! accessors, the ring-buffer indexing of its segment and section queues, and clearing.

use kerf_geom::PerAxis;
use kerf_geom::{PlannedSegment, Vec3};
use rsruckig::prelude::*;

use crate::profile::JerkProfile;
use crate::section::Section;
use crate::{MotionState, Setpoint, Status};

/// The core's motion mode.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Mode {
    /// Following the lookahead plan.
    Run,
    /// Running the plan while a hold waits for a safe moment.
    HoldPending,
    /// Stopping on the path.
    Braking,
    /// Stopped on the path.
    Held,
}

/// The real-time motion core. See the crate documentation.
pub struct MotionCore {
    pub(crate) period_s: f64,
    pub(crate) segs: Vec<PlannedSegment>,
    /// Offset of each segment's start within its section (parallel to `segs`).
    pub(crate) seg_offset_mm: Vec<f64>,
    pub(crate) seg_head: u64,
    pub(crate) seg_count: u64,
    pub(crate) secs: Vec<Section>,
    pub(crate) sec_head: u64,
    pub(crate) sec_count: u64,
    /// The front section is running (its limits are frozen).
    pub(crate) running: bool,
    pub(crate) otg: Ruckig<1, IgnoreErrorHandler>,
    pub(crate) input: InputParameter<1>,
    pub(crate) traj: Trajectory<1>,
    /// Scratch trajectory: every calculation goes here and is swapped in on success.
    pub(crate) scratch: Trajectory<1>,
    /// Factor the running profile's positions are scaled by (see `calc`).
    pub(crate) traj_scale: f64,
    /// Seconds per time unit of the running profile (see `calc`).
    pub(crate) traj_time_scale_s: f64,
    /// Section-local position where the profile starts.
    pub(crate) traj_origin_mm: f64,
    /// Time since the profile start, s.
    pub(crate) traj_t_s: f64,
    /// End speed the running profile targets.
    pub(crate) traj_end_v_mm_s: f64,
    /// End acceleration the running profile targets: zero except where a speed-up goes on
    /// into the next section (see `carry_target`).
    pub(crate) traj_end_a_mm_s2: f64,
    /// The running profile is `own` (the closed-form fallback) instead of `traj`.
    pub(crate) own_active: bool,
    pub(crate) own: JerkProfile,
    /// When positive, the running "profile" is a coast at `traj_end_v_mm_s` through a sliver
    /// section this many seconds long instead of `traj` (see `calc`).
    pub(crate) coast_s: f64,
    /// Set when the lookahead raised the running section's end speed.
    pub(crate) replan: bool,
    /// The running section waits for its acceleration to come down to move to its boost
    /// level (see `replan_running`).
    pub(crate) boost_pending: bool,
    pub(crate) mode: Mode,
    pub(crate) abort_requested: bool,
    pub(crate) override_factor: f64,
    /// A hold requested by the operator is in force.
    pub(crate) user_hold: bool,
    /// A hold caused by a zero feed override is in force.
    pub(crate) override_hold: bool,
    /// Current segment (absolute index) and section-local state.
    pub(crate) cursor: u64,
    pub(crate) s_local_mm: f64,
    pub(crate) v_mm_s: f64,
    pub(crate) a_mm_s2: f64,
    pub(crate) last: Setpoint,
    pub(crate) failures: u64,
    /// Stops forced because no plan within a section existed (see `emergency_stop`).
    pub(crate) emergencies: u64,
    /// Units of the profile in `scratch` after `calc_brake` (see there).
    pub(crate) brake_scale: f64,
    pub(crate) brake_time_scale_s: f64,
    /// Tests: make every solver call fail, to exercise the fallbacks.
    #[cfg(test)]
    pub(crate) fail_solver: bool,
}

impl std::fmt::Debug for MotionCore {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MotionCore")
            .field("queued", &self.seg_count)
            .field("sections", &self.sec_count)
            .field("mode", &self.mode)
            .finish_non_exhaustive()
    }
}

impl MotionCore {
    /// A core interpolating at `period_s` (seconds per [`MotionCore::step`]) holding up to
    /// `capacity` segments. All memory is allocated here. The core needs no machine limits:
    /// every limit it keeps to is carried by the segments ([`PlannedSegment`]).
    pub fn new(period_s: f64, capacity: usize) -> Self {
        let capacity = capacity.max(2);
        let dummy = PlannedSegment::with_zero_limits(
            kerf_geom::Curve::line(Vec3::zeros(), Vec3::zeros()),
            0.0,
            ([0.0; 3], [0.0; 3]),
            0,
            0,
            0.0,
        );
        let mut input = InputParameter::new(None);
        input.min_velocity = Some(DataArrayOrVec::new(None, 0.0));
        let mut traj = Trajectory::new(None);
        traj.reserve_sections(1);
        let mut scratch = Trajectory::new(None);
        scratch.reserve_sections(1);
        MotionCore {
            period_s,
            segs: vec![dummy; capacity],
            seg_offset_mm: vec![0.0; capacity],
            seg_head: 0,
            seg_count: 0,
            secs: vec![Section::EMPTY; capacity],
            sec_head: 0,
            sec_count: 0,
            running: false,
            otg: Ruckig::new(None, period_s),
            input,
            traj,
            scratch,
            traj_scale: 1.0,
            traj_time_scale_s: 1.0,
            traj_origin_mm: 0.0,
            traj_t_s: 0.0,
            traj_end_v_mm_s: 0.0,
            traj_end_a_mm_s2: 0.0,
            own_active: false,
            own: JerkProfile::default(),
            coast_s: 0.0,
            replan: false,
            boost_pending: false,
            mode: Mode::Run,
            abort_requested: false,
            override_factor: 1.0,
            user_hold: false,
            override_hold: false,
            cursor: 0,
            s_local_mm: 0.0,
            v_mm_s: 0.0,
            a_mm_s2: 0.0,
            last: Setpoint::default(),
            failures: 0,
            emergencies: 0,
            brake_scale: 1.0,
            brake_time_scale_s: 1.0,
            #[cfg(test)]
            fail_solver: false,
        }
    }

    /// The interpolation period, s.
    pub fn period_s(&self) -> f64 {
        self.period_s
    }

    /// Capacity of the segment queue.
    pub fn capacity(&self) -> usize {
        self.segs.len()
    }

    /// Segments in the queue (including the one running).
    pub fn queued(&self) -> usize {
        self.seg_count as usize
    }

    /// Free queue slots.
    pub fn free(&self) -> usize {
        self.segs.len() - self.seg_count as usize
    }

    /// `true` when at rest with nothing queued.
    pub fn is_idle(&self) -> bool {
        self.seg_count == 0 && self.v_mm_s == 0.0
    }

    /// `true` while stopped on the path in feed hold (or by zero override).
    pub fn is_held(&self) -> bool {
        self.mode == Mode::Held
    }

    /// `true` while the core follows its plan: no hold pending, no stop on the path, not
    /// held. Only then does a pushed segment join the tail section where it can (see
    /// [`push`](Self::push)).
    pub fn follows_plan(&self) -> bool {
        self.mode == Mode::Run
    }

    /// A status snapshot.
    pub fn status(&self) -> Status {
        let state = match self.mode {
            Mode::Held => MotionState::Held,
            Mode::Braking => MotionState::Stopping,
            Mode::Run | Mode::HoldPending if self.is_idle() => MotionState::Idle,
            Mode::Run | Mode::HoldPending => MotionState::Running,
        };
        Status {
            state,
            line: self.last.line,
            queued: self.queued(),
            free: self.free(),
            feed_mm_s: self.v_mm_s,
            feed_override: self.override_factor,
            plan_failures: self.failures,
        }
    }

    /// Number of profile calculations that failed (each fell back to a safer plan).
    pub fn plan_failures(&self) -> u64 {
        self.failures
    }

    /// Number of jerk-limited stops forced because no plan within a section existed
    /// (zero while the lookahead holds; each is also a limit-respecting stop).
    pub fn emergency_stops(&self) -> u64 {
        self.emergencies
    }

    /// The feed override factor the plan uses (a zero override holds instead and leaves
    /// this at its previous value).
    pub fn feed_override(&self) -> f64 {
        self.override_factor
    }

    /// Sets the position the core rests at (only while idle); the first segment pushed
    /// should start there.
    pub fn set_position(&mut self, position: PerAxis<f64>) {
        if self.is_idle() {
            self.last.position = position;
        }
    }

    /// Drops the queue and every motion state at once and rests at `position`: for the
    /// drive side's quick stop, after which the drives stand where its jerk-limited ramp
    /// brought them, not where this core's path stop would have. Never allocates.
    pub fn reset_to(&mut self, position: PerAxis<f64>) {
        self.clear();
        self.last = Setpoint {
            position,
            ..Setpoint::default()
        };
    }

    pub(crate) fn seg(&self, abs: u64) -> &PlannedSegment {
        &self.segs[(abs % self.segs.len() as u64) as usize]
    }

    pub(crate) fn sec_slot(&self, abs: u64) -> usize {
        (abs % self.secs.len() as u64) as usize
    }

    pub(crate) fn sec(&self, abs: u64) -> &Section {
        &self.secs[self.sec_slot(abs)]
    }

    pub(crate) fn sec_mut(&mut self, abs: u64) -> &mut Section {
        let i = self.sec_slot(abs);
        &mut self.secs[i]
    }

    /// Forgets which program line the last setpoint came from (a new program begins at
    /// rest here: until its first segment runs, its setpoints name no line, as a fresh
    /// core's do).
    pub fn forget_line(&mut self) {
        let position = self.last.position;
        self.last = Setpoint {
            position,
            ..Setpoint::default()
        };
    }

    pub(crate) fn clear(&mut self) {
        self.seg_head += self.seg_count;
        self.seg_count = 0;
        self.sec_head += self.sec_count;
        self.sec_count = 0;
        self.running = false;
        self.mode = Mode::Run;
        self.abort_requested = false;
        self.user_hold = false;
        self.override_hold = false;
        self.v_mm_s = 0.0;
        self.a_mm_s2 = 0.0;
        self.s_local_mm = 0.0;
        self.last.feed_mm_s = 0.0;
    }
}
