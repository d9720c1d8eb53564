//! What a program asks of the machine besides motion, as the motion runs it: the
//! [`Action`]s (a pause, a tool change, the spindle, coolant, outputs, a wait on an input)
//! at their points of the path, when each takes effect ([`Sync`]), and the interface
//! through which the per-cycle step hands them to the machine ([`MachineIo`], answered
//! with a [`Gate`]).
//!
//! They live here, below the pipeline (which runs them in `kerf sim` and the daemon) and
//! the drive side (which switches the outputs), so that neither depends on the other.
//! Every type is `Copy` and holds no text: actions cross the real-time thread.

/// Why a program pauses (the state `paused` shows it with the line).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PauseCode {
    /// Program stop (M0 and the other controls' equivalents).
    ProgramStop,
    /// Optional program stop (M1): a pause only while the optional-stop switch is on.
    OptionalStop,
    /// Pallet change pause (LinuxCNC M60): a pause like M0.
    PalletChange,
    /// Single block: the block before has ended.
    SingleBlock,
}

/// The spindle's direction of rotation as commanded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpindleDir {
    /// Stopped (M5).
    Off,
    /// Clockwise (M3).
    Cw,
    /// Counter-clockwise (M4).
    Ccw,
}

impl SpindleDir {
    /// +1 clockwise, -1 counter-clockwise, 0 stopped.
    pub fn sign(self) -> f64 {
        match self {
            SpindleDir::Off => 0.0,
            SpindleDir::Cw => 1.0,
            SpindleDir::Ccw => -1.0,
        }
    }
}

/// How a wait on an input ends (LinuxCNC's M66 L word).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WaitMode {
    /// L0: no wait; the input is read at once.
    Immediate,
    /// L1: wait for a rising edge (the input goes from off to on).
    Rise,
    /// L2: wait for a falling edge.
    Fall,
    /// L3: wait until the input is on.
    High,
    /// L4: wait until the input is off.
    Low,
}

impl WaitMode {
    /// The mode of an L word (0–4), `None` for any other.
    pub fn from_l(l: u32) -> Option<WaitMode> {
        Some(match l {
            0 => WaitMode::Immediate,
            1 => WaitMode::Rise,
            2 => WaitMode::Fall,
            3 => WaitMode::High,
            4 => WaitMode::Low,
            _ => return None,
        })
    }

    /// The L word of this mode.
    pub fn l(self) -> u32 {
        match self {
            WaitMode::Immediate => 0,
            WaitMode::Rise => 1,
            WaitMode::Fall => 2,
            WaitMode::High => 3,
            WaitMode::Low => 4,
        }
    }
}

/// When an action takes effect relative to the motion around it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Sync {
    /// After the motion before it has come to rest (the path is not blended across it),
    /// and the motion after it waits until the action is done (its [`Gate`]).
    AtRest,
    /// With the start of the next move: when the motion has finished every segment
    /// planned before it, without stopping (LinuxCNC M62, M63, M67).
    WithMotion,
    /// As soon as the motion takes it from the planner, ahead of the moves queued before
    /// it (LinuxCNC M64, M65, M68: "immediately").
    Immediate,
}

/// What a program asks of the machine at one point of its path.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ActionKind {
    /// Pause until cycle start (`kerf resume`).
    Pause(PauseCode),
    /// Put tool `tool` in the spindle (M6 after T): the tool changer's business (a
    /// manual change pauses until the operator confirms).
    ToolChange {
        /// The tool number (0: unload the spindle).
        tool: u32,
    },
    /// The spindle command in force from here on (M3, M4, M5 and S resolved together).
    Spindle {
        /// Direction.
        dir: SpindleDir,
        /// Programmed speed, rpm (>= 0; kept while stopped, for the next start).
        rpm: f64,
    },
    /// Wait until the spindle is at its commanded speed (inserted before the first feed
    /// move after a spindle start or speed change; rapids do not wait).
    WaitAtSpeed,
    /// Orient the spindle (M19): stop it at `angle_deg`, turning by `mode` (0 the shorter
    /// way, 1 clockwise, 2 counter-clockwise); `timeout_s` bounds the wait (infinite
    /// without Q).
    Orient {
        /// Angle, degrees, 0–360.
        angle_deg: f64,
        /// Direction mode.
        mode: u8,
        /// Most time to wait, s.
        timeout_s: f64,
    },
    /// The coolant outputs in force from here on (M7, M8, M9).
    Coolant {
        /// Mist (M7).
        mist: bool,
        /// Flood (M8).
        flood: bool,
    },
    /// Switch digital output `output` (M62–M65).
    Digital {
        /// Output number (the program's P word).
        output: u8,
        /// On or off.
        on: bool,
        /// With the next move (M62, M63) or at once (M64, M65).
        sync: Sync,
    },
    /// Set analog output `output` (M67, M68).
    Analog {
        /// Output number (the program's E word).
        output: u8,
        /// The value (the program's Q word).
        value: f64,
        /// With the next move (M67) or at once (M68).
        sync: Sync,
    },
    /// Wait on input `input` (M66) and keep its value for `#5399`: a digital input's
    /// state (1/0), an analog input's value, or -1 on a timeout.
    WaitInput {
        /// Input number (the program's P or E word).
        input: u8,
        /// An analog input (E word) rather than a digital one (P word).
        analog: bool,
        /// When the wait ends.
        mode: WaitMode,
        /// Most time to wait, s (the Q word; 0 with L0).
        timeout_s: f64,
    },
    /// The overrides' enables from here on (M48–M51): `None` leaves one as it is.
    Overrides {
        /// Feed override enabled.
        feed: Option<bool>,
        /// Spindle override enabled.
        spindle: Option<bool>,
    },
    /// The program ended (M2, M30): the spindle and coolant are switched off as
    /// configured.
    ProgramEnd,
}

/// One action at its point of the program.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Action {
    /// 1-based source line.
    pub line: u32,
    /// What to do.
    pub kind: ActionKind,
}

impl Action {
    /// When it takes effect.
    pub fn sync(&self) -> Sync {
        match self.kind {
            ActionKind::Digital { sync, .. } | ActionKind::Analog { sync, .. } => sync,
            // LinuxCNC queues the override enables with the motion.
            ActionKind::Overrides { .. } => Sync::WithMotion,
            _ => Sync::AtRest,
        }
    }
}

/// The machine's answer to an action it was handed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Gate {
    /// Done: the program goes on.
    Done,
    /// Not yet (a pause, a tool change, the spindle coming up to speed, a wait on an
    /// input): asked again next cycle.
    Wait,
}

/// The machine side of the per-cycle step: it carries out the program's actions.
/// Implementations run in the real-time cycle and must not allocate, lock or block.
pub trait MachineIo {
    /// Carries out `action`, or goes on with it: called once per cycle while the action
    /// is due ([`Sync::AtRest`]: once the motion before it is at rest) until it returns
    /// [`Gate::Done`]. Actions with [`Sync::WithMotion`] or [`Sync::Immediate`] are
    /// called once; their answer is not waited for.
    fn act(&mut self, action: &Action) -> Gate;

    /// The program was aborted or dropped while `action` was being carried out (a pause
    /// ended by abort, a tool change or wait cut short): the machine forgets it.
    fn cancel(&mut self, _action: &Action) {}
}

/// A machine that carries out every action at once: `kerf sim` and the offline runs
/// (an operator who presses cycle start at once, a spindle always at speed, inputs that
/// never change).
#[derive(Clone, Copy, Debug, Default)]
pub struct InstantMachine;

impl MachineIo for InstantMachine {
    fn act(&mut self, _action: &Action) -> Gate {
        Gate::Done
    }
}
