//! Bad programs: one program per error in `tests/data/errors/<dialect>/NAME.<ext>`, with the
//! expected place and message next to it in `NAME.expect`:
//!
//! ```text
//! at LINE:COL          1-based line and byte column of the offending word
//! items N              items yielded before the error (from the earlier blocks)
//! message FRAGMENT     a fragment the message must contain (case-insensitive), repeatable
//! ```
//!
//! The table-driven test runs every program and reports every failure at once. Besides the
//! place and the message it checks that the blocks before the failing one were yielded,
//! that nothing of the failing block or after it was (invariant 6: bad input never moves
//! the machine), and that the iterator stops after the error.

use std::path::Path as FsPath;

use kerf_tests::*;

struct Expect {
    line: u32,
    col: u32,
    items: usize,
    fragments: Vec<String>,
}

fn parse_expect(path: &FsPath) -> Result<Expect, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut at = None;
    let mut items = None;
    let mut fragments = Vec::new();
    for l in text.lines() {
        let l = l.trim();
        if l.is_empty() || l.starts_with('#') {
            continue;
        }
        if let Some(rest) = l.strip_prefix("at ") {
            let (a, b) = rest.split_once(':').ok_or("bad 'at'")?;
            at = Some((
                a.trim().parse::<u32>().map_err(|e| e.to_string())?,
                b.trim().parse::<u32>().map_err(|e| e.to_string())?,
            ));
        } else if let Some(rest) = l.strip_prefix("items ") {
            items = Some(rest.trim().parse::<usize>().map_err(|e| e.to_string())?);
        } else if let Some(rest) = l.strip_prefix("message ") {
            fragments.push(rest.trim().to_string());
        } else {
            return Err(format!("{}: unknown line {l:?}", path.display()));
        }
    }
    let (line, col) = at.ok_or("missing 'at'")?;
    Ok(Expect {
        line,
        col,
        items: items.ok_or("missing 'items'")?,
        fragments,
    })
}

/// Checks one error program; returns a description of every way it fails.
fn check_error_program(d: Dialect, program: &FsPath) -> Vec<String> {
    let name = program.display().to_string();
    let expect = match parse_expect(&program.with_extension("expect")) {
        Ok(e) => e,
        Err(e) => return vec![format!("{name}: {e}")],
    };
    let src = std::fs::read(program).expect("program");
    let out = run_bytes(d, Settings::default(), &src);
    let mut problems = Vec::new();
    let Some(diag) = out.error else {
        return vec![format!(
            "{name}: accepted, but must fail at {}:{} with {:?}; items:\n{}",
            expect.line,
            expect.col,
            expect.fragments,
            describe_items(&out.items)
        )];
    };
    if (diag.line, diag.col) != (expect.line, expect.col) {
        problems.push(format!(
            "{name}: error at {}:{}, want {}:{} ({})",
            diag.line, diag.col, expect.line, expect.col, diag
        ));
    }
    let msg = diag.message.to_lowercase();
    for f in &expect.fragments {
        if !msg.contains(&f.to_lowercase()) {
            problems.push(format!("{name}: message {:?} lacks {f:?}", diag.message));
        }
    }
    if out.items.len() != expect.items {
        problems.push(format!(
            "{name}: {} items before the error, want {}:\n{}",
            out.items.len(),
            expect.items,
            describe_items(&out.items)
        ));
    }
    if let Some(late) = out.items.iter().find(|i| item_line(i) > diag.line) {
        problems.push(format!(
            "{name}: item after the failing block was yielded: {late:?}"
        ));
    }
    // The blocks before the failing line, run on their own, give exactly the items that
    // were yielded before the error (unless the failing line also holds earlier blocks).
    if !out.items.iter().any(|i| item_line(i) == diag.line) {
        let text = String::from_utf8_lossy(&src);
        let prefix: String = text
            .split_inclusive('\n')
            .take(diag.line.saturating_sub(1) as usize)
            .collect();
        let before = run_bytes(d, Settings::default(), prefix.as_bytes());
        if describe_items(&before.items) != describe_items(&out.items) {
            problems.push(format!(
                "{name}: items before the error differ from the items of the lines before it:\n{}\nvs\n{}",
                describe_items(&out.items),
                describe_items(&before.items)
            ));
        }
    }
    problems
}

#[test]
fn one_program_per_error_for_every_dialect() {
    let mut problems = Vec::new();
    let mut count = 0;
    for d in Dialect::ALL {
        let dir = data_dir().join("errors").join(d.name());
        let programs = files_with_ext(&dir, extension(d));
        assert!(!programs.is_empty(), "no error programs for {}", d.name());
        for p in programs {
            count += 1;
            problems.extend(check_error_program(d, &p));
        }
    }
    assert!(
        problems.is_empty(),
        "{} of {count} error programs failed:\n{}",
        problems.len(),
        problems.join("\n")
    );
}

#[test]
fn every_error_program_has_an_expectation() {
    for d in Dialect::ALL {
        let dir = data_dir().join("errors").join(d.name());
        for p in files_with_ext(&dir, extension(d)) {
            let e = p.with_extension("expect");
            assert!(e.exists(), "{} has no {}", p.display(), e.display());
            parse_expect(&e).unwrap_or_else(|err| panic!("{err}"));
        }
    }
}

#[test]
fn diagnostic_displays_line_col_error_message() {
    let d = error(Dialect::LinuxCnc, "G1 X10 F100\nG2 X30 Y0 R5\n");
    let shown = d.to_string();
    let want_prefix = format!("{}:{}: error: ", d.line, d.col);
    assert!(shown.starts_with(&want_prefix), "{shown:?}");
    assert!(shown.ends_with(&d.message), "{shown:?}");
    assert!(!d.message.is_empty());
    assert!(!d.message.contains('\n'), "one line: {:?}", d.message);
}

#[test]
fn cutter_compensation_error_stops_before_the_block() {
    // A non-zero tool radius with G41/G42 is an error in every dialect but LinuxCNC (which
    // compensates: tests/gcode/comp.rs), at the G41/G42 word, saying "cutter
    // compensation"; the block's move is not yielded.
    let s = settings_with_tool(4, 0.0, 1.5);
    let cases = [
        (
            Dialect::Rockwell,
            "T4 M06 ;\nG01 X1 F100 ;\nG41 D4 G01 X10 ;\n",
            3,
            1,
        ),
        (
            Dialect::Sinumerik,
            "T4 M6\nG1 X1 F100\nN30 G41 G1 X10\n",
            3,
            5,
        ),
        (
            Dialect::Heidenhain,
            "%C G71 *\nN10 T4 G17 *\nN20 G01 X+1 F100 *\nN30 G01 G41 X+10 *\nN40 %C G71 *\n",
            4,
            9,
        ),
        (Dialect::Fagor, "T4 M6\nG01 X1 F100\nG41 G01 X10\n", 3, 1),
    ];
    for (d, src, line, col) in cases {
        let out = run_bytes(d, s.clone(), src.as_bytes());
        let diag = out
            .error
            .unwrap_or_else(|| panic!("{}: G41 with radius 1.5 accepted", d.name()));
        assert_diag(&diag, line, col, &["cutter compensation"]);
        let ms = only_moves(&out.items);
        assert_eq!(
            ms.len(),
            1,
            "{}: only the move before G41: {ms:#?}",
            d.name()
        );
    }
}

#[test]
fn negative_dwell_is_refused_in_every_dialect_at_the_time_word() {
    // Each control's dwell word (LinuxCNC G4 P, Rockwell G04 X or P, Sinumerik G4 F or S,
    // Heidenhain G04 F, Fagor G04 K) with a negative value stops the program at that word;
    // the move before it is yielded, nothing after it.
    let cases = [
        (
            Dialect::LinuxCnc,
            "G1 X1 F100\nG4 P-1\nG1 X2\n",
            2,
            4,
            "Negative P word used",
        ),
        (
            Dialect::Rockwell,
            "G01 X1 F100 ;\nG04 X-1.5 ;\nG01 X2 ;\n",
            2,
            5,
            "negative dwell time X",
        ),
        (
            Dialect::Rockwell,
            "G01 X1 F100 ;\nG04 P-1 ;\nG01 X2 ;\n",
            2,
            5,
            "negative dwell time P",
        ),
        (
            Dialect::Sinumerik,
            "G1 X1 F100\nN20 G4 F-2\nG1 X2\n",
            2,
            8,
            "negative dwell time F",
        ),
        (
            Dialect::Sinumerik,
            "G1 X1 F100\nG4 S-3\nG1 X2\n",
            2,
            4,
            "negative dwell time S",
        ),
        (
            Dialect::Heidenhain,
            "%C G71 *\nN10 G01 X+1 F100 *\nN20 G04 F-1 *\nN30 G01 X+2 *\nN40 %C G71 *\n",
            3,
            9,
            "negative dwell time F",
        ),
        (
            Dialect::Fagor,
            "G01 X1 F100\nG04 K-0.5\nG01 X2\n",
            2,
            5,
            "negative dwell time K",
        ),
    ];
    for (d, src, line, col, message) in cases {
        let out = run_bytes(d, Settings::default(), src.as_bytes());
        let diag = out
            .error
            .unwrap_or_else(|| panic!("{}: {src:?} accepted", d.name()));
        assert_diag(&diag, line, col, &[message]);
        let ms = only_moves(&out.items);
        assert_eq!(ms.len(), 1, "{}: only the move before: {ms:#?}", d.name());
    }
}

#[test]
fn absurdly_long_dwell_is_refused() {
    // Up to 1e6 s (11.6 days) is accepted; beyond that the value is a mistake.
    for (d, ok, bad, col) in [
        (Dialect::LinuxCnc, "G4 P1000000\nM2\n", "G4 P1000001\n", 4),
        (
            Dialect::Rockwell,
            "G04 X1000000 ;\n",
            "G04 X1000000.5 ;\n",
            5,
        ),
        (Dialect::Sinumerik, "G4 F1000000\n", "G4 F2000000\n", 4),
        (Dialect::Fagor, "G04 K1000000\n", "G04 K99999999\n", 5),
    ] {
        let out = run_bytes(d, Settings::default(), ok.as_bytes());
        assert!(out.error.is_none(), "{}: {ok:?}: {:?}", d.name(), out.error);
        let diag = error(d, bad);
        assert_diag(&diag, 1, col, &["dwell time", "at most 1000000"]);
    }
    let diag = error(
        Dialect::Heidenhain,
        "%C G71 *\nN10 G04 F1000001 *\nN20 %C G71 *\n",
    );
    assert_diag(&diag, 2, 9, &["dwell time F", "at most 1000000"]);
}

#[test]
fn dwell_words_missing_repeated_or_mixed_with_motion() {
    // LinuxCNC requires P with G4, in its own words.
    assert_diag(
        &error(Dialect::LinuxCnc, "G1 X1 F100\nG4\n"),
        2,
        1,
        &["Dwell time P word missing with G4"],
    );
    // Two dwell times in one block.
    assert_diag(
        &error(Dialect::Rockwell, "G04 X1 P2 ;\n"),
        1,
        8,
        &["dwell time given twice"],
    );
    assert_diag(
        &error(Dialect::Sinumerik, "G4 F1 S2\n"),
        1,
        7,
        &["dwell time given twice"],
    );
    // Outside LinuxCNC the dwell is a block of its own: an axis word there would otherwise
    // be dropped silently.
    let cases = [
        (Dialect::Rockwell, "G04 X1 Y5 ;\n", 8, "Y word"),
        (Dialect::Sinumerik, "G4 F2 X1\n", 7, "X word"),
        (Dialect::Heidenhain, "%C G71 *\nG04 F2 Z+1 *\n", 8, "Z word"),
        (Dialect::Fagor, "G04 K1 X3\n", 8, "X word"),
    ];
    for (d, src, col, word) in cases {
        let diag = error(d, src);
        let line = src.lines().count() as u32;
        assert_diag(&diag, line, col, &["separate block", word]);
    }
}
