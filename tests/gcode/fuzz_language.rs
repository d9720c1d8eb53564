//! The LinuxCNC language layer never panics or hangs: token soup of parameters,
//! expressions and O-words, and mutations of the language golden programs.
//!
//! Loops may legitimately emit more items than the input has bytes, so these runs use a
//! small `max_loop_iterations` and their own item cap instead of
//! [`kerf_tests::item_bound`]; everything else is checked as in `fuzz.rs`.

use proptest::prelude::*;
use proptest::test_runner::{RngSeed, TestRunner};

use kerf_gcode::InputWait;
use kerf_tests::*;

const CASES: u32 = 1500;
/// Loops stop after this many iterations in these runs.
const LOOP_LIMIT: u64 = 8;
/// No input of at most 400 tokens may yield more items than this (loops nest at most a few
/// deep with `LOOP_LIMIT` iterations, subroutines nine deep).
const ITEM_CAP: usize = 2_000_000;

const TOKENS: &[&str] = &[
    "#1=",
    "#2=",
    "#<a>=",
    "#<_g>=",
    "#<a>",
    "#<_g>",
    "##1",
    "#1",
    "#5420",
    "#<_x>",
    "#<_value>",
    "#[",
    "#<",
    "[",
    "]",
    "[1+",
    "*",
    "/",
    "**",
    "MOD",
    "EQ",
    "NE",
    "GT",
    "LT",
    "AND",
    "OR",
    "XOR",
    "-",
    "+",
    "ABS[",
    "ATAN[1]/[",
    "SIN[",
    "SQRT[",
    "LN[",
    "FIX[",
    "ROUND[",
    "EXISTS[#<a>]",
    "G1",
    "G0",
    "G[1]",
    "X",
    "Y",
    "Z",
    "F100",
    "M2",
    "o1 while [",
    "o1 endwhile",
    "o2 do",
    "o2 while [",
    "o3 repeat [",
    "o3 endrepeat",
    "o4 if [",
    "o4 elseif [",
    "o4 else",
    "o4 endif",
    "o1 break",
    "o1 continue",
    "o<s> sub",
    "o<s> endsub",
    "o<s> call [",
    "o<s> return",
    "o<t> call",
    "o100 sub",
    "o100 call",
    "(MSG,hi)",
    "(DEBUG,#1 #<a>)",
    "(PRINT,#<_x>)",
    "(",
    ")",
    "\n",
    " ",
    "1",
    "0",
    "2.5",
    "-1",
    "1e9",
    "99999999999",
    // Machine I/O (issue 28) and the wait's result.
    "M66 P1 L3 Q1",
    "M66 E0",
    "M66 P",
    "M62 P",
    "M67 E1 Q",
    "#5399",
    "#5399=",
    "EXISTS[#5399]",
    "(PRINT,#5399)",
];

fn soup() -> impl Strategy<Value = Vec<u8>> {
    prop::collection::vec(0..TOKENS.len(), 0..400).prop_map(|parts| {
        let mut s = String::new();
        for t in parts {
            s.push_str(TOKENS[t]);
        }
        s.into_bytes()
    })
}

fn check(bytes: &[u8]) {
    let settings = Settings {
        max_loop_iterations: LOOP_LIMIT,
        ..Settings::default()
    };
    let mut it = Interpreter::new(bytes, Dialect::LinuxCnc, settings);
    let mut n = 0usize;
    let max_line = 1 + bytes.iter().filter(|&&b| b == b'\n' || b == b'\r').count() as u32;
    while let Some(item) = it.next() {
        n += 1;
        assert!(n <= ITEM_CAP, "more than {ITEM_CAP} items");
        match item {
            Ok(Item::Move(m)) => {
                let (s, e) = match m.path {
                    Path::Line(l) => (l.start, l.end),
                    Path::Arc(a) => (a.start, a.end),
                };
                assert!(s.iter().chain(e.iter()).all(|c| c.is_finite()), "{m:?}");
                assert!((1..=max_line).contains(&m.line));
            }
            Ok(Item::Event(e)) => {
                assert!(e.value.is_none_or(f64::is_finite), "{e:?}");
            }
            Err(d) => {
                assert!(d.line >= 1 && d.col >= 1 && !d.message.is_empty(), "{d:?}");
                assert!(it.next().is_none(), "items after the error");
                return;
            }
        }
    }
}

fn run<S: Strategy<Value = Vec<u8>>>(seed: u64, strategy: S) {
    let config = ProptestConfig {
        cases: CASES,
        rng_seed: RngSeed::Fixed(seed),
        failure_persistence: None,
        ..ProptestConfig::default()
    };
    let mut runner = TestRunner::new(config);
    if let Err(e) = runner.run(&strategy, |bytes| {
        check(&bytes);
        Ok(())
    }) {
        panic!("language fuzzing from seed {seed:#x} failed: {e}");
    }
}

#[test]
fn language_token_soup_never_panics_or_hangs() {
    run(0x6b65_7266_0101, soup());
}

#[test]
fn mutated_language_programs_never_panic_or_hang() {
    let dir = data_dir().join("ngc/lang");
    let corpus: Vec<Vec<u8>> = files_with_ext(&dir, "ngc")
        .into_iter()
        .map(|p| std::fs::read(p).unwrap())
        .collect();
    assert!(!corpus.is_empty());
    let strategy = (
        any::<usize>(),
        prop::collection::vec((any::<usize>(), 0..TOKENS.len(), 0usize..3), 1..8),
    )
        .prop_map(move |(which, edits)| {
            let mut bytes = corpus[which % corpus.len()].clone();
            for (at, token, op) in edits {
                let p = at % (bytes.len() + 1);
                match op {
                    0 => {
                        bytes.splice(p..p, TOKENS[token].bytes());
                    }
                    1 => {
                        let e = (p + token % 16).min(bytes.len());
                        bytes.drain(p..e);
                    }
                    _ => bytes.truncate(p),
                }
            }
            bytes
        });
    run(0x6b65_7266_0102, strategy);
}

#[test]
fn language_corpus_never_panics_or_hangs() {
    let dir = data_dir().join("fuzz/linuxcnc");
    let files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name()
                .is_some_and(|n| n.to_string_lossy().starts_with("lang_"))
        })
        .collect();
    assert!(files.len() >= 8, "{files:?}");
    for f in files {
        check(&std::fs::read(&f).unwrap());
    }
}

/// Whole lines around M66 and `#5399`, mostly valid, with some that are not.
const IO_LINES: &[&str] = &[
    "M66 P1 L3 Q1",
    "M66 E2",
    "M66 P0",
    "M66 P[#5399+1] L4 Q2",
    "#1=#5399",
    "#5399=2",
    "#2=[#5399*2+#1]",
    "o1 if [#5399 GT 0]",
    "o1 else",
    "o1 endif",
    "o2 repeat [3]",
    "o2 endrepeat",
    "G1 X[#5399] F100",
    "(PRINT,#5399)",
    "o3 if [EXISTS[#5399]]",
    "o3 endif",
    "M62 P1",
    "M67 E0 Q#5399",
    "G0 X1",
    "M66 P1 L3",
    "#<v>=#5399",
    "M2",
];

/// Programs of [`IO_LINES`], with now and then a token of the soup.
fn io_program() -> impl Strategy<Value = Vec<u8>> {
    prop::collection::vec((0..IO_LINES.len(), 0..TOKENS.len(), 0u8..10), 0..40).prop_map(|lines| {
        let mut s = String::new();
        for (line, token, junk) in lines {
            s.push_str(IO_LINES[line]);
            if junk == 0 {
                s.push_str(TOKENS[token]);
            }
            s.push('\n');
        }
        s.into_bytes()
    })
}

/// A machine that answers every wait and records what it was asked.
struct Recorder(std::sync::Arc<std::sync::Mutex<Vec<Event>>>);

impl InputWait for Recorder {
    fn wait(&mut self, event: &Event) -> Result<f64, String> {
        let mut asked = self.0.lock().map_err(|e| e.to_string())?;
        asked.push(event.clone());
        Ok(if asked.len() % 2 == 0 { 1.0 } else { -1.0 })
    }
}

/// Issue 28: on any program the interpreter asks for an M66's answer only after it has
/// yielded that M66 event, at most once per M66, and in program order: the machine is
/// never asked to wait on an input it has not been told about.
#[test]
fn the_machine_is_asked_only_about_m66_events_already_handed_on() {
    let config = ProptestConfig {
        cases: CASES,
        rng_seed: RngSeed::Fixed(0x6b65_7266_0103),
        failure_persistence: None,
        ..ProptestConfig::default()
    };
    let mut runner = TestRunner::new(config);
    // Questions over all cases: the property must not hold only because nothing asks.
    let questions = std::sync::atomic::AtomicUsize::new(0);
    let strategy = prop_oneof![soup(), io_program()];
    let result = runner.run(&strategy, |bytes| {
        let asked = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
        let settings = Settings {
            max_loop_iterations: LOOP_LIMIT,
            ..Settings::default()
        };
        let it = Interpreter::new(&bytes[..], Dialect::LinuxCnc, settings)
            .with_input_wait(Box::new(Recorder(std::sync::Arc::clone(&asked))));
        // The M66 events yielded so far, and how many of them were asked about.
        let mut yielded: Vec<Event> = Vec::new();
        let mut matched = 0usize;
        let mut n = 0usize;
        for item in it {
            n += 1;
            prop_assert!(n <= ITEM_CAP);
            let now = asked.lock().expect("lock").clone();
            // Every new question is about an M66 yielded before this item, after the
            // M66 of the previous question.
            for q in &now[matched.min(now.len())..] {
                let found = yielded.iter().position(|e| e == q);
                prop_assert!(found.is_some(), "asked about {q:?} before yielding it");
                yielded.drain(..=found.unwrap_or(0));
            }
            matched = now.len();
            match item {
                Ok(Item::Event(e)) if matches!(e.code, EventCode::M66 | EventCode::M66Analog) => {
                    yielded.push(e)
                }
                Ok(_) => {}
                Err(_) => break,
            }
        }
        questions.fetch_add(matched, std::sync::atomic::Ordering::Relaxed);
        Ok(())
    });
    if let Err(e) = result {
        panic!("{e}");
    }
    let questions = questions.into_inner();
    assert!(
        questions >= 50,
        "only {questions} waits asked in {CASES} programs"
    );
}
