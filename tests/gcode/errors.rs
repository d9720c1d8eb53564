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
    // A non-zero tool radius with G41/G42 is an error in every dialect, at the G41/G42 word,
    // saying "cutter compensation"; the block's move is not yielded.
    let s = settings_with_tool(4, 0.0, 1.5);
    let cases = [
        (
            Dialect::LinuxCnc,
            "T4 M6\nG1 X1 F100\nG41 G1 X10\nG1 X20\n",
            3,
            1,
        ),
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
