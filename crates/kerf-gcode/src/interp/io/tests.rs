//! M62–M68 and `#5399`, with expected values from the LinuxCNC manual (M62–M66, M67, M68
//! and "G-code Order of Execution") and rs274's messages and canon calls for the same
//! lines (LinuxCNC 2.9, `tests/rs274/canon.sh`).

use std::sync::{Arc, Mutex};

use crate::{
    Diagnostic, Dialect, Event, EventCode, InputWait, Interpreter, Item, Settings, SimulatedInputs,
    Tool,
};

const D: Dialect = Dialect::LinuxCnc;

fn program(body: &str) -> String {
    format!("G21 G90 F100\n{body}\nM2\n")
}

fn run(src: &str, settings: Settings) -> Result<Vec<Item>, Diagnostic> {
    Interpreter::new(src.as_bytes(), D, settings).collect()
}

fn events(items: &[Item]) -> Vec<&Event> {
    items
        .iter()
        .filter_map(|i| match i {
            Item::Event(e) if e.code != EventCode::M2 => Some(e),
            _ => None,
        })
        .collect()
}

/// What a PRINT line wrote.
fn prints(items: &[Item]) -> Vec<String> {
    items
        .iter()
        .filter_map(|i| match i {
            Item::Event(e) if e.code == EventCode::Print => e.text.as_deref().map(str::to_string),
            _ => None,
        })
        .collect()
}

/// An event's code, line, value, P and Q.
type Fields = (EventCode, u32, Option<f64>, Option<f64>, Option<f64>);

fn fields(items: &[Item]) -> Vec<Fields> {
    events(items)
        .iter()
        .map(|e| (e.code, e.line, e.value, e.p, e.q))
        .collect()
}

fn ends_x(items: &[Item]) -> Vec<f64> {
    items
        .iter()
        .filter_map(|i| match i {
            Item::Move(m) => Some(m.path.end().x),
            Item::Event(_) => None,
        })
        .collect()
}

#[test]
fn outputs_carry_their_number_and_value() {
    // rs274: SET_MOTION_OUTPUT_BIT(1), CLEAR_MOTION_OUTPUT_BIT(2), SET_AUX_OUTPUT_BIT(3),
    // CLEAR_AUX_OUTPUT_BIT(0), SET_MOTION_OUTPUT_VALUE(1,3.5), SET_AUX_OUTPUT_VALUE(63,-2).
    let src = program("M62 P1\nM63 P2\nM64 P3\nM65 P0\nM67 E1 Q3.5\nM68 E63 Q-2\nM62 P[1/3*3]");
    let items = run(&src, Settings::default()).expect("accepted");
    let got = fields(&items);
    use EventCode::*;
    assert_eq!(
        got,
        [
            (M62, 2, Some(1.0), None, None),
            (M63, 3, Some(2.0), None, None),
            (M64, 4, Some(3.0), None, None),
            (M65, 5, Some(0.0), None, None),
            (M67, 6, Some(1.0), None, Some(3.5)),
            (M68, 7, Some(63.0), None, Some(-2.0)),
            // An expression a rounding error away from 1 is output 1.
            (M62, 8, Some(1.0), None, None),
        ]
    );
}

#[test]
fn m66_carries_input_mode_and_timeout() {
    let src = program("M66 P1 L3 Q2.5\nM66 E2\nM66 P0\nM66 P5 Q-1\nM66 E0 L0 Q3");
    let items = run(&src, Settings::default()).expect("accepted");
    let got = fields(&items);
    use EventCode::*;
    assert_eq!(
        got,
        [
            // Digital input 1, wait for high (L3), 2.5 s.
            (M66, 2, Some(1.0), Some(3.0), Some(2.5)),
            // Analog input 2, immediate (no L: L0), no timeout.
            (M66Analog, 3, Some(2.0), Some(0.0), None),
            (M66, 4, Some(0.0), Some(0.0), None),
            // rs274 waits no time for a Q at or below zero.
            (M66, 5, Some(5.0), Some(0.0), Some(0.0)),
            (M66Analog, 6, Some(0.0), Some(0.0), Some(3.0)),
        ]
    );
}

#[test]
fn io_codes_run_after_t_and_before_m6() {
    // The manual's order: S, T, HAL pin I/O (M62–M68), M6, spindle, coolant, dwell, motion;
    // rs274 prints SET_SPINDLE_SPEED, SELECT_TOOL, SET_AUX_OUTPUT_BIT(1), CHANGE_TOOL,
    // START_SPINDLE_CLOCKWISE, FLOOD_ON, STRAIGHT_FEED for this line.
    let settings = Settings {
        tools: vec![Tool {
            number: 1,
            ..Tool::default()
        }],
        ..Settings::default()
    };
    let items = run(&program("G1 X1 M64 P1 S100 T1 M3 M6 M8"), settings).expect("accepted");
    let order: Vec<String> = items
        .iter()
        .map(|i| match i {
            Item::Event(e) => e.code.as_str().to_string(),
            Item::Move(_) => "move".to_string(),
        })
        .collect();
    assert_eq!(order, ["S", "T", "M64", "M6", "M3", "M8", "move", "M2"]);
    // A dwell shares P with M62 (both use it) and comes after it.
    let items = run(&program("G4 P1 M62"), Settings::default()).expect("accepted");
    let got: Vec<(EventCode, Option<f64>)> =
        events(&items).iter().map(|e| (e.code, e.value)).collect();
    assert_eq!(
        got,
        [(EventCode::M62, Some(1.0)), (EventCode::G4, Some(1.0))]
    );
}

#[test]
fn word_errors_are_rs274s_at_the_word() {
    let out_range = "the output number is a whole number from 0 to 63";
    let in_range = "the input number is a whole number from 0 to 63";
    let q_unused = "Q word with no G5, G10, G64, G73, G76, G83, M19, M66, M67, M68 or user M code that uses it";
    let cases: Vec<(&str, u32, String)> = vec![
        ("M62", 1, "No valid P word with M62".into()),
        ("M63", 1, "No valid P word with M63".into()),
        ("M64", 1, "No valid P word with M64".into()),
        ("G0 X1 M65", 7, "No valid P word with M65".into()),
        ("M62 P-1", 5, format!("No valid P word with M62: {out_range}")),
        ("M63 P1.5", 5, format!("No valid P word with M63: {out_range}")),
        ("M64 P64", 5, format!("No valid P word with M64: {out_range}")),
        ("M62 P1 Q1", 8, q_unused.into()),
        (
            "M62 P1 L1",
            8,
            "L word with no G10, cutter compensation, canned cycle, digital/analog input, M98 or NURBS code".into(),
        ),
        (
            "M62 P1 E1",
            8,
            "E word with no G70, G76, M66, M67 or M68 to use it".into(),
        ),
        (
            "G1 X1 E2",
            7,
            "E word with no G70, G76, M66, M67 or M68 to use it".into(),
        ),
        (
            "M67 E1 Q2 P3",
            11,
            "P word with no G2 G3 G4 G10 G64 G5 G5.2 G76 G82 G86 G88 G89 or M50 M51 M52 M53 M62 M63 M64 M65 M66 M98 or user M code to use it".into(),
        ),
        ("M64 P2 M65", 8, "two M codes used from same modal group".into()),
        ("M62 P1 M66", 8, "two M codes used from same modal group".into()),
        (
            "M66",
            1,
            "Need to have either a valid P or a valid E word with M66".into(),
        ),
        (
            "M66 P1 E1",
            8,
            "Invalid to select both a digital and an analog input with M66".into(),
        ),
        (
            "M66 P1 L3",
            8,
            "Zero timeout with wait type != immediate return".into(),
        ),
        (
            "M66 P1 L3 Q0",
            11,
            "Zero timeout with wait type != immediate return".into(),
        ),
        (
            "M66 E1 L1 Q1",
            8,
            "Can't select analog input with wait type != immediate return".into(),
        ),
        (
            "M66 P-1",
            5,
            "Need to have either a valid P or a valid E word with M66".into(),
        ),
        (
            "M66 E-1",
            5,
            "Need to have either a valid P or a valid E word with M66".into(),
        ),
        ("M66 P1 L-1 Q1", 8, "Negative l word used".into()),
        ("M66 P1 L0.4 Q1", 8, "Non integer value for integer".into()),
        (
            "M66 P1 L5 Q1",
            8,
            "Invalid wait mode L5 with M66: L0 immediate, L1 rise, L2 fall, L3 high, L4 low"
                .into(),
        ),
        ("M66 P64", 5, "Digital input selected out of bounds".into()),
        ("M66 E64", 5, "Analog input selected out of bounds".into()),
        (
            "M66 P1.5",
            5,
            format!("Need to have either a valid P or a valid E word with M66: {in_range}"),
        ),
        ("M67", 1, "Invalid analog index with M67".into()),
        ("M67 Q1", 1, "Invalid analog index with M67".into()),
        ("M67 E-1 Q1", 5, "Invalid analog index with M67".into()),
        (
            "M68 E64 Q1",
            5,
            format!("Invalid analog index with M68: {out_range}"),
        ),
        (
            "M67 E1",
            1,
            "Q word missing with M67: the value to set".into(),
        ),
        (
            "M68 E1",
            1,
            "Q word missing with M68: the value to set".into(),
        ),
    ];
    for (line, col, message) in cases {
        let e = run(&program(line), Settings::default())
            .err()
            .unwrap_or_else(|| panic!("{line}: accepted"));
        assert_eq!(
            (e.line, e.col, e.message.as_str()),
            (2, col, message.as_str()),
            "{line}"
        );
    }
}

#[test]
fn io_codes_are_refused_under_cutter_compensation() {
    let settings = Settings {
        tools: vec![Tool {
            number: 1,
            radius_mm: 1.0,
            ..Tool::default()
        }],
        ..Settings::default()
    };
    for (line, message) in [
        (
            "M62 P1",
            "Cannot set motion output with cutter radius compensation on",
        ),
        // rs274 checks the compensation before the P word.
        (
            "M62",
            "Cannot set motion output with cutter radius compensation on",
        ),
        (
            "M63 P1",
            "Cannot set motion digital output with cutter radius compensation on",
        ),
        (
            "M64 P1",
            "Cannot set auxiliary digital output with cutter radius compensation on",
        ),
        (
            "M65 P1",
            "Cannot set auxiliary digital output with cutter radius compensation on",
        ),
        (
            "M66 P1",
            "Cannot wait for digital input with cutter radius compensation on",
        ),
        (
            "M66 E1",
            "Cannot wait for analog input with cutter radius compensation on",
        ),
        // ... but after the M66 words.
        (
            "M66 P1 L3",
            "Zero timeout with wait type != immediate return",
        ),
        (
            "M67 E1 Q1",
            "Cannot set motion analog output with cutter radius compensation on",
        ),
        (
            "M68 E1 Q1",
            "Cannot set auxiliary analog output with cutter radius compensation on",
        ),
    ] {
        let src = program(&format!("T1 M6\nG41\nG1 X5 Y5\n{line}\nG1 X10"));
        let e = run(&src, settings.clone())
            .err()
            .unwrap_or_else(|| panic!("{line}: accepted"));
        assert_eq!((e.line, e.message.as_str()), (5, message), "{line}");
    }
    // G41 in the same block takes effect after the I/O codes (rs274 runs convert_m first).
    assert!(run(&program("T1 M6\nG41 M62 P1\nG40"), settings).is_ok());
}

/// A machine that answers from a list and records every wait it was asked for.
struct Machine {
    answers: Vec<Result<f64, String>>,
    asked: Arc<Mutex<Vec<Event>>>,
}

impl InputWait for Machine {
    fn wait(&mut self, event: &Event) -> Result<f64, String> {
        self.asked.lock().expect("lock").push(event.clone());
        if self.answers.is_empty() {
            return Err("no answer".into());
        }
        self.answers.remove(0)
    }
}

fn with_machine(
    src: &str,
    answers: Vec<Result<f64, String>>,
) -> (Interpreter<&[u8]>, Arc<Mutex<Vec<Event>>>) {
    let asked = Arc::new(Mutex::new(Vec::new()));
    let machine = Machine {
        answers,
        asked: Arc::clone(&asked),
    };
    let it =
        Interpreter::new(src.as_bytes(), D, Settings::default()).with_input_wait(Box::new(machine));
    (it, asked)
}

const BRANCH: &str = "G21 G90 F100
M66 P3 L3 Q5
G1 X1
o100 if [#5399 EQ 1]
G1 X10
o100 else
G1 X20
o100 endif
M2
";

#[test]
fn the_branch_on_5399_takes_the_machines_answer_read_once_where_it_is_read() {
    for (answer, x) in [(1.0, 10.0), (-1.0, 20.0)] {
        let (mut it, asked) = with_machine(BRANCH, vec![Ok(answer)]);
        // The M66 event and the move after it come out before the machine is asked.
        let mut seen = Vec::new();
        for _ in 0..2 {
            seen.push(it.next().expect("item").expect("accepted"));
            assert!(asked.lock().expect("lock").is_empty());
        }
        assert!(matches!(&seen[0], Item::Event(e) if e.code == EventCode::M66));
        assert_eq!(ends_x(&seen), [1.0]);
        // Reading the `if` line asks once, with the M66 as it was yielded.
        let rest: Vec<Item> = it.collect::<Result<_, _>>().expect("accepted");
        let asked = asked.lock().expect("lock");
        assert_eq!(asked.len(), 1);
        let Item::Event(m66) = &seen[0] else {
            unreachable!()
        };
        assert_eq!(&asked[0], m66);
        assert_eq!(
            (asked[0].line, asked[0].value, asked[0].p, asked[0].q),
            (2, Some(3.0), Some(3.0), Some(5.0))
        );
        assert_eq!(ends_x(&rest), [x], "answer {answer}");
    }
}

#[test]
fn no_read_no_wait_and_each_m66_is_asked_once() {
    // An M66 whose result nobody reads holds nothing up.
    let src = program("M66 P1 L3 Q1\nG1 X5\nM66 E0");
    let (it, asked) = with_machine(&src, vec![]);
    let items: Vec<Item> = it.collect::<Result<_, _>>().expect("accepted");
    assert_eq!(ends_x(&items), [5.0]);
    assert!(asked.lock().expect("lock").is_empty());
    // Two reads after one M66 ask once; the next M66 asks again; EXISTS does not ask.
    let src = program(
        "M66 P1\n#1=#5399\n#2=[#5399+1]\no1 if [EXISTS[#5399]]\nM66 E4\no1 endif\n(PRINT,#1 #2 #5399)",
    );
    let (it, asked) = with_machine(&src, vec![Ok(1.0), Ok(2.5)]);
    let items: Vec<Item> = it.collect::<Result<_, _>>().expect("accepted");
    assert_eq!(prints(&items), ["1.000000 2.000000 2.500000"]);
    let asked: Vec<(EventCode, Option<f64>)> = asked
        .lock()
        .expect("lock")
        .iter()
        .map(|e| (e.code, e.value))
        .collect();
    assert_eq!(
        asked,
        [
            (EventCode::M66, Some(1.0)),
            (EventCode::M66Analog, Some(4.0))
        ]
    );
}

#[test]
fn an_assignment_to_5399_replaces_the_wait_and_a_loop_asks_every_time() {
    let src = program("M66 P1\n#5399=7\n(PRINT,#5399)");
    let (it, asked) = with_machine(&src, vec![]);
    let items: Vec<Item> = it.collect::<Result<_, _>>().expect("accepted");
    assert_eq!(prints(&items), ["7.000000"]);
    assert!(asked.lock().expect("lock").is_empty());
    // A part counter: wait for the door closed (input 2 high) before each of three parts.
    let src = program(
        "#1=0\no10 while [#1 LT 3]\nM66 P2 L3 Q10\no11 if [#5399 LT 0]\n(MSG,door open)\nM0\no11 endif\nG1 X[#1+1]\n#1=[#1+1]\no10 endwhile",
    );
    let (it, asked) = with_machine(&src, vec![Ok(1.0), Ok(-1.0), Ok(1.0)]);
    let items: Vec<Item> = it.collect::<Result<_, _>>().expect("accepted");
    assert_eq!(asked.lock().expect("lock").len(), 3);
    assert_eq!(ends_x(&items), [1.0, 2.0, 3.0]);
    let pauses = events(&items)
        .iter()
        .filter(|e| e.code == EventCode::M0)
        .count();
    assert_eq!(pauses, 1, "only the second part found the door open");
}

#[test]
fn a_failed_wait_stops_the_program_at_the_read() {
    let (it, _) = with_machine(BRANCH, vec![Err("the daemon went away".into())]);
    let out: Vec<Result<Item, Diagnostic>> = it.collect();
    let e = out
        .last()
        .expect("items")
        .as_ref()
        .expect_err("an error last");
    // Line 4 reads #5399 at column 10 (`o100 if [#5399 EQ 1]`).
    assert_eq!(
        e.to_string(),
        "4:10: error: #5399 after the M66 of line 2: the daemon went away"
    );
    assert_eq!(out.len(), 3, "the M66 and the move before the read");
    // Read in a PRINT text, which shows `######` for what it cannot read: still an error.
    let src = program("M66 P1\n(PRINT,#5399)");
    let (it, _) = with_machine(&src, vec![]);
    let e = it.last().expect("items").expect_err("an error last");
    assert_eq!(e.line, 3);
    assert!(e.message.contains("no answer"), "{e}");
}

#[test]
fn offline_the_simulated_inputs_answer() {
    let src = program(
        "M66 P0 L3 Q1\n#1=#5399\nM66 P0 L4 Q1\n#2=#5399\nM66 P1\n#3=#5399\nM66 P1 L1 Q1\n#4=#5399\nM66 E2\n#5=#5399\n(PRINT,#1 #2 #3 #4 #5)",
    );
    // Everything off: high times out, low is met at once (0), L0 reads 0, no edge comes.
    let items = run(&src, Settings::default()).expect("accepted");
    assert_eq!(
        prints(&items),
        ["-1.000000 0.000000 0.000000 -1.000000 0.000000"]
    );
    let mut sim = SimulatedInputs {
        digital: 0b11,
        ..SimulatedInputs::default()
    };
    sim.analog[2] = 4.25;
    let settings = Settings {
        simulated_inputs: sim,
        ..Settings::default()
    };
    let items = run(&src, settings).expect("accepted");
    assert_eq!(
        prints(&items),
        ["1.000000 -1.000000 1.000000 -1.000000 4.250000"]
    );
}

#[test]
fn other_dialects_refuse_machine_io_clearly() {
    // Their manuals' I/O (Sinumerik system variables, the machine builder's M functions of
    // the others) is not part of Kerf's dialects: a refusal naming it, never a silent skip.
    let cases: &[(Dialect, &str, &str)] = &[
        (
            Dialect::Rockwell,
            "G21\nM62 P1\nM30\n",
            "2:1: error: unknown M code M62",
        ),
        (
            Dialect::Fagor,
            "G71\nM66\nM30\n",
            "2:1: error: unknown M code M66",
        ),
        (
            Dialect::Heidenhain,
            "%P G71 *\nN10 M67 *\n%P G71 *\n",
            "2:5: error: unknown M code M67",
        ),
        (
            Dialect::Sinumerik,
            "G71\nN10 $A_OUT[1]=1\nM30\n",
            "2:5: error: system variable $A_OUT is not supported yet",
        ),
        (
            Dialect::Sinumerik,
            "G71\n$a_in[2]\nM30\n",
            "2:1: error: system variable $A_IN is not supported yet",
        ),
        (
            Dialect::Sinumerik,
            "G71\nG1 X1 M62\nM30\n",
            "2:7: error: unknown M code M62",
        ),
        // E is LinuxCNC's I/O word only.
        (
            Dialect::Sinumerik,
            "G71\nE1\nM30\n",
            "2:1: error: unknown word E",
        ),
    ];
    for (d, src, want) in cases {
        let e = Interpreter::new(src.as_bytes(), *d, Settings::default())
            .find_map(Result::err)
            .unwrap_or_else(|| panic!("{d:?} accepts {src:?}"));
        assert_eq!(e.to_string(), *want, "{d:?} {src:?}");
    }
}
