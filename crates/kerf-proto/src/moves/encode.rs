//! Building [`MoveMsg`]s: the BEGIN and END of a program, and one message per move or
//! event of the program.

use kerf_geom::{CornerMode, Event, Move, Path, Vec3};

use super::event_codes::event_code_to_u32;
use crate::{
    AXES, CORNER_BLEND_DEFAULT, CORNER_BLEND_TOLERANCE, CORNER_EXACT_STOP, FLAG_ABC, FLAG_EVENT_P,
    FLAG_EVENT_Q, FLAG_EVENT_VALUE, FLAG_NAIVE_CAM, FLAG_RAPID, KIND_ARC, KIND_BEGIN, KIND_END,
    KIND_EVENT, KIND_LINE, MoveMsg, PROTOCOL_VERSION,
};

fn arr(v: &Vec3) -> [f64; 3] {
    [v.x, v.y, v.z]
}

impl MoveMsg {
    fn header(kind: u32, program_id: u64, seq: u64) -> MoveMsg {
        MoveMsg {
            version: PROTOCOL_VERSION,
            kind,
            program_id,
            seq,
            ..MoveMsg::zeroed()
        }
    }

    /// The BEGIN message of program `program_id` (sequence number 0): the machine position
    /// the program starts from (X, Y, Z mm, A, B, C degrees) and the number of items that
    /// will follow (0 if unknown).
    pub fn begin(program_id: u64, start_mm_deg: [f64; AXES], total_items: u64) -> MoveMsg {
        let mut m = MoveMsg::header(KIND_BEGIN, program_id, 0);
        m.start_mm = [start_mm_deg[0], start_mm_deg[1], start_mm_deg[2]];
        m.abc_start_deg = [start_mm_deg[3], start_mm_deg[4], start_mm_deg[5]];
        m.count = total_items;
        m
    }

    /// The END message of program `program_id` after `items` items (sequence number
    /// `items + 1`).
    pub fn end(program_id: u64, items: u64) -> MoveMsg {
        let mut m = MoveMsg::header(KIND_END, program_id, items.saturating_add(1));
        m.count = items;
        m
    }

    /// Item `seq` (1-based) of program `program_id`: a line, arc or helix. Encodes the move
    /// as it is; whether it is valid is for the receiver's [`TryFrom`] to decide.
    pub fn from_move(program_id: u64, seq: u64, mv: &Move) -> MoveMsg {
        let mut m = MoveMsg::header(KIND_LINE, program_id, seq);
        m.line = mv.line;
        if mv.rapid {
            m.flags |= FLAG_RAPID;
        }
        m.feed_mm_min = mv.feed_mm_min.unwrap_or(0.0);
        match mv.corner {
            CornerMode::ExactStop => m.corner = CORNER_EXACT_STOP,
            CornerMode::Blend {
                tolerance_mm,
                naive_cam_mm,
            } => {
                match tolerance_mm {
                    None => m.corner = CORNER_BLEND_DEFAULT,
                    Some(t) => {
                        m.corner = CORNER_BLEND_TOLERANCE;
                        m.tolerance_mm = t;
                    }
                }
                if let Some(q) = naive_cam_mm {
                    m.flags |= FLAG_NAIVE_CAM;
                    m.naive_cam_mm = q;
                }
            }
        }
        match &mv.path {
            Path::Line(l) => {
                m.start_mm = arr(&l.start);
                m.end_mm = arr(&l.end);
            }
            Path::Arc(a) => {
                m.kind = KIND_ARC;
                m.start_mm = arr(&a.start);
                m.end_mm = arr(&a.end);
                m.center_mm = arr(&a.center);
                m.axis = arr(&a.axis);
                m.sweep_rad = a.sweep_rad;
            }
        }
        if let Some((s, e)) = mv.abc_deg {
            m.flags |= FLAG_ABC;
            m.abc_start_deg = s;
            m.abc_end_deg = e;
        }
        m
    }

    /// Item `seq` (1-based) of program `program_id`: a non-motion event.
    pub fn from_event(program_id: u64, seq: u64, ev: &Event) -> MoveMsg {
        let mut m = MoveMsg::header(KIND_EVENT, program_id, seq);
        m.line = ev.line;
        m.event_code = event_code_to_u32(ev.code);
        if let Some(v) = ev.value {
            m.flags |= FLAG_EVENT_VALUE;
            m.event_value = v;
        }
        if let Some(p) = ev.p {
            m.flags |= FLAG_EVENT_P;
            m.event_p = p;
        }
        if let Some(q) = ev.q {
            m.flags |= FLAG_EVENT_Q;
            m.event_q = q;
        }
        m
    }

    /// Item `seq` (1-based) of program `program_id`.
    pub fn from_item(program_id: u64, seq: u64, item: &kerf_geom::Item) -> MoveMsg {
        match item {
            kerf_geom::Item::Move(mv) => MoveMsg::from_move(program_id, seq, mv),
            kerf_geom::Item::Event(ev) => MoveMsg::from_event(program_id, seq, ev),
        }
    }
}
