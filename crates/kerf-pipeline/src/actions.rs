//! What a program's non-motion events ask of the machine ([`ProgramActions`]: events in,
//! [`Input`]s out, with the modal state of the spindle and coolant that turns `S`, `M3`,
//! `M8` … into whole commands), and where the actions synchronised with the motion go
//! among the planned segments ([`ActionOrder`]). Both planning threads (`kerf sim`'s and
//! the daemon's) run them, so that both run the same actions at the same points.

use std::collections::VecDeque;

use kerf_geom::machine::{Action, ActionKind, PauseCode, SpindleDir, Sync, WaitMode};
use kerf_geom::{Event, EventCode, Item, Move};
use kerf_plan::PlannedSegment;

use crate::{Input, Planned};

/// The modal machine state of one program as its events set it, and the inputs each
/// event and move means to the motion and the machine.
///
/// - A dwell (`G4`) is an exact stop and a rest.
/// - M0, M1 and M60 are pauses (M1 only while the optional-stop switch is on, which the
///   machine decides when it gets there); M2 and M30 end the program (the machine switches
///   the spindle and coolant off as configured); M6 is the change to the tool selected by
///   the last T (without a T, nothing changes: the tool in the spindle stays), and it
///   leaves the spindle stopped (as LinuxCNC's M6 does).
/// - M3, M4 and M5 with the last S make the spindle command; an S while the spindle
///   turns changes its speed; an S while it stands only sets the speed of the next start.
///   The first feed move after a start or a change of speed waits until the spindle is at
///   speed (a [`ActionKind::WaitAtSpeed`] before it); rapids do not wait. M19 orients the
///   spindle (it then stands).
/// - M7, M8 and M9 set the coolant outputs.
/// - M62–M65 and M67/M68 switch outputs (with the next move, or at once); M66 waits on an
///   input. M48–M51 enable and disable the overrides (with the motion).
/// - Every action the machine waits for is an exact stop: the control acts once the
///   motion before it has finished, as LinuxCNC's task does. A user M code (M100–M199)
///   is an exact stop too (its program runs after the motion before it).
/// - T, the messages (MSG, DEBUG, PRINT), LinuxCNC's log calls and M52/M53 do not stop
///   the motion and ask nothing of the machine.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProgramActions {
    rpm: f64,
    dir: SpindleDir,
    mist: bool,
    flood: bool,
    tool: Option<u32>,
    loaded: Option<u32>,
    at_speed_due: bool,
}

impl Default for ProgramActions {
    fn default() -> Self {
        ProgramActions::new()
    }
}

impl ProgramActions {
    /// The state at the start of a program: spindle stopped at 0 rpm, coolant off, no
    /// tool selected.
    pub fn new() -> Self {
        ProgramActions {
            rpm: 0.0,
            dir: SpindleDir::Off,
            mist: false,
            flood: false,
            tool: None,
            loaded: None,
            at_speed_due: false,
        }
    }

    /// The spindle as the program has commanded it so far: direction and speed, rpm.
    pub fn spindle(&self) -> (SpindleDir, f64) {
        (self.dir, self.rpm)
    }

    /// The coolant as the program has commanded it so far: mist, flood.
    pub fn coolant(&self) -> (bool, bool) {
        (self.mist, self.flood)
    }

    /// The tool the program's last M6 put in the spindle (`None` before its first M6).
    pub fn loaded_tool(&self) -> Option<u32> {
        self.loaded
    }

    /// The input an event means to the motion and the machine, if any.
    pub fn event(&mut self, e: &Event) -> Option<Input> {
        use EventCode as C;
        let act = |kind| Some(Input::Action(Action { line: e.line, kind }));
        let number = |v: Option<f64>| v.map_or(0, |n| n.clamp(0.0, 255.0) as u8);
        match e.code {
            C::G4 => Some(Input::Dwell(e.value.unwrap_or(0.0))),
            C::M0 => act(ActionKind::Pause(PauseCode::ProgramStop)),
            C::M1 => act(ActionKind::Pause(PauseCode::OptionalStop)),
            C::M60 => act(ActionKind::Pause(PauseCode::PalletChange)),
            C::M2 | C::M30 => {
                self.dir = SpindleDir::Off;
                self.mist = false;
                self.flood = false;
                self.at_speed_due = false;
                act(ActionKind::ProgramEnd)
            }
            C::T => {
                self.tool = e.value.map(|t| t.max(0.0) as u32);
                None
            }
            C::M6 => match self.tool {
                Some(tool) => {
                    self.loaded = Some(tool);
                    // The change stops the spindle (as LinuxCNC's M6 does): the program
                    // starts it again with M3 or M4, and the feed after that waits.
                    self.dir = SpindleDir::Off;
                    self.at_speed_due = false;
                    act(ActionKind::ToolChange { tool })
                }
                None => Some(Input::Stop),
            },
            C::S => {
                self.rpm = e.value.unwrap_or(0.0).max(0.0);
                if self.dir == SpindleDir::Off {
                    return None;
                }
                self.at_speed_due = true;
                act(self.spindle_command())
            }
            C::M3 | C::M4 => {
                self.dir = if e.code == C::M3 {
                    SpindleDir::Cw
                } else {
                    SpindleDir::Ccw
                };
                self.at_speed_due = true;
                act(self.spindle_command())
            }
            C::M5 => {
                self.dir = SpindleDir::Off;
                self.at_speed_due = false;
                act(self.spindle_command())
            }
            C::M19 => {
                self.dir = SpindleDir::Off;
                self.at_speed_due = false;
                act(ActionKind::Orient {
                    angle_deg: e.value.unwrap_or(0.0),
                    mode: e.p.map_or(0, |p| p.clamp(0.0, 2.0) as u8),
                    timeout_s: e.q.unwrap_or(f64::INFINITY),
                })
            }
            C::M7 | C::M8 | C::M9 => {
                match e.code {
                    C::M7 => self.mist = true,
                    C::M8 => self.flood = true,
                    _ => (self.mist, self.flood) = (false, false),
                }
                act(ActionKind::Coolant {
                    mist: self.mist,
                    flood: self.flood,
                })
            }
            C::M62 | C::M63 | C::M64 | C::M65 => act(ActionKind::Digital {
                output: number(e.value),
                on: matches!(e.code, C::M62 | C::M64),
                sync: if matches!(e.code, C::M62 | C::M63) {
                    Sync::WithMotion
                } else {
                    Sync::Immediate
                },
            }),
            C::M66 | C::M66Analog => act(ActionKind::WaitInput {
                input: number(e.value),
                analog: e.code == C::M66Analog,
                mode: WaitMode::from_l(e.p.map_or(0, |l| l.max(0.0) as u32))
                    .unwrap_or(WaitMode::Immediate),
                timeout_s: e.q.unwrap_or(0.0).max(0.0),
            }),
            C::M67 | C::M68 => act(ActionKind::Analog {
                output: number(e.value),
                value: e.q.unwrap_or(0.0),
                sync: if e.code == C::M67 {
                    Sync::WithMotion
                } else {
                    Sync::Immediate
                },
            }),
            C::M48 | C::M49 => {
                let on = Some(e.code == C::M48);
                act(ActionKind::Overrides {
                    feed: on,
                    spindle: on,
                })
            }
            C::M50 => act(ActionKind::Overrides {
                feed: Some(e.value.unwrap_or(1.0) != 0.0),
                spindle: None,
            }),
            C::M51 => act(ActionKind::Overrides {
                feed: None,
                spindle: Some(e.value.unwrap_or(1.0) != 0.0),
            }),
            C::User(_) => Some(Input::Stop),
            C::M52 | C::M53 | C::Msg | C::Debug | C::Print | C::Log => None,
        }
    }

    /// What must come before move `m`: the wait for the spindle's speed before the first
    /// feed move after a start or a change of speed.
    pub fn before_move(&mut self, m: &Move) -> Option<Input> {
        if m.rapid || !self.at_speed_due {
            return None;
        }
        self.at_speed_due = false;
        Some(Input::Action(Action {
            line: m.line,
            kind: ActionKind::WaitAtSpeed,
        }))
    }

    /// The inputs of one program item, in order: a move (after the wait for the spindle
    /// where one is due), or what an event means (if anything).
    pub fn item(&mut self, item: &Item) -> [Option<Input>; 2] {
        match item {
            Item::Move(m) => [self.before_move(m), Some(Input::Move(*m))],
            Item::Event(e) => [self.event(e), None],
        }
    }

    fn spindle_command(&self) -> ActionKind {
        ActionKind::Spindle {
            dir: self.dir,
            rpm: self.rpm,
        }
    }
}

/// Puts each action synchronised with the motion ([`Sync::WithMotion`]) after the planned
/// segments of the moves before it: the planner holds the end of a path back (a corner
/// blend may still change it), so such an action comes out of the planning step before
/// the segments of the move it follows. An action taken after `k` moves goes just before
/// the first segment of move `k` or later (after a corner blend into that move; on a
/// smoothed dense polyline, after the piece that covers the move's start), or before
/// anything else the program ends or stops with.
#[derive(Clone, Debug, Default)]
pub struct ActionOrder {
    held: VecDeque<(u64, Action)>,
    moves: u64,
}

impl ActionOrder {
    /// An order for a new program.
    pub fn new() -> Self {
        ActionOrder::default()
    }

    /// A move was given to the planner.
    pub fn moved(&mut self) {
        self.moves += 1;
    }

    /// Holds `input` if it is an action synchronised with the motion (it waits for the
    /// segments of the moves before it): `true` when it was taken, and is not to be
    /// planned.
    pub fn take_held(&mut self, input: &Input) -> bool {
        match input {
            Input::Action(a) if a.sync() == Sync::WithMotion => {
                self.held.push_back((self.moves, *a));
                true
            }
            _ => false,
        }
    }

    /// What goes out after the segments planned for `input` (not a held one): an
    /// immediate action itself; at an exact stop, a dwell or an action at rest, where the
    /// path ended at rest, every held action and then the dwell or action; after a move,
    /// nothing.
    pub fn after(&mut self, input: &Input, out: &mut impl Extend<Planned>) {
        match *input {
            Input::Move(_) => {}
            Input::Action(a) if a.sync() == Sync::Immediate => out.extend([Planned::Action(a)]),
            Input::Stop => out.extend(self.release()),
            Input::Dwell(seconds) => {
                out.extend(self.release());
                out.extend([Planned::Dwell(seconds)]);
            }
            Input::Action(a) => {
                out.extend(self.release());
                out.extend([Planned::Action(a)]);
            }
        }
    }

    /// The held actions due before `seg`, in order.
    pub fn before(&mut self, seg: &PlannedSegment) -> impl Iterator<Item = Planned> + '_ {
        let due = self
            .held
            .iter()
            .take_while(|(k, _)| seg.move_index >= *k)
            .count();
        self.held.drain(..due).map(|(_, a)| Planned::Action(a))
    }

    /// Every held action (the path has ended at rest, or the program ends).
    pub fn release(&mut self) -> impl Iterator<Item = Planned> + '_ {
        self.held.drain(..).map(|(_, a)| Planned::Action(a))
    }
}
