//! [`StreamCheck`]: the rules between the messages of a program stream.

use kerf_geom::Move;

use crate::{AXES, MoveMsg, Reject, Resolved};

/// Continuity tolerance between consecutive moves: coordinate `i` of a move's start may
/// differ from the previous end (or BEGIN's start position) by at most
/// `1e-9 · max(1, |a|, |b|)`, i.e. 1e-9 mm (or degree) absolute below 1 and 1e-9 relative
/// above. Both ends come from the same computation in the planner, so they normally agree
/// exactly; this only absorbs rounding.
pub const CONTINUITY_TOL: f64 = 1e-9;

/// Why [`StreamCheck::check`] refused a message. A refused message changes nothing: the
/// check still expects what it expected before.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum StreamError {
    /// The message itself is invalid.
    #[error("invalid message: {0}")]
    Rejected(Reject),
    /// An item or END arrived while no program was open.
    #[error("message of program {program_id} before its BEGIN")]
    NoBegin {
        /// The program named by the message.
        program_id: u64,
    },
    /// A BEGIN arrived while a program was still open.
    #[error("BEGIN of program {found} while program {open} is still open")]
    UnexpectedBegin {
        /// The open program.
        open: u64,
        /// The program of the new BEGIN.
        found: u64,
    },
    /// A BEGIN whose program id the daemon has seen before (ids must be new).
    #[error("BEGIN of program {program_id}: that id was used before; a program needs a new id")]
    RepeatedId {
        /// The program id.
        program_id: u64,
    },
    /// A BEGIN whose sequence number is not 0.
    #[error("BEGIN with sequence number {found}, expected 0")]
    BeginSeq {
        /// The sequence number found.
        found: u64,
    },
    /// A message of another program than the open one.
    #[error("message of program {found} inside program {expected}")]
    WrongProgram {
        /// The open program.
        expected: u64,
        /// The program of the message.
        found: u64,
    },
    /// Sequence numbers skipped: messages were lost.
    #[error("sequence gap: expected {expected}, got {found}")]
    Gap {
        /// The expected sequence number.
        expected: u64,
        /// The one found.
        found: u64,
    },
    /// A sequence number already seen: a duplicate or reordered message.
    #[error("duplicate or out-of-order sequence number {found}, expected {expected}")]
    Duplicate {
        /// The expected sequence number.
        expected: u64,
        /// The one found.
        found: u64,
    },
    /// More items than BEGIN announced.
    #[error("more items than the {total} announced by BEGIN")]
    TooManyItems {
        /// The total announced.
        total: u64,
    },
    /// END's count differs from the number of items received.
    #[error("END says {sent} items were sent but {received} were received")]
    EndCount {
        /// END's count.
        sent: u64,
        /// Items received.
        received: u64,
    },
    /// END arrived before the number of items announced by BEGIN.
    #[error("END after {received} items but BEGIN announced {total}")]
    EndBeforeTotal {
        /// BEGIN's total.
        total: u64,
        /// Items received.
        received: u64,
    },
    /// A move does not start where the previous one ended (or where BEGIN said).
    #[error(
        "move {seq} does not start where the previous one ended (axis {axis}: {found} instead of {expected})"
    )]
    Discontinuous {
        /// The move's sequence number.
        seq: u64,
        /// The axis, 0..6 for X, Y, Z, A, B, C.
        axis: usize,
        /// Where the previous move ended, mm or degrees.
        expected: f64,
        /// Where this one starts.
        found: f64,
    },
}

#[derive(Clone, Copy, Debug)]
struct Open {
    program_id: u64,
    next_seq: u64,
    total: u64,
    position: [f64; AXES],
}

/// Checks a stream of [`MoveMsg`]s against the protocol's stream rules:
///
/// - a program starts with BEGIN (sequence number 0) and no BEGIN comes while one is open;
/// - every later message of the program carries its program id and the next sequence
///   number (items 1, 2, ..., END after the last item);
/// - no more items than BEGIN announced (when it announced a total); END counts exactly the
///   items received (and equals BEGIN's total when one was announced);
/// - the first move starts at BEGIN's start position and every move starts where the
///   previous one ended ([`CONTINUITY_TOL`]); rotary axes A, B, C are checked on moves that
///   carry them, and keep their last value across moves that do not.
///
/// Travel limits are not checked here: the daemon owns them.
// A copy would be a second instance of its state, silently diverging from the first.
#[allow(missing_copy_implementations)]
#[derive(Clone, Debug, Default)]
pub struct StreamCheck {
    open: Option<Open>,
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= CONTINUITY_TOL * 1f64.max(a.abs()).max(b.abs())
}

impl StreamCheck {
    /// A check expecting a BEGIN.
    pub fn new() -> StreamCheck {
        StreamCheck::default()
    }

    /// Forgets the open program (after the daemon aborted it, or its client vanished):
    /// the next message must be a BEGIN.
    pub fn reset(&mut self) {
        self.open = None;
    }

    /// The open program, if any.
    pub fn program_id(&self) -> Option<u64> {
        self.open.map(|o| o.program_id)
    }

    /// Items of the open program accepted so far (0 when none is open).
    pub fn items_received(&self) -> u64 {
        self.open.map_or(0, |o| o.next_seq - 1)
    }

    /// Where the last accepted move of the open program ended (BEGIN's position before the
    /// first move): X, Y, Z mm, A, B, C degrees.
    pub fn position(&self) -> Option<[f64; AXES]> {
        self.open.map(|o| o.position)
    }

    /// Validates `msg` alone and in the stream; on success the stream advances and the
    /// decoded message is returned. On error nothing changes.
    pub fn check(&mut self, msg: &MoveMsg) -> Result<Resolved, StreamError> {
        let resolved = Resolved::try_from(msg).map_err(StreamError::Rejected)?;
        let Some(mut open) = self.open else {
            return match resolved {
                Resolved::Begin {
                    program_id,
                    start_mm_deg,
                    total_items,
                } => {
                    if msg.seq != 0 {
                        return Err(StreamError::BeginSeq { found: msg.seq });
                    }
                    self.open = Some(Open {
                        program_id,
                        next_seq: 1,
                        total: total_items,
                        position: start_mm_deg,
                    });
                    Ok(resolved)
                }
                _ => Err(StreamError::NoBegin {
                    program_id: msg.program_id,
                }),
            };
        };
        if let Resolved::Begin { program_id, .. } = resolved {
            return Err(StreamError::UnexpectedBegin {
                open: open.program_id,
                found: program_id,
            });
        }
        if msg.program_id != open.program_id {
            return Err(StreamError::WrongProgram {
                expected: open.program_id,
                found: msg.program_id,
            });
        }
        if msg.seq != open.next_seq {
            let (expected, found) = (open.next_seq, msg.seq);
            return Err(if found > expected {
                StreamError::Gap { expected, found }
            } else {
                StreamError::Duplicate { expected, found }
            });
        }
        let received = open.next_seq - 1;
        match &resolved {
            Resolved::End { items, .. } => {
                if *items != received {
                    return Err(StreamError::EndCount {
                        sent: *items,
                        received,
                    });
                }
                if open.total != 0 && open.total != received {
                    return Err(StreamError::EndBeforeTotal {
                        total: open.total,
                        received,
                    });
                }
                self.open = None;
                return Ok(resolved);
            }
            Resolved::Move(_) | Resolved::Event(_) => {
                if open.total != 0 && received >= open.total {
                    return Err(StreamError::TooManyItems { total: open.total });
                }
            }
            Resolved::Begin { .. } => {}
        }
        if let Resolved::Move(mv) = &resolved {
            open.position = continue_from(&open.position, msg.seq, mv)?;
        }
        open.next_seq += 1;
        self.open = Some(open);
        Ok(resolved)
    }
}

/// Checks that `mv` starts at `position` and returns where it ends.
fn continue_from(position: &[f64; AXES], seq: u64, mv: &Move) -> Result<[f64; AXES], StreamError> {
    let s = mv.path.start();
    let e = mv.path.end();
    let mut start = *position;
    let mut end = *position;
    start[..3].copy_from_slice(&[s.x, s.y, s.z]);
    end[..3].copy_from_slice(&[e.x, e.y, e.z]);
    if let Some((a0, a1)) = mv.abc_deg {
        start[3..].copy_from_slice(&a0);
        end[3..].copy_from_slice(&a1);
    }
    for axis in 0..AXES {
        if !close(position[axis], start[axis]) {
            return Err(StreamError::Discontinuous {
                seq,
                axis,
                expected: position[axis],
                found: start[axis],
            });
        }
    }
    Ok(end)
}
