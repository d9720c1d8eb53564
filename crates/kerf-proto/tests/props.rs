//! Arbitrary bytes reinterpreted as a `MoveMsg` never make the decoder panic: it either
//! decodes them (and then re-encoding gives the same bytes: nothing is lost or invented,
//! every number it uses is finite, and an arc is a curve the motion can follow) or names a
//! reason.

use proptest::prelude::*;

use kerf_gcode::{Dialect, Interpreter, Item, Settings};
use kerf_geom::{Arc, CornerMode, Curve, Move, Path, Vec3};
use kerf_proto::{
    CORNER_EXACT_STOP, FLAG_NAIVE_CAM, KIND_ARC, KIND_LINE, MoveMsg, PROTOCOL_VERSION, Resolved,
};

const SIZE: usize = size_of::<MoveMsg>();

fn from_bytes(b: &[u8; SIZE]) -> MoveMsg {
    // SAFETY: MoveMsg is #[repr(C)] and made of u32, u64 and f64 only (no padding, checked
    // by the layout test), so every bit pattern is a valid value; read_unaligned copes with
    // the byte array's alignment.
    unsafe { std::ptr::read_unaligned(b.as_ptr().cast::<MoveMsg>()) }
}

fn to_bytes(m: &MoveMsg) -> [u8; SIZE] {
    // SAFETY: as above; a MoveMsg has no padding, so all SIZE bytes are initialised.
    unsafe { std::ptr::read_unaligned(std::ptr::from_ref(m).cast::<[u8; SIZE]>()) }
}

/// Valid messages to start from: every item of a small program with lines, arcs, a helix,
/// rotary axes and events, plus BEGIN and END.
fn seeds() -> Vec<MoveMsg> {
    let program = "G21 G90 F600\nG64 P0.02\nG0 X5 Y0\nG1 X10 A30\nG3 X0 Y10 I-10 J0 Z-1\nG2 X10 Y0 R10\nG4 P1\nM3 S1000\nT2 M6\nM30\n";
    // LinuxCNC refuses a tool missing from the tool table.
    let settings = Settings {
        tools: vec![kerf_gcode::Tool {
            number: 2,
            ..kerf_gcode::Tool::default()
        }],
        ..Settings::default()
    };
    let items: Vec<Item> = Interpreter::new(program.as_bytes(), Dialect::LinuxCnc, settings)
        .collect::<Result<_, _>>()
        .expect("valid program");
    let mut v = vec![MoveMsg::begin(1, [0.0; 6], items.len() as u64)];
    v.extend(
        items
            .iter()
            .enumerate()
            .map(|(i, it)| MoveMsg::from_item(1, i as u64 + 1, it)),
    );
    v.push(MoveMsg::end(1, items.len() as u64));
    // Blending moves with LinuxCNC's naive-CAM tolerance (G64 P… Q…), which the
    // interpreter does not send today.
    let naive: Vec<MoveMsg> = v
        .iter()
        .filter(|m| (m.kind == KIND_LINE || m.kind == KIND_ARC) && m.corner != CORNER_EXACT_STOP)
        .map(|m| {
            let mut n = *m;
            n.flags |= FLAG_NAIVE_CAM;
            n.naive_cam_mm = 0.005;
            n
        })
        .collect();
    assert!(!naive.is_empty());
    v.extend(naive);
    // A BEGIN away from the origin, with rotary positions.
    v.push(MoveMsg::begin(2, [1.5, -2.0, 30.0, 45.0, 0.0, -90.0], 7));
    // Arcs at the extremes of radius and sweep: 10 mm of radius 1e8 and 1e12 mm from near
    // the origin, a 50-turn helix, an arc of radius 1e-3 mm.
    for (r, sweep, rise) in [
        (1e8, 1e-7, 0.0),
        (1e12, -1e-11, 0.0),
        (2.0, 100.0 * std::f64::consts::PI, -5.0),
        (1e-3, 2.0, 0.0),
    ] {
        v.push(arc_item(Vec3::new(3.0, -4.0, 5.0), r, sweep, rise));
    }
    v
}

/// A consistent arc item about +Z from `start`, its centre `r` along +Y of it.
fn arc_item(start: Vec3, r: f64, sweep: f64, rise: f64) -> MoveMsg {
    let half = (0.5 * sweep).sin();
    // e1 = -Y (centre at +Y), e2 = Z × e1 = +X.
    let end = start + Vec3::new(r * sweep.sin(), 2.0 * r * half * half, rise);
    let mv = Move {
        line: 30,
        rapid: false,
        path: Path::Arc(Arc {
            start,
            end,
            center: start + Vec3::new(0.0, r, 0.0),
            axis: Vec3::z(),
            sweep_rad: sweep,
        }),
        feed_mm_min: Some(1000.0),
        abc_deg: None,
        corner: CornerMode::Blend {
            tolerance_mm: None,
            naive_cam_mm: None,
        },
    };
    MoveMsg::from_move(1, 40, &mv)
}

/// Every `f64` of the message.
fn floats(m: &MoveMsg) -> Vec<(&'static str, f64)> {
    let mut v = vec![
        ("feed_mm_min", m.feed_mm_min),
        ("tolerance_mm", m.tolerance_mm),
        ("sweep_rad", m.sweep_rad),
        ("event_value", m.event_value),
        ("naive_cam_mm", m.naive_cam_mm),
    ];
    for (name, a) in [
        ("start_mm", m.start_mm),
        ("end_mm", m.end_mm),
        ("center_mm", m.center_mm),
        ("axis", m.axis),
        ("abc_start_deg", m.abc_start_deg),
        ("abc_end_deg", m.abc_end_deg),
    ] {
        v.extend(a.iter().map(|&x| (name, x)));
    }
    v
}

fn check(m: &MoveMsg) {
    match Resolved::try_from(m) {
        Err(reason) => assert!(!reason.to_string().is_empty()),
        Ok(r) => {
            // Every number of an accepted message is finite, used or not (unused ones are
            // zero).
            for (name, x) in floats(m) {
                assert!(x.is_finite(), "{name} = {x} accepted in {m:?}");
            }
            // An accepted move within 1e15 mm of the origin is a curve of finite length
            // (positive for an arc) whose points are finite, ending exactly at its end. (Beyond, the length
            // of a line or a helix's rise can overflow f64: the daemon's travel check
            // refuses such moves before any motion.)
            let machine_sized = [m.start_mm, m.end_mm, m.center_mm]
                .iter()
                .flatten()
                .all(|x| x.abs() <= 1e15);
            if let (Resolved::Move(Move { path, .. }), true) = (&r, machine_sized) {
                let c = Curve::from_path(path);
                let len = c.length();
                let positive = len > 0.0 || matches!(path, Path::Line(_));
                assert!(
                    len.is_finite() && len >= 0.0 && positive,
                    "length {len} of {m:?}"
                );
                for k in 0..=8 {
                    let p = c.point_at(len * f64::from(k) / 8.0);
                    assert!(p.iter().all(|x| x.is_finite()), "{p:?} on {m:?}");
                }
                assert_eq!(c.point_at(len), path.end());
            }
            let again = match r {
                Resolved::Begin {
                    program_id,
                    start_mm_deg,
                    total_items,
                } => {
                    let mut b = MoveMsg::begin(program_id, start_mm_deg, total_items);
                    b.seq = m.seq; // the stream check, not the decoder, checks BEGIN's seq
                    b
                }
                Resolved::End { program_id, items } => {
                    let mut e = MoveMsg::end(program_id, items);
                    e.seq = m.seq; // the stream check, not the decoder, checks END's seq
                    e
                }
                Resolved::Move(mv) => MoveMsg::from_move(m.program_id, m.seq, &mv),
                Resolved::Event(ref ev) => MoveMsg::from_event(m.program_id, m.seq, ev),
            };
            assert_eq!(to_bytes(&again), to_bytes(m), "{m:?} decoded as {r:?}");
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(4000))]

    #[test]
    fn random_bytes(bytes in prop::collection::vec(any::<u8>(), SIZE), valid_version in any::<bool>(), kind in 0u32..7) {
        let mut b = [0u8; SIZE];
        b.copy_from_slice(&bytes);
        let mut m = from_bytes(&b);
        if valid_version {
            // Get past the first checks so that the later ones see random data too.
            m.version = PROTOCOL_VERSION;
            m.kind = kind;
        }
        check(&m);
    }

    #[test]
    fn arc_numbers_of_any_magnitude(
        seed in 0usize..64,
        field in 0usize..13,
        bits in any::<u64>(),
        scale in -12i32..14,
        mantissa in -1.0f64..1.0,
        raw in any::<bool>(),
    ) {
        // One number of an arc replaced by a random bit pattern (NaN, infinities,
        // subnormals and huge values included) or by a value of any decimal magnitude.
        let arcs: Vec<MoveMsg> = seeds().into_iter().filter(|m| m.kind == KIND_ARC).collect();
        let mut m = arcs[seed % arcs.len()];
        let x = if raw { f64::from_bits(bits) } else { mantissa * 10f64.powi(scale) };
        match field {
            0..=2 => m.start_mm[field] = x,
            3..=5 => m.end_mm[field - 3] = x,
            6..=8 => m.center_mm[field - 6] = x,
            9..=11 => m.axis[field - 9] = x,
            _ => m.sweep_rad = x,
        }
        check(&m);
    }

    #[test]
    fn mutated_valid_messages(
        seed in 0usize..64,
        edits in prop::collection::vec((0usize..SIZE, any::<u8>()), 1..6),
    ) {
        let seeds = seeds();
        let mut b = to_bytes(&seeds[seed % seeds.len()]);
        for (at, byte) in edits {
            b[at] = byte;
        }
        check(&from_bytes(&b));
    }

    #[test]
    fn special_floats_in_any_f64_slot(seed in 0usize..64, slot in 0usize..(SIZE / 8), which in 0usize..8) {
        let special = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, -0.0, f64::MIN_POSITIVE, 5e-324, f64::MAX, -1.0];
        let seeds = seeds();
        let mut b = to_bytes(&seeds[seed % seeds.len()]);
        b[slot * 8..slot * 8 + 8].copy_from_slice(&special[which].to_ne_bytes());
        check(&from_bytes(&b));
    }
}

#[test]
fn seeds_are_valid() {
    for m in seeds() {
        assert!(Resolved::try_from(&m).is_ok(), "{m:?}");
        check(&m);
    }
}

/// The arc this property once found: a 1 µm-scale circle swept 1.34e156 rad (2e155
/// turns). Its sweep times its length overflows f64; the curve still evaluates to finite
/// points at every arc length, ending exactly at its end.
#[test]
fn an_arc_of_absurdly_many_turns_evaluates_to_finite_points() {
    let m = MoveMsg::from_move(
        1,
        1,
        &Move {
            line: 30,
            rapid: false,
            path: Path::Arc(Arc {
                start: Vec3::new(3.0, -4.0, 5.0),
                end: Vec3::new(3.000909297426826, -3.9985838531634528, 5.0),
                center: Vec3::new(3.0, -3.999, 5.0),
                axis: Vec3::z(),
                sweep_rad: 1.343155541070819e156,
            }),
            feed_mm_min: Some(1000.0),
            abc_deg: None,
            corner: CornerMode::ExactStop,
        },
    );
    assert!(Resolved::try_from(&m).is_ok(), "the arc is consistent");
    check(&m);
}
