//! The LinuxCNC language layer never panics or hangs: token soup of parameters,
//! expressions and O-words, and mutations of the language golden programs.
//!
//! Loops may legitimately emit more items than the input has bytes, so these runs use a
//! small `max_loop_iterations` and their own item cap instead of
//! [`kerf_tests::item_bound`]; everything else is checked as in `fuzz.rs`.

use proptest::prelude::*;
use proptest::test_runner::{RngSeed, TestRunner};

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
