//! MDI input ([`Settings::mdi`]): lines that arrive one at a time, without LinuxCNC's
//! end-of-file rule, each run to its end before the next; an error ends its line only.

use std::cell::RefCell;
use std::collections::VecDeque;
use std::io::{BufReader, Read};
use std::rc::Rc;

use crate::{Dialect, Interpreter, Item, Move, Settings, Tool};

/// Lines the test types, read by the interpreter; empty reads as "nothing more yet".
#[derive(Clone, Default)]
struct Typed(Rc<RefCell<VecDeque<u8>>>);

impl Typed {
    fn push(&self, line: &str) {
        let mut q = self.0.borrow_mut();
        q.extend(line.as_bytes());
        q.push_back(b'\n');
    }
}

impl Read for Typed {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let mut q = self.0.borrow_mut();
        let n = buf.len().min(q.len());
        for (slot, b) in buf.iter_mut().zip(q.drain(..n)) {
            *slot = b;
        }
        Ok(n)
    }
}

fn session(dialect: Dialect, settings: Settings) -> (Typed, Interpreter<BufReader<Typed>>) {
    let typed = Typed::default();
    let settings = Settings {
        mdi: true,
        ..settings
    };
    let interp = Interpreter::new(BufReader::new(typed.clone()), dialect, settings);
    (typed, interp)
}

/// Types `line` and takes everything it produces (the interpreter pauses after it).
fn line(
    typed: &Typed,
    interp: &mut Interpreter<BufReader<Typed>>,
    text: &str,
) -> Result<Vec<Item>, crate::Diagnostic> {
    typed.push(text);
    interp.by_ref().collect()
}

fn ends(items: &[Item]) -> Vec<[f64; 3]> {
    items
        .iter()
        .filter_map(|i| match i {
            Item::Move(Move { path, .. }) => {
                let e = path.end();
                Some([e[0], e[1], e[2]])
            }
            Item::Event(_) => None,
        })
        .collect()
}

#[test]
fn a_line_needs_no_program_end_and_the_modal_state_carries_over_in_every_dialect() {
    for dialect in Dialect::ALL {
        let (typed, mut interp) = session(dialect, Settings::default());
        let first = line(&typed, &mut interp, "G91 G0 X1").expect("G91 G0 X1");
        assert_eq!(ends(&first), [[1.0, 0.0, 0.0]], "{dialect:?}");
        // G91 and G0 are still in force: X1 again is 1 mm further.
        let second = line(&typed, &mut interp, "X1").expect("X1");
        assert_eq!(ends(&second), [[2.0, 0.0, 0.0]], "{dialect:?}");
        assert!(!interp.ended(), "{dialect:?}");
    }
}

#[test]
fn an_error_ends_its_line_only_and_yields_nothing_of_it() {
    let (typed, mut interp) = session(Dialect::LinuxCnc, Settings::default());
    let e = line(&typed, &mut interp, "G0 X5 G2").expect_err("two motions");
    assert_eq!(e.line, 1);
    let after = line(&typed, &mut interp, "G0 X3").expect("the next line runs");
    assert_eq!(ends(&after), [[3.0, 0.0, 0.0]]);
    assert_eq!(
        line(&typed, &mut interp, "G0 Q")
            .expect_err("bad word")
            .line,
        3
    );
    // An unfinished loop is abandoned with the error inside it.
    line(&typed, &mut interp, "o1 while [1]").expect("opens a loop");
    assert!(interp.unfinished_structure().is_some());
    line(&typed, &mut interp, "G0 X[1/0]").expect("collected, not run");
    assert!(line(&typed, &mut interp, "o1 endwhile").is_err());
    assert!(interp.unfinished_structure().is_none());
    let after = line(&typed, &mut interp, "G0 Y2").expect("runs");
    assert_eq!(ends(&after), [[3.0, 2.0, 0.0]]);
}

#[test]
fn the_position_follows_the_machine_and_offsets_apply() {
    let (typed, mut interp) = session(Dialect::LinuxCnc, Settings::default());
    line(&typed, &mut interp, "G10 L2 P1 X100 Y50").expect("G54 offset");
    interp.set_position([110.0, 60.0, 5.0, 0.0, 0.0, 0.0]);
    let items = line(&typed, &mut interp, "G91 G1 X1 F100").expect("relative move");
    let Item::Move(m) = &items[0] else {
        panic!("{items:?}")
    };
    let s = m.path.start();
    assert_eq!([s[0], s[1], s[2]], [110.0, 60.0, 5.0]);
    assert_eq!(ends(&items), [[111.0, 60.0, 5.0]]);
    let items = line(&typed, &mut interp, "G90 G0 X0 Y0").expect("to the G54 zero");
    assert_eq!(ends(&items), [[100.0, 50.0, 5.0]]);
    // G10 L10 changes the tool table the session reports.
    let (typed, mut interp) = session(
        Dialect::LinuxCnc,
        Settings {
            tools: vec![Tool {
                number: 3,
                ..Tool::default()
            }],
            start_mm_deg: [0.0, 0.0, -20.0, 0.0, 0.0, 0.0],
            ..Settings::default()
        },
    );
    line(&typed, &mut interp, "G10 L10 P3 Z0").expect("touch-off");
    assert_eq!(interp.tools()[0].length_mm, -20.0);
}

#[test]
fn cutter_compensation_is_refused_and_m2_ends_the_session() {
    let (typed, mut interp) = session(Dialect::LinuxCnc, Settings::default());
    let e = line(&typed, &mut interp, "G41.1 D2 G1 X10 F100").expect_err("comp");
    assert!(e.message.contains("not available in MDI"), "{e}");
    line(&typed, &mut interp, "M2").expect("program end");
    assert!(interp.ended());
}
