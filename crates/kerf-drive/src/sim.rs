//! The simulated CiA 402 servo drive: the whole power state machine and a servo model,
//! deterministic (a fixed period, no clock), allocation-free.
//!
//! The servo model, in cyclic synchronous position mode while Operation enabled:
//! within each period the position reference `r` goes linearly from the previous target
//! to the new one (the drive's own interpolation of the cyclic target), the velocity
//! feed-forward is `kff · (target − previous target) / period`, and the commanded
//! acceleration of the motor (torque / inertia) is
//! `a = (ωn² (r − x) + 2 ζ ωn (v_ff − v)) / ρ` with `ωn = 2π · bandwidth_hz` and ρ the
//! `inertia_ratio`: the load's inertia over the inertia the loop was tuned for (1: tuned
//! for this load; 2: twice as heavy, so the same torque accelerates it half as much, the
//! loop's natural frequency falls by √2 and its damping too). The motor is a
//! double integrator (`x'' = a`), integrated with `substeps` semi-implicit Euler steps per
//! period. Without feed-forward the loop is the textbook second-order system (step
//! overshoot `exp(−ζπ/√(1−ζ²))`); with full feed-forward the following error under an
//! acceleration `A` settles at `A / ωn²`.
//!
//! A commanded acceleration above `overcurrent_accel_counts_s2` trips the overcurrent
//! fault (error code 0x2310); [`SimDrive::inject_fault`] trips any code. A fault goes
//! through Fault reaction active (one cycle, the holding brake stops the motor) to Fault,
//! which only a rising edge of controlword bit 7 leaves, and only once no fault cause is
//! set ([`SimDrive::set_fault_cause`]). Quick stop (option code 2): the motor ramps to
//! rest at `quick_stop_decel_counts_s2`, then the drive goes to Switch on disabled.
//! Without power (every state but Operation enabled and Quick stop active) the holding
//! brake keeps the motor where it is.
//!
//! Homing mode (6, [`homing`]): the drive homes itself with the method and parameters of
//! its [`SimHomingConfig`] ([`SimDrive::set_homing_config`], what a master writes to a
//! real drive by SDO) once controlword bit 4 rises in Operation enabled; the falling edge
//! of bit 4 or the halt bit (8) interrupt it. Statusword bits 10, 12 and 13 then say
//! where it is ([`crate::cia402::HomingStatus`]). At the home position the drive
//! redefines its coordinates: the position actual value there becomes the home offset.
//! A change of the mode of operation away from homing takes effect only once the homing
//! motion is at rest (until then the mode display stays 6); back in cyclic synchronous
//! position the drive follows its targets from its new coordinates.

pub mod homing;

pub use homing::{SUPPORTED_METHODS, SimHomingConfig, is_supported_method};

use crate::cia402::{
    Drive, DriveCommand, DriveState, MODE_CYCLIC_SYNC_POSITION, MODE_HOMING, cw,
    is_fault_reset_edge, sw,
};
use homing::HomingMotion;

/// Error code 0x2310: continuous over current.
pub const ERROR_OVERCURRENT: u16 = 0x2310;

/// The simulated drive's parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimConfig {
    /// The cycle period, ns.
    pub period_ns: u64,
    /// Position loop natural frequency, Hz (ωn = 2π · bandwidth).
    pub bandwidth_hz: f64,
    /// Damping ratio ζ.
    pub damping: f64,
    /// The load's inertia over the inertia the position loop was tuned for, ρ (1: tuned
    /// for it). The commanded torque accelerates the load by 1/ρ of what the loop asks.
    pub inertia_ratio: f64,
    /// Velocity feed-forward gain, 0 (none) to 1 (full).
    pub velocity_feed_forward: f64,
    /// Integration steps per period (at least 1).
    pub substeps: u32,
    /// A commanded acceleration above this trips the overcurrent fault, counts/s².
    pub overcurrent_accel_counts_s2: f64,
    /// The drive's own quick-stop deceleration, counts/s².
    pub quick_stop_decel_counts_s2: f64,
    /// Following error window: statusword bit 13 is set above it, counts.
    pub following_error_window_counts: u32,
    /// The motor position at power-up, counts.
    pub initial_position_counts: f64,
}

impl Default for SimConfig {
    /// A well-tuned drive at 1 kHz: 50 Hz, ζ = 1, full feed-forward.
    fn default() -> Self {
        SimConfig {
            period_ns: 1_000_000,
            bandwidth_hz: 50.0,
            damping: 1.0,
            inertia_ratio: 1.0,
            velocity_feed_forward: 1.0,
            substeps: 20,
            overcurrent_accel_counts_s2: 1.0e9,
            quick_stop_decel_counts_s2: 1.0e6,
            following_error_window_counts: 1000,
            initial_position_counts: 0.0,
        }
    }
}

impl SimConfig {
    /// The loop as the load sees it: natural frequency ωn/√ρ (rad/s) and damping ratio
    /// ζ/√ρ.
    fn effective(&self) -> (f64, f64) {
        let root = self.inertia_ratio.max(f64::MIN_POSITIVE).sqrt();
        (
            2.0 * core::f64::consts::PI * self.bandwidth_hz / root,
            self.damping / root,
        )
    }

    /// ω·h·(ω·h + 4ζ) for the integration step h = period / substeps, with the loop's
    /// effective ω = ωn/√ρ and ζ/√ρ: the servo model's semi-implicit Euler step is stable
    /// below 4 (the eigenvalues of its step matrix, whose determinant is 1 − 2ζω·h and
    /// trace 2 − (ω·h)² − 2ζω·h, stay inside the unit circle exactly then).
    pub fn stability_index(&self) -> f64 {
        let (omega, zeta) = self.effective();
        let h = self.period_ns as f64 * 1e-9 / f64::from(self.substeps.max(1));
        omega * h * (omega * h + 4.0 * zeta)
    }

    /// The fewest substeps that keep [`SimConfig::stability_index`] at most 2 (half the
    /// stability bound, so that the model is also accurate).
    pub fn min_substeps(&self) -> u32 {
        let (omega, zeta) = self.effective();
        let period_s = self.period_ns as f64 * 1e-9;
        // ωh(ωh + 4ζ) ≤ 2  ⇔  ωh ≤ −2ζ + √(4ζ² + 2).
        let max_omega_h = -2.0 * zeta + (4.0 * zeta * zeta + 2.0).sqrt();
        let n = (omega * period_s / max_omega_h).ceil();
        if n.is_finite() && n >= 1.0 {
            n.min(f64::from(u32::MAX)) as u32
        } else {
            1
        }
    }
}

/// A simulated CiA 402 drive (see the module documentation).
// A copy would be a second instance of its state, silently diverging from the first.
#[allow(missing_copy_implementations)]
#[derive(Debug, Clone)]
pub struct SimDrive {
    config: SimConfig,
    state: DriveState,
    /// The mode of operation in effect (the display).
    mode: i8,
    /// The mode of operation the master wrote; takes effect once allowed.
    requested_mode: i8,
    position_counts: f64,
    velocity_counts_s: f64,
    previous_target_counts: f64,
    demand_counts: i32,
    last_controlword: u16,
    error_code: u16,
    pending_fault: Option<u16>,
    fault_cause: Option<u16>,
    homing: HomingMotion,
}

fn saturate_i32(value: f64) -> i32 {
    let rounded = value.round();
    if rounded.is_nan() {
        0
    } else if rounded >= f64::from(i32::MAX) {
        i32::MAX
    } else if rounded <= f64::from(i32::MIN) {
        i32::MIN
    } else {
        rounded as i32
    }
}

impl SimDrive {
    /// A drive in Not ready to switch on, mode of operation 8, motor at rest at the
    /// configured initial position.
    pub fn new(config: SimConfig) -> SimDrive {
        SimDrive {
            config,
            state: DriveState::NotReadyToSwitchOn,
            mode: MODE_CYCLIC_SYNC_POSITION,
            requested_mode: MODE_CYCLIC_SYNC_POSITION,
            position_counts: config.initial_position_counts,
            velocity_counts_s: 0.0,
            previous_target_counts: config.initial_position_counts,
            demand_counts: saturate_i32(config.initial_position_counts),
            last_controlword: 0,
            error_code: 0,
            pending_fault: None,
            fault_cause: None,
            homing: HomingMotion::new(config.initial_position_counts),
        }
    }

    /// Sets the homing parameters (what a master writes to a real drive by SDO: 0x6098,
    /// 0x6099, 0x609A, 0x607C) and where the simulated home switch is; they take effect
    /// at the next start of a homing.
    pub fn set_homing_config(&mut self, config: SimHomingConfig) {
        self.homing.set_config(config);
    }

    /// The homing parameters.
    pub fn homing_config(&self) -> &SimHomingConfig {
        self.homing.config()
    }

    /// The configuration.
    pub fn config(&self) -> &SimConfig {
        &self.config
    }

    /// The power state.
    pub fn state(&self) -> DriveState {
        self.state
    }

    /// The motor position, counts (not rounded).
    pub fn motor_position_counts(&self) -> f64 {
        self.position_counts
    }

    /// The motor position in its own frame, counts: where it is from power-up, before
    /// any homing redefined the drive's coordinates (the frame the home switch of
    /// [`SimHomingConfig::home_switch_counts`] is placed in).
    pub fn motor_frame_position_counts(&self) -> f64 {
        self.position_counts - self.homing.frame_shift()
    }

    /// Whether the simulated home switch is active (the drive's digital input 0x60FD bit
    /// 2): never without one, or with a method that homes without a switch.
    pub fn home_switch_active(&self) -> bool {
        self.homing.switch_is_active(self.position_counts)
    }

    /// The motor velocity, counts/s (not rounded).
    pub fn motor_velocity_counts_s(&self) -> f64 {
        self.velocity_counts_s
    }

    /// Test hook: the next `write` trips a fault with this error code.
    pub fn inject_fault(&mut self, error_code: u16) {
        self.pending_fault = Some(error_code);
    }

    /// Test hook: a lasting fault cause (e.g. a tripped thermal switch). While it is set
    /// the drive goes to Fault and refuses a fault reset; `None` removes the cause.
    pub fn set_fault_cause(&mut self, error_code: Option<u16>) {
        self.fault_cause = error_code;
    }

    fn period_s(&self) -> f64 {
        self.config.period_ns as f64 * 1e-9
    }

    fn trip(&mut self, error_code: u16) {
        self.state = DriveState::FaultReactionActive;
        self.error_code = error_code;
    }

    /// The power state machine for one controlword.
    fn transition(&mut self, controlword: u16, target_counts: i32) {
        let edge = is_fault_reset_edge(self.last_controlword, controlword);
        self.last_controlword = controlword;
        if let Some(code) = self.pending_fault.take().or(self.fault_cause)
            && !matches!(self.state, FaultReactionActive | Fault)
        {
            self.trip(code);
            return;
        }
        let command = DriveCommand::from_controlword(controlword);
        use DriveState::*;
        let next = match (self.state, command) {
            (NotReadyToSwitchOn, _) => SwitchOnDisabled, // 1 (initialisation done)
            (FaultReactionActive, _) => Fault,           // 14
            (Fault, _) if edge && self.fault_cause.is_none() => {
                self.error_code = 0;
                SwitchOnDisabled // 15
            }
            (Fault, _) => Fault,
            (SwitchOnDisabled, Some(DriveCommand::Shutdown)) => ReadyToSwitchOn, // 2
            (ReadyToSwitchOn, Some(DriveCommand::SwitchOn | DriveCommand::EnableOperation)) => {
                SwitchedOn // 3
            }
            (ReadyToSwitchOn, Some(DriveCommand::DisableVoltage | DriveCommand::QuickStop)) => {
                SwitchOnDisabled // 7
            }
            (SwitchedOn, Some(DriveCommand::EnableOperation)) => OperationEnabled, // 4
            (SwitchedOn, Some(DriveCommand::Shutdown)) => ReadyToSwitchOn,         // 6
            (SwitchedOn, Some(DriveCommand::DisableVoltage | DriveCommand::QuickStop)) => {
                SwitchOnDisabled // 10
            }
            (OperationEnabled, Some(DriveCommand::SwitchOn)) => SwitchedOn, // 5
            (OperationEnabled, Some(DriveCommand::Shutdown)) => ReadyToSwitchOn, // 8
            (OperationEnabled, Some(DriveCommand::DisableVoltage)) => SwitchOnDisabled, // 9
            (OperationEnabled, Some(DriveCommand::QuickStop)) => QuickStopActive, // 11
            (QuickStopActive, Some(DriveCommand::DisableVoltage)) => SwitchOnDisabled, // 12
            (state, _) => state,
        };
        if next == OperationEnabled && self.state != OperationEnabled {
            // The drive takes the target of the enabling cycle as where it starts.
            self.previous_target_counts = f64::from(target_counts);
        }
        self.state = next;
    }

    /// One period of the motor.
    fn physics(&mut self, target_counts: i32) {
        let period_s = self.period_s();
        let substeps = self.config.substeps.max(1);
        let dt_s = period_s / f64::from(substeps);
        match self.state {
            DriveState::OperationEnabled if self.mode == MODE_HOMING => {
                self.homing_physics(substeps, dt_s, period_s);
            }
            DriveState::OperationEnabled => {
                let start = self.previous_target_counts;
                let end = if self.mode == MODE_CYCLIC_SYNC_POSITION {
                    f64::from(target_counts)
                } else {
                    start
                };
                let omega = 2.0 * core::f64::consts::PI * self.config.bandwidth_hz;
                let v_ff = if period_s > 0.0 {
                    self.config.velocity_feed_forward * (end - start) / period_s
                } else {
                    0.0
                };
                for i in 0..substeps {
                    // The reference at the start of the substep, with x and v there.
                    let reference = start + (end - start) * f64::from(i) / f64::from(substeps);
                    // What the loop asks for (the torque, at the tuned inertia)…
                    let accel = omega * omega * (reference - self.position_counts)
                        + 2.0 * self.config.damping * omega * (v_ff - self.velocity_counts_s);
                    if accel.is_nan() || accel.abs() > self.config.overcurrent_accel_counts_s2 {
                        self.trip(ERROR_OVERCURRENT);
                        self.velocity_counts_s = 0.0;
                        break;
                    }
                    // … and what the load does with it.
                    self.velocity_counts_s += accel / self.config.inertia_ratio * dt_s;
                    self.position_counts += self.velocity_counts_s * dt_s;
                }
                self.previous_target_counts = end;
                self.demand_counts = saturate_i32(end);
            }
            DriveState::QuickStopActive => {
                let decel = self.config.quick_stop_decel_counts_s2.abs();
                for _ in 0..substeps {
                    let v = self.velocity_counts_s;
                    let dv = decel * dt_s;
                    let v_next = if v.abs() <= dv {
                        0.0
                    } else {
                        v - dv * v.signum()
                    };
                    self.position_counts += 0.5 * (v + v_next) * dt_s;
                    self.velocity_counts_s = v_next;
                }
                self.demand_counts = saturate_i32(self.position_counts);
                if self.velocity_counts_s == 0.0 {
                    self.state = DriveState::SwitchOnDisabled; // 12: quick stop completed
                }
            }
            _ => {
                // Holding brake: the motor stays where it is.
                self.velocity_counts_s = 0.0;
                self.demand_counts = saturate_i32(self.position_counts);
            }
        }
        let homing_mode = self.state == DriveState::OperationEnabled && self.mode == MODE_HOMING;
        if !homing_mode && !self.homing.at_rest() {
            // Out of Operation enabled (a fault, a quick stop, a disable): the homing ends.
            self.homing.hold(self.previous_target_counts);
        }
    }

    /// The requested mode of operation takes effect unless it leaves homing mode while the
    /// homing motion moves.
    fn apply_mode(&mut self) {
        if self.requested_mode == self.mode {
            return;
        }
        if self.mode == MODE_HOMING && !self.homing.at_rest() {
            return;
        }
        if self.requested_mode == MODE_HOMING {
            // Homing mode starts holding where the position reference stands.
            self.homing.hold(self.previous_target_counts);
        }
        self.mode = self.requested_mode;
    }

    /// Controlword bits 4 and 8 in homing mode: the rising edge of bit 4 starts a homing,
    /// its falling edge or the halt bit interrupt it.
    fn homing_control(&mut self, previous: u16, controlword: u16) {
        if self.mode != MODE_HOMING || self.state != DriveState::OperationEnabled {
            return;
        }
        let was = previous & cw::HOMING_START != 0;
        let is = controlword & cw::HOMING_START != 0;
        let halt = controlword & cw::HALT != 0;
        if halt || (was && !is) {
            self.homing.interrupt();
        } else if is && !was {
            let reference = self.previous_target_counts;
            if let Some(delta) = self.homing.start(self.position_counts, reference) {
                self.redefine(delta);
            }
        }
    }

    /// The drive's coordinates move by `delta` counts (homing attained): the motor does
    /// not move, every position the drive holds reads `delta` more.
    fn redefine(&mut self, delta: f64) {
        self.position_counts += delta;
        self.previous_target_counts = self.homing.reference();
    }

    /// One period of the homing motion: the servo model follows the drive's own reference
    /// with full velocity and acceleration feed-forward.
    fn homing_physics(&mut self, substeps: u32, dt_s: f64, period_s: f64) {
        if self.homing.at_rest() {
            // At rest the reference is the drive's position reference (the one it was
            // enabled at, or where the last homing ended).
            self.homing.hold(self.previous_target_counts);
        }
        let omega = 2.0 * core::f64::consts::PI * self.config.bandwidth_hz;
        for _ in 0..substeps {
            let (r, v_ref, a_ref) = self.homing.command(dt_s);
            let accel = a_ref
                + omega * omega * (r - self.position_counts)
                + 2.0 * self.config.damping * omega * (v_ref - self.velocity_counts_s);
            if accel.is_nan() || accel.abs() > self.config.overcurrent_accel_counts_s2 {
                self.trip(ERROR_OVERCURRENT);
                self.velocity_counts_s = 0.0;
                break;
            }
            self.velocity_counts_s += accel / self.config.inertia_ratio * dt_s;
            self.position_counts += self.velocity_counts_s * dt_s;
            self.homing.advance(a_ref, dt_s);
            if let Some(delta) =
                self.homing
                    .observe(self.position_counts, self.velocity_counts_s, dt_s, period_s)
            {
                self.redefine(delta);
            }
        }
        self.previous_target_counts = self.homing.reference();
        self.demand_counts = saturate_i32(self.previous_target_counts);
    }
}

impl Drive for SimDrive {
    fn write(&mut self, controlword: u16, target_position_counts: i32) {
        self.apply_mode();
        let previous = self.last_controlword;
        self.transition(controlword, target_position_counts);
        self.homing_control(previous, controlword);
        self.physics(target_position_counts);
    }

    fn set_mode_of_operation(&mut self, mode: i8) {
        self.requested_mode = mode;
        self.apply_mode();
    }

    fn mode_of_operation_display(&self) -> i8 {
        self.mode
    }

    fn statusword(&self) -> u16 {
        let mut word = self.state.statusword_bits() | sw::REMOTE;
        if self.mode == MODE_HOMING {
            // Bits 10, 12 and 13 are the homing's in homing mode.
            if self.state == DriveState::OperationEnabled {
                word |= self.homing.status().statusword_bits();
            }
            return word;
        }
        if self.state == DriveState::OperationEnabled && self.mode == MODE_CYCLIC_SYNC_POSITION {
            word |= sw::DRIVE_FOLLOWS_TARGET;
        }
        if self.following_error_counts().unsigned_abs() > self.config.following_error_window_counts
        {
            word |= sw::FOLLOWING_ERROR;
        }
        word
    }

    fn position_actual_counts(&self) -> i32 {
        saturate_i32(self.position_counts)
    }

    fn velocity_actual_counts_s(&self) -> i32 {
        saturate_i32(self.velocity_counts_s)
    }

    fn following_error_counts(&self) -> i32 {
        self.demand_counts
            .saturating_sub(self.position_actual_counts())
    }

    fn error_code(&self) -> u16 {
        self.error_code
    }
}
