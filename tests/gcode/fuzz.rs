//! Never panic, never hang, never emit non-finite geometry, on any byte sequence.
//!
//! Property tests from a fixed seed with a fixed case count (independent of
//! `PROPTEST_CASES`): random bytes, random G-code-like token soup, and random mutations
//! (byte flips, insertions, deletions, truncation, splices, token insertions) of the valid
//! fixture programs of every dialect. A regression corpus of nasty inputs in
//! `tests/data/fuzz/` is replayed in every dialect.
//!
//! "Never hang" is checked as far as a test can without timing: the iterator must stop
//! after the first error and may not yield more items than the input could describe
//! ([`kerf_tests::item_bound`]).

use std::cell::Cell;

use proptest::prelude::*;
use proptest::test_runner::{RngSeed, TestError, TestRunner};

use kerf_tests::*;

const CASES: u32 = 2000;

fn config(seed: u64) -> ProptestConfig {
    ProptestConfig {
        cases: CASES,
        rng_seed: RngSeed::Fixed(seed),
        failure_persistence: None,
        max_shrink_iters: 4096,
        ..ProptestConfig::default()
    }
}

/// Runs `bytes` in `d` and checks everything that must hold for any input.
pub(super) fn check_any_input(d: Dialect, bytes: &[u8]) {
    let out = run_bytes(d, Settings::default(), bytes);
    check_outcome(d, bytes, &out);
}

/// Checks everything that must hold for any input `bytes` on the outcome `out` of running
/// it in `d`.
pub(super) fn check_outcome(d: Dialect, bytes: &[u8], out: &Outcome) {
    // Any of LF, CR may end a line; the line numbers reported cannot exceed that count.
    let max_line = 1 + bytes.iter().filter(|&&b| b == b'\n' || b == b'\r').count() as u32;
    // LinuxCNC O-words run subroutines and loops: their items come from earlier lines.
    let ordered = !(d == Dialect::LinuxCnc && bytes.iter().any(|&b| b == b'o' || b == b'O'));
    let mut last_line = 0;
    for item in &out.items {
        let l = item_line(item);
        assert!(
            (1..=max_line).contains(&l),
            "{}: item line {l} outside 1..={max_line}: {item:?}",
            d.name()
        );
        assert!(
            !ordered || l >= last_line,
            "{}: items out of source order",
            d.name()
        );
        last_line = l;
        if let Item::Move(m) = item {
            check_move_finite(d, m);
        }
        if let Item::Event(e) = item
            && let Some(v) = e.value
        {
            assert!(v.is_finite(), "{}: non-finite event value {e:?}", d.name());
        }
    }
    if let Some(e) = &out.error {
        assert!(
            (1..=max_line).contains(&e.line) && e.col >= 1,
            "{}: diagnostic place {}:{} outside the input ({max_line} lines): {e}",
            d.name(),
            e.line,
            e.col
        );
        assert!(!e.message.trim().is_empty(), "{}: empty message", d.name());
        assert!(
            !ordered || out.items.iter().all(|i| item_line(i) <= e.line),
            "{}: items after the failing line {}",
            d.name(),
            e.line
        );
    }
}

fn check_move_finite(d: Dialect, m: &Move) {
    let finite = |p: Vec3| p.iter().all(|c| c.is_finite());
    let ctx = || format!("{}: {}", d.name(), describe_move(m));
    match m.path {
        Path::Line(l) => assert!(
            finite(l.start) && finite(l.end),
            "non-finite line {}",
            ctx()
        ),
        Path::Arc(a) => {
            assert!(
                finite(a.start) && finite(a.end) && finite(a.center) && a.sweep_rad.is_finite(),
                "non-finite arc {}",
                ctx()
            );
            assert!(
                (a.axis.norm() - 1.0).abs() < 1e-9,
                "axis not a unit vector {}",
                ctx()
            );
            assert!(a.sweep_rad != 0.0, "zero-sweep arc {}", ctx());
        }
    }
    if m.rapid {
        assert!(m.feed_mm_min.is_none(), "rapid with a feed {}", ctx());
    } else {
        let f = m
            .feed_mm_min
            .unwrap_or_else(|| panic!("feed move without feed {}", ctx()));
        assert!(
            f.is_finite() && f > 0.0,
            "feed must be finite and positive {}",
            ctx()
        );
    }
    if let Some((s, e)) = m.abc_deg {
        assert!(
            s.iter().chain(&e).all(|c| c.is_finite()),
            "non-finite rotary axes {}",
            ctx()
        );
    }
}

/// The valid fixture programs (the pockets, the seed examples), as bytes.
fn fixtures() -> Vec<Vec<u8>> {
    let mut out = Vec::new();
    for d in Dialect::ALL {
        let dir = data_dir().join("programs").join(d.name());
        for p in files_with_ext(&dir, extension(d)) {
            out.push(std::fs::read(p).expect("fixture"));
        }
    }
    assert!(!out.is_empty());
    out
}

/// Words and fragments of every dialect, for token soup and insertions.
const TOKENS: &[&str] = &[
    "G0", "G1", "G2", "G3", "G02", "G03", "G17", "G18", "G19", "G20", "G21", "G90", "G91", "G90.1",
    "G91.1", "G70", "G71", "G700", "G710", "G110", "G111", "G112", "G10", "G11", "G12", "G13",
    "G15", "G29", "G30", "G40", "G41", "G42", "G43", "G49", "G92", "G92.1", "G54", "G59.3", "G93",
    "G95", "M0", "M2", "M3", "M6", "M30", "X", "Y", "Z", "A", "B", "C", "I", "J", "K", "R", "P",
    "Q", "H", "F", "S", "T", "D", "N", "@", "^", "RP=", "AP=", "AP=IC(", "CR=", "TURN=", "I=AC(",
    "X=IC(", ")", "(", "*", ";", "%", "/", "#", "[", "]", "=", " ", "\n", "\r", "+", "-", ".", "E",
    "O100 sub", "G94", "G61", "G61.1", "G64", "M60", "M70", "M71", "M72", "M73", "M101", "M199",
    "M7", "M8", "M9", "G73", "G80", "G81", "G82", "G83", "G85", "G86", "G87", "G88", "G89", "G98",
    "G99", "L", "M62", "M63", "M64", "M65", "M66", "M67", "M68",
];

const NUMBERS: &[&str] = &[
    "0",
    "1",
    "-1",
    "10",
    "-10",
    "0.5",
    ".5",
    "-.5",
    "5.",
    "360",
    "-360",
    "720",
    "5400",
    "-5400",
    "1e9",
    "1e308",
    "-1e308",
    "4294967295",
    "4294967296",
    "99999999999999999999",
    "1e-300",
    "0.00001",
    "nan",
    "inf",
    "-",
    "+",
    ".",
    "",
    "1.2.3",
    "--1",
    "+0",
    "-0",
    "179.999",
    "180",
    "0.0127",
    "25.4",
];

fn token_soup() -> impl Strategy<Value = Vec<u8>> {
    prop::collection::vec((0..TOKENS.len(), 0..NUMBERS.len(), any::<bool>()), 0..120).prop_map(
        |parts| {
            let mut s = String::new();
            for (t, n, with_number) in parts {
                s.push_str(TOKENS[t]);
                if with_number {
                    s.push_str(NUMBERS[n]);
                }
                s.push(' ');
            }
            s.into_bytes()
        },
    )
}

#[derive(Clone, Debug)]
enum Mutation {
    Flip {
        at: usize,
        bit: u8,
    },
    Insert {
        at: usize,
        byte: u8,
    },
    InsertToken {
        at: usize,
        token: usize,
        number: usize,
    },
    Delete {
        at: usize,
        len: usize,
    },
    Truncate {
        at: usize,
    },
    Splice {
        at: usize,
        from: usize,
        start: usize,
        len: usize,
    },
    Duplicate {
        at: usize,
        len: usize,
    },
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        (any::<usize>(), 0u8..8).prop_map(|(at, bit)| Mutation::Flip { at, bit }),
        (any::<usize>(), any::<u8>()).prop_map(|(at, byte)| Mutation::Insert { at, byte }),
        (any::<usize>(), 0..TOKENS.len(), 0..NUMBERS.len())
            .prop_map(|(at, token, number)| Mutation::InsertToken { at, token, number }),
        (any::<usize>(), 0usize..40).prop_map(|(at, len)| Mutation::Delete { at, len }),
        any::<usize>().prop_map(|at| Mutation::Truncate { at }),
        (any::<usize>(), any::<usize>(), any::<usize>(), 0usize..200).prop_map(
            |(at, from, start, len)| Mutation::Splice {
                at,
                from,
                start,
                len
            }
        ),
        (any::<usize>(), 0usize..80).prop_map(|(at, len)| Mutation::Duplicate { at, len }),
    ]
}

fn apply(mut bytes: Vec<u8>, muts: &[Mutation], corpus: &[Vec<u8>]) -> Vec<u8> {
    for m in muts {
        let n = bytes.len();
        let pos = |at: usize| if n == 0 { 0 } else { at % (n + 1) };
        match *m {
            Mutation::Flip { at, bit } => {
                if n > 0 {
                    bytes[at % n] ^= 1 << bit;
                }
            }
            Mutation::Insert { at, byte } => bytes.insert(pos(at), byte),
            Mutation::InsertToken { at, token, number } => {
                let p = pos(at);
                let text = format!("{}{}", TOKENS[token], NUMBERS[number]);
                bytes.splice(p..p, text.bytes());
            }
            Mutation::Delete { at, len } => {
                let p = pos(at);
                let end = (p + len).min(n);
                bytes.drain(p..end);
            }
            Mutation::Truncate { at } => bytes.truncate(pos(at)),
            Mutation::Splice {
                at,
                from,
                start,
                len,
            } => {
                let src = &corpus[from % corpus.len()];
                let s = start % (src.len() + 1);
                let e = (s + len).min(src.len());
                let p = pos(at);
                bytes.splice(p..p, src[s..e].iter().copied());
            }
            Mutation::Duplicate { at, len } => {
                let p = pos(at);
                let e = (p + len).min(n);
                let copy = bytes[p..e].to_vec();
                bytes.splice(e..e, copy);
            }
        }
    }
    bytes
}

/// Runs `CASES` cases of `strategy` from `seed`, checking [`check_any_input`] on each input
/// in dialect `Dialect::ALL[d]`. A failure is shrunk to a minimal input and reported with its
/// bytes, ready to be added to the regression corpus.
fn fuzz<S>(seed: u64, strategy: S)
where
    S: Strategy<Value = (usize, Vec<u8>)>,
{
    let mut runner = TestRunner::new(config(seed));
    let cases = Cell::new(0u32);
    let result = runner.run(&strategy, |(d, bytes)| {
        cases.set(cases.get() + 1);
        check_any_input(Dialect::ALL[d], &bytes);
        Ok(())
    });
    if let Err(e) = result {
        let detail = match &e {
            TestError::Fail(reason, (d, bytes)) => format!(
                "{reason}\ndialect {}, input {:?}",
                Dialect::ALL[*d].name(),
                String::from_utf8_lossy(bytes)
            ),
            TestError::Abort(reason) => format!("aborted: {reason}"),
        };
        panic!("fuzzing from seed {seed:#x} failed: {detail}");
    }
    assert_eq!(
        cases.get(),
        CASES,
        "every case must run, whatever PROPTEST_CASES says"
    );
}

#[test]
fn random_bytes_never_panic() {
    fuzz(
        0x6b65_7266_0001,
        (0..5usize, prop::collection::vec(any::<u8>(), 0..600)),
    );
}

#[test]
fn token_soup_never_panics() {
    fuzz(0x6b65_7266_0002, (0..5usize, token_soup()));
}

#[test]
fn mutated_fixtures_never_panic() {
    let corpus = fixtures();
    let strategy = (
        0..5usize,
        any::<usize>(),
        prop::collection::vec(mutation(), 1..8),
    )
        .prop_map(move |(d, which, muts)| {
            let base = corpus[which % corpus.len()].clone();
            (d, apply(base, &muts, &corpus))
        });
    fuzz(0x6b65_7266_0003, strategy);
}

#[test]
fn fixtures_in_foreign_dialects_never_panic() {
    // Every valid program of one control fed to every other control: errors are fine,
    // panics and non-finite output are not.
    for bytes in fixtures() {
        for d in Dialect::ALL {
            check_any_input(d, &bytes);
        }
    }
}

#[test]
fn regression_corpus_is_replayed_in_every_dialect() {
    let root = data_dir().join("fuzz");
    let mut files = Vec::new();
    for d in Dialect::ALL {
        let dir = root.join(d.name());
        if let Ok(rd) = std::fs::read_dir(&dir) {
            files.extend(
                rd.filter_map(|e| e.ok().map(|e| e.path()))
                    .filter(|p| p.is_file()),
            );
        }
    }
    files.sort();
    assert!(
        files.len() >= 20,
        "regression corpus missing: {} files",
        files.len()
    );
    for f in files {
        let bytes = std::fs::read(&f).expect("corpus file");
        for d in Dialect::ALL {
            let r = std::panic::catch_unwind(|| check_any_input(d, &bytes));
            assert!(r.is_ok(), "{} in {} failed", f.display(), d.name());
        }
    }
}
