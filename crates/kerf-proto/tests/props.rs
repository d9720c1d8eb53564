//! Arbitrary bytes reinterpreted as a `MoveMsg` never make the decoder panic: it either
//! decodes them (and then re-encoding gives the same bytes: nothing is lost or invented)
//! or names a reason.

use proptest::prelude::*;

use kerf_gcode::{Dialect, Interpreter, Item, Settings};
use kerf_proto::{MoveMsg, Resolved};

const SIZE: usize = size_of::<MoveMsg>();

fn from_bytes(b: &[u8; SIZE]) -> MoveMsg {
    // SAFETY: MoveMsg is #[repr(C)] and made of u32, u64 and f64 only (no padding, checked
    // by the layout test), so every bit pattern is a valid value; read_unaligned copes with
    // the byte array's alignment.
    unsafe { std::ptr::read_unaligned(b.as_ptr().cast::<MoveMsg>()) }
}

fn to_bytes(m: &MoveMsg) -> [u8; SIZE] {
    // SAFETY: as above; a MoveMsg has no padding, so all SIZE bytes are initialised.
    unsafe { std::ptr::read_unaligned((m as *const MoveMsg).cast::<[u8; SIZE]>()) }
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
    v
}

fn check(m: &MoveMsg) {
    match Resolved::try_from(m) {
        Err(reason) => assert!(!reason.to_string().is_empty()),
        Ok(r) => {
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
    fn random_bytes(bytes in prop::collection::vec(any::<u8>(), SIZE), version_one in any::<bool>(), kind in 0u32..7) {
        let mut b = [0u8; SIZE];
        b.copy_from_slice(&bytes);
        let mut m = from_bytes(&b);
        if version_one {
            // Get past the first checks so that the later ones see random data too.
            m.version = 1;
            m.kind = kind;
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
