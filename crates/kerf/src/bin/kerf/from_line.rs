//! `kerf run --from-line N`: the program is interpreted from its start without motion, so
//! that the modal state, offsets, tool, spindle and coolant are what they would be at line
//! N; then a safe approach brings the machine to where line N starts, the spindle and
//! coolant are restored, and the program runs on from there.
//!
//! The approach, all at line N (the status and errors name it):
//!
//! 1. a rapid straight up to the top of the Z travel (`axes.z.max_mm`), where X and Y
//!    stand;
//! 2. the tool the program has in the spindle at line N (its last M6 before it), if the
//!    machine has another: `T` and `M6`;
//! 3. a rapid in X and Y (and the rotary axes) to above the start of line N;
//! 4. the spindle (`S`, then `M3` or `M4`) and coolant (`M7`, `M8`) as the program left
//!    them before line N;
//! 5. a rapid down to [`CLEARANCE_MM`] above the start of line N (not lower than the
//!    start), then the last [`CLEARANCE_MM`] at the feed of line N's first move (a rapid
//!    if that move is one): the first feed move waits until the spindle is at speed.
//!
//! Outputs (M62–M68), pauses, dwells and waits on inputs before line N are not replayed.
//! A program whose path depends on the machine's inputs (it reads `#5399` after an M66) is
//! refused: which way it went before line N is not known.

use std::collections::VecDeque;

use kerf_config::Config;
use kerf_gcode::{CornerMode, Diagnostic, Event, EventCode, Item, Line, Move, Path, Vec3};
use kerf_geom::PerAxis;
use kerf_geom::machine::SpindleDir;
use kerf_pipeline::ProgramActions;

/// How far above the start of line N the approach's last rapid ends, mm: the rest is at
/// the feed of line N's first move.
pub const CLEARANCE_MM: f64 = 5.0;

/// The program's items from line N on, after the approach.
pub struct FromLine<I> {
    items: I,
    line: u32,
    config: Config,
    /// The tool in the machine's spindle now.
    tool_in_spindle: u32,
    /// Where the machine stands now.
    machine_at: PerAxis<f64>,
    /// Where the program stands: the end of its last move so far.
    program_at: PerAxis<f64>,
    actions: ProgramActions,
    /// Items of line N and later, before the approach has been sent.
    waiting: VecDeque<Item>,
    /// Items to hand out (the approach, then the waiting ones).
    ready: VecDeque<Item>,
    reached: bool,
    last_line: u32,
    done: bool,
}

impl<I: Iterator<Item = Result<Item, Diagnostic>>> FromLine<I> {
    /// Runs `items` from `line` on; the machine stands at `machine_at` with
    /// `tool_in_spindle` (the program starts from there too).
    pub fn new(
        items: I,
        line: u32,
        config: &Config,
        machine_at: PerAxis<f64>,
        tool_in_spindle: u32,
    ) -> Self {
        FromLine {
            items,
            line,
            config: config.clone(),
            tool_in_spindle,
            machine_at,
            program_at: machine_at,
            actions: ProgramActions::new(),
            waiting: VecDeque::new(),
            ready: VecDeque::new(),
            reached: false,
            last_line: 0,
            done: false,
        }
    }

    /// The approach to `start` (the end of the program's last move before line N),
    /// followed by the spindle and coolant; `first` is line N's first move.
    fn approach(&mut self, first: &Move) -> Result<(), Diagnostic> {
        let n = self.line;
        let top = self.config.axes.z.max_mm;
        let from = self.machine_at;
        let to = self.program_at;
        let at = |p: &PerAxis<f64>, z: f64| [p[0], p[1], z, p[3], p[4], p[5]];
        let mut moves = Vec::new();
        let mut here = from;
        let mut go = |target: PerAxis<f64>, feed: Option<f64>, moves: &mut Vec<Item>| {
            if target == here {
                return;
            }
            let rotary = (3..6).any(|i| target[i] != here[i]);
            moves.push(Item::Move(Move {
                line: n,
                rapid: feed.is_none(),
                path: Path::Line(Line {
                    start: Vec3::new(here[0], here[1], here[2]),
                    end: Vec3::new(target[0], target[1], target[2]),
                }),
                feed_mm_min: feed,
                abc_deg: rotary.then_some((
                    [here[3], here[4], here[5]],
                    [target[3], target[4], target[5]],
                )),
                corner: CornerMode::ExactStop,
            }));
            here = target;
        };
        let mut items = Vec::new();
        go(at(&from, top.max(from[2])), None, &mut items);
        if let Some(tool) = self.actions.loaded_tool()
            && tool != self.tool_in_spindle
        {
            items.push(event(n, EventCode::T, Some(f64::from(tool))));
            items.push(event(n, EventCode::M6, None));
        }
        let above = top.max(from[2]);
        go(at(&to, above), None, &mut items);
        let (dir, rpm) = self.actions.spindle();
        if dir != SpindleDir::Off {
            items.push(event(n, EventCode::S, Some(rpm)));
            let code = if dir == SpindleDir::Cw {
                EventCode::M3
            } else {
                EventCode::M4
            };
            items.push(event(n, code, None));
        }
        let (mist, flood) = self.actions.coolant();
        if mist {
            items.push(event(n, EventCode::M7, None));
        }
        if flood {
            items.push(event(n, EventCode::M8, None));
        }
        let clear = (to[2] + CLEARANCE_MM).min(above);
        go(at(&to, clear), None, &mut items);
        let feed = if first.rapid { None } else { first.feed_mm_min };
        go(to, feed, &mut items);
        for item in &items {
            if let Item::Move(m) = item {
                kerf_config::travel::check_move(m, &self.config.axes).map_err(|e| {
                    diagnostic(
                        n,
                        format!("the approach to line {n} would leave the travel: {e}"),
                    )
                })?;
            }
        }
        moves.extend(items);
        self.ready.extend(moves);
        Ok(())
    }
}

fn event(line: u32, code: EventCode, value: Option<f64>) -> Item {
    Item::Event(Event::new(line, code, value))
}

fn diagnostic(line: u32, message: String) -> Diagnostic {
    Diagnostic {
        line,
        col: 1,
        message,
        file: None,
        called_from: Vec::new(),
    }
}

impl<I: Iterator<Item = Result<Item, Diagnostic>>> Iterator for FromLine<I> {
    type Item = Result<Item, Diagnostic>;

    fn next(&mut self) -> Option<Self::Item> {
        loop {
            if let Some(item) = self.ready.pop_front() {
                return Some(Ok(item));
            }
            if self.done {
                return None;
            }
            if self.reached && self.waiting.is_empty() {
                return self.items.next();
            }
            let item = match self.items.next() {
                Some(Ok(item)) => item,
                Some(Err(e)) => return Some(Err(e)),
                None => {
                    self.done = true;
                    let n = self.line;
                    if !self.reached {
                        let last = self.last_line;
                        return Some(Err(diagnostic(
                            n,
                            format!(
                                "run from line {n}: the program has nothing to run from line {n} on (its last line with a move or event is {last})"
                            ),
                        )));
                    }
                    // Line N has events but no move: they run where the machine stands.
                    self.ready.extend(self.waiting.drain(..));
                    continue;
                }
            };
            let line = match &item {
                Item::Move(m) => m.line,
                Item::Event(e) => e.line,
            };
            self.last_line = self.last_line.max(line);
            if !self.reached && line < self.line {
                // Before line N: the state is kept, nothing moves.
                match &item {
                    Item::Move(m) => {
                        let e = m.path.end();
                        let abc = m.abc_deg.map_or(
                            [self.program_at[3], self.program_at[4], self.program_at[5]],
                            |(_, b)| b,
                        );
                        self.program_at = [e.x, e.y, e.z, abc[0], abc[1], abc[2]];
                    }
                    Item::Event(e) => {
                        let _ = self.actions.event(e);
                    }
                }
                continue;
            }
            self.reached = true;
            match item {
                Item::Move(m) if self.waiting.iter().all(|i| matches!(i, Item::Event(_))) => {
                    if let Err(e) = self.approach(&m) {
                        self.done = true;
                        return Some(Err(e));
                    }
                    self.ready.extend(self.waiting.drain(..));
                    self.ready.push_back(Item::Move(m));
                }
                other => self.waiting.push_back(other),
            }
        }
    }
}
