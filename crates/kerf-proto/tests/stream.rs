//! StreamCheck: order, sequence numbers, counts and continuity.

use kerf_gcode::{Event, EventCode};
use kerf_geom::{CornerMode, Line, Move, Path, Vec3};
use kerf_proto::{MoveMsg, Reject, Resolved, StreamCheck, StreamError};

fn line_move(from: [f64; 3], to: [f64; 3]) -> Move {
    Move {
        line: 1,
        rapid: false,
        path: Path::Line(Line {
            start: Vec3::from(from),
            end: Vec3::from(to),
        }),
        feed_mm_min: Some(1000.0),
        abc_deg: None,
        corner: CornerMode::Blend {
            tolerance_mm: None,
            naive_cam_mm: None,
        },
    }
}

fn ev() -> Event {
    Event::new(2, EventCode::M8, None)
}

/// BEGIN at (1, 2, 3), then (1,2,3)→(4,2,3), M8, (4,2,3)→(4,5,3).
fn program(id: u64) -> Vec<MoveMsg> {
    vec![
        MoveMsg::begin(id, [1.0, 2.0, 3.0, 0.0, 0.0, 0.0], 3),
        MoveMsg::from_move(id, 1, &line_move([1.0, 2.0, 3.0], [4.0, 2.0, 3.0])),
        MoveMsg::from_event(id, 2, &ev()),
        MoveMsg::from_move(id, 3, &line_move([4.0, 2.0, 3.0], [4.0, 5.0, 3.0])),
        MoveMsg::end(id, 3),
    ]
}

/// Feeds `msgs` and returns the result of the last one (all earlier ones must pass).
fn run(msgs: &[MoveMsg]) -> Result<Resolved, StreamError> {
    let mut c = StreamCheck::new();
    let (last, rest) = msgs.split_last().expect("messages");
    for m in rest {
        c.check(m).unwrap_or_else(|e| panic!("{m:?}: {e}"));
    }
    c.check(last)
}

#[test]
fn a_valid_program_and_the_next_one() {
    let mut c = StreamCheck::new();
    for id in [7, 8] {
        for (i, m) in program(id).iter().enumerate() {
            c.check(m).unwrap_or_else(|e| panic!("{id}/{i}: {e}"));
            if i == 3 {
                assert_eq!(c.program_id(), Some(id));
                assert_eq!(c.items_received(), 3);
                assert_eq!(c.position(), Some([4.0, 5.0, 3.0, 0.0, 0.0, 0.0]));
            }
        }
        assert_eq!(c.program_id(), None);
    }
}

#[test]
fn missing_begin() {
    let p = program(7);
    assert_eq!(run(&p[1..2]), Err(StreamError::NoBegin { program_id: 7 }));
    assert_eq!(run(&p[4..5]), Err(StreamError::NoBegin { program_id: 7 }));
    // After a complete program, items of it again need a new BEGIN.
    let mut again = p.clone();
    again.push(p[1]);
    assert_eq!(run(&again), Err(StreamError::NoBegin { program_id: 7 }));
}

#[test]
fn begin_inside_a_program_and_begin_seq() {
    let p = program(7);
    let q = program(9);
    assert_eq!(
        run(&[p[0], p[1], q[0]]),
        Err(StreamError::UnexpectedBegin { open: 7, found: 9 })
    );
    let mut b = p[0];
    b.seq = 1;
    assert_eq!(run(&[b]), Err(StreamError::BeginSeq { found: 1 }));
    // reset() forgets the open program.
    let mut c = StreamCheck::new();
    c.check(&p[0]).expect("begin");
    c.check(&p[1]).expect("move");
    c.reset();
    assert_eq!(c.program_id(), None);
    c.check(&q[0]).expect("new begin after reset");
}

#[test]
fn gap_and_duplicate() {
    let p = program(7);
    assert_eq!(
        run(&[p[0], p[2]]),
        Err(StreamError::Gap {
            expected: 1,
            found: 2
        })
    );
    assert_eq!(
        run(&[p[0], p[1], p[1]]),
        Err(StreamError::Duplicate {
            expected: 2,
            found: 1
        })
    );
    // A refused message changes nothing: the right one is still accepted after it.
    let mut c = StreamCheck::new();
    c.check(&p[0]).expect("begin");
    assert!(c.check(&p[2]).is_err());
    for m in &p[1..] {
        c.check(m).expect("the rest of the program");
    }
}

#[test]
fn wrong_program() {
    let p = program(7);
    let q = program(9);
    assert_eq!(
        run(&[p[0], q[1]]),
        Err(StreamError::WrongProgram {
            expected: 7,
            found: 9
        })
    );
}

#[test]
fn end_counts() {
    let p = program(7);
    // END claims 2 items, 3 were received.
    let mut v = p.clone();
    v[4] = MoveMsg::end(7, 2);
    v[4].seq = 4;
    assert_eq!(
        run(&v),
        Err(StreamError::EndCount {
            sent: 2,
            received: 3
        })
    );
    // END after 2 items, saying 2, but BEGIN announced 3.
    let mut w = p[..3].to_vec();
    w.push(MoveMsg::end(7, 2));
    assert_eq!(
        run(&w),
        Err(StreamError::EndBeforeTotal {
            total: 3,
            received: 2
        })
    );
    // With the total unknown (0) the same stream is complete.
    w[0].count = 0;
    assert!(matches!(
        run(&w),
        Ok(Resolved::End {
            program_id: 7,
            items: 2
        })
    ));
    // A fourth item when 3 were announced.
    let mut x = p[..4].to_vec();
    x.push(MoveMsg::from_event(7, 4, &ev()));
    assert_eq!(run(&x), Err(StreamError::TooManyItems { total: 3 }));
}

#[test]
fn discontinuous_start() {
    let p = program(7);
    // The first move must start at BEGIN's position: here it starts at the origin.
    let first = MoveMsg::from_move(7, 1, &line_move([0.0, 2.0, 3.0], [4.0, 2.0, 3.0]));
    assert_eq!(
        run(&[p[0], first]),
        Err(StreamError::Discontinuous {
            seq: 1,
            axis: 0,
            expected: 1.0,
            found: 0.0
        })
    );
    // The second move starts 1 µm off the first one's end in Y.
    let second = MoveMsg::from_move(7, 3, &line_move([4.0, 2.000001, 3.0], [4.0, 5.0, 3.0]));
    assert_eq!(
        run(&[p[0], p[1], p[2], second]),
        Err(StreamError::Discontinuous {
            seq: 3,
            axis: 1,
            expected: 2.0,
            found: 2.000001
        })
    );
    // Rounding (1e-12 mm) is accepted.
    let near = MoveMsg::from_move(7, 3, &line_move([4.0, 2.0 + 1e-12, 3.0], [4.0, 5.0, 3.0]));
    assert!(run(&[p[0], p[1], p[2], near]).is_ok());
}

/// The continuity tolerance is relative beyond 1 mm (PROTOCOL.md, stream rule 5: 1e-9 ×
/// max(1, |a|, |b|)): at 1,000 mm a step of 5e-7 mm (half of 1e-9 × 1,000) is rounding
/// and accepted, one of 2e-6 mm is a jump and refused.
#[test]
fn continuity_is_relative_at_large_coordinates() {
    let at = 1000.0;
    let begin = MoveMsg::begin(9, [at, 0.0, 0.0, 0.0, 0.0, 0.0], 1);
    let from = |x: f64| MoveMsg::from_move(9, 1, &line_move([x, 0.0, 0.0], [at + 5.0, 0.0, 0.0]));
    assert!(run(&[begin, from(at + 5e-7)]).is_ok());
    assert!(matches!(
        run(&[begin, from(at + 2e-6)]),
        Err(StreamError::Discontinuous { axis: 0, .. })
    ));
}

#[test]
fn rotary_axes_continue_from_begin_and_across_moves_without_them() {
    let begin = MoveMsg::begin(3, [0.0, 0.0, 0.0, 90.0, 0.0, 0.0], 0);
    let plain = MoveMsg::from_move(3, 1, &line_move([0.0; 3], [1.0, 0.0, 0.0]));
    let mut rot = line_move([1.0, 0.0, 0.0], [2.0, 0.0, 0.0]);
    rot.abc_deg = Some(([90.0, 0.0, 0.0], [120.0, 0.0, 0.0]));
    assert!(run(&[begin, plain, MoveMsg::from_move(3, 2, &rot)]).is_ok());
    rot.abc_deg = Some(([0.0, 0.0, 0.0], [120.0, 0.0, 0.0]));
    assert_eq!(
        run(&[begin, plain, MoveMsg::from_move(3, 2, &rot)]),
        Err(StreamError::Discontinuous {
            seq: 2,
            axis: 3,
            expected: 90.0,
            found: 0.0
        })
    );
}

#[test]
fn invalid_messages_are_reported_as_such() {
    let mut m = program(7)[0];
    m.version = 9;
    assert_eq!(
        run(&[m]),
        Err(StreamError::Rejected(Reject::WrongVersion { found: 9 }))
    );
}
