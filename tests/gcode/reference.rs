//! `docs/DIALECTS.md`, the G and M code reference of every dialect, is generated here from
//! the interpreter's own tables (`kerf_gcode::code_reference`, `word_addresses`), with a
//! link from each code to a test or test program that uses it. The test fails when the
//! page and the code differ; `KERF_BLESS=1 cargo test -p kerf-tests reference` rewrites it.
//!
//! Each listed code is also checked through the interpreter: a supported code is not
//! refused as unknown or unsupported, a refused one gives exactly the listed error.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use kerf_gcode::{CodeInfo, Dialect, Interpreter, Settings, code_reference, word_addresses};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Files searched for a use of a code, in order: the dialect's own test module, its test
/// programs, then the other test modules, LinuxCNC's golden programs and the front end's
/// unit tests.
fn sources(d: Dialect) -> Vec<(String, String)> {
    let mut files = vec![format!("tests/gcode/{}.rs", d.name())];
    files.extend(under(
        &format!("tests/data/programs/{}", d.name()),
        &["ngc", "nc", "mpf", "spf", "h", "i", "pim", "pit"],
    ));
    // The modules that test every dialect (not another dialect's own module, nor the
    // LinuxCNC language's).
    for m in [
        "cross_dialect",
        "grammar",
        "errors",
        "codes",
        "comp",
        "modal",
        "syntax",
        "api",
        "fuzz",
    ] {
        files.push(format!("tests/gcode/{m}.rs"));
    }
    if d == Dialect::LinuxCnc {
        files.extend(under("tests/gcode", &["rs"]));
        files.extend(under("tests/data/ngc", &["ngc"]));
    }
    files.push("crates/kerf-gcode/src/tests.rs".to_string());
    let mut seen = std::collections::HashSet::new();
    files
        .into_iter()
        .filter(|f| seen.insert(f.clone()))
        .filter_map(|f| {
            std::fs::read_to_string(root().join(&f))
                .ok()
                .map(|t| (f, t))
        })
        .collect()
}

/// The files under `rel` (relative to the workspace) with one of the extensions, sorted.
fn under(rel: &str, ext: &[&str]) -> Vec<String> {
    let mut found = Vec::new();
    let mut stack = vec![root().join(rel)];
    while let Some(p) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&p) else {
            continue;
        };
        for e in entries.flatten() {
            let path = e.path();
            if path.is_dir() {
                stack.push(path);
            } else if path
                .extension()
                .is_some_and(|x| ext.iter().any(|e| x.eq_ignore_ascii_case(e)))
            {
                let rel = path
                    .strip_prefix(root())
                    .unwrap()
                    .to_string_lossy()
                    .into_owned();
                found.push(rel);
            }
        }
    }
    found.sort();
    found
}

/// Whether `line` uses `code` (`G2` also as `G02`, not as `G20` or `G2.1`; `M3` not as
/// `M30`), as a word: not inside a longer name.
fn uses(line: &str, code: &str) -> bool {
    let (letter, number) = code.split_at(1);
    let (int, frac) = match number.split_once('.') {
        Some((i, f)) => (i, Some(f)),
        None => (number, None),
    };
    let b = line.as_bytes();
    let mut i = 0;
    while let Some(pos) =
        line[i..].find(|c: char| c.eq_ignore_ascii_case(&letter.chars().next().unwrap()))
    {
        let at = i + pos;
        i = at + 1;
        if at > 0 && (b[at - 1].is_ascii_alphanumeric() || b[at - 1] == b'_') {
            continue;
        }
        let rest = &line[at + 1..];
        let digits: String = rest.chars().take_while(|c| c.is_ascii_digit()).collect();
        if digits.is_empty() || digits.trim_start_matches('0') != int.trim_start_matches('0') {
            continue;
        }
        if int == "0" && digits.chars().any(|c| c != '0') {
            continue;
        }
        let after = &rest[digits.len()..];
        match frac {
            Some(f) => {
                if after.starts_with('.') && after[1..].starts_with(f) {
                    let tail = &after[1 + f.len()..];
                    if !tail.starts_with(|c: char| c.is_ascii_digit()) {
                        return true;
                    }
                }
            }
            None => {
                // Not a decimal code (G2.1; G2.0 is G2) and not a longer word.
                let decimal = after.starts_with('.')
                    && after[1..].starts_with(|c: char| c.is_ascii_digit() && c != '0');
                let longer = after.starts_with(|c: char| c.is_ascii_alphanumeric() || c == '_');
                if !decimal && !longer {
                    return true;
                }
            }
        }
    }
    false
}

/// A link to the first line of the sources that uses `code`.
fn link(sources: &[(String, String)], code: &str) -> String {
    // A range such as M100–M199: the first code of it.
    let code = code.split('–').next().unwrap_or(code);
    for (file, text) in sources {
        for (n, line) in text.lines().enumerate() {
            // Not a comment of a test module: a program or an assertion.
            if file.ends_with(".rs") && line.trim_start().starts_with("//") {
                continue;
            }
            if uses(line, code) {
                return format!("[{file}:{}](../{file}#L{})", n + 1, n + 1);
            }
        }
    }
    "—".to_string()
}

fn extension_note(d: Dialect) -> &'static str {
    match d {
        Dialect::LinuxCnc => "LinuxCNC and Tormach (`.ngc`)",
        Dialect::Rockwell => "Rockwell 9/Series",
        Dialect::Sinumerik => "Siemens Sinumerik 840D (`.mpf`, `.spf`)",
        Dialect::Heidenhain => "Heidenhain TNC, ISO programs (`.i`)",
        Dialect::Fagor => "Fagor 8070 (`.pim`)",
    }
}

/// How a program of the dialect reaches the machine's inputs and outputs (issue 28), and
/// why: only what the dialect's manual text in Kerf's hands covers and maps onto Kerf's
/// I/O events is accepted; the rest is refused by name.
fn io_note(d: Dialect) -> &'static str {
    match d {
        Dialect::LinuxCnc => {
            "M62/M63 switch digital output P on/off with the start of the next move, M64/M65 \
             at once; M67/M68 set analog output E to Q with the next move / at once; M66 waits \
             on digital input P or analog input E (L0 immediate, L1 rise, L2 fall, L3 high, L4 \
             low, with the timeout Q in seconds; analog inputs L0 only). Input and output \
             numbers are whole numbers 0–63 (LinuxCNC's limit of 64 each); which exist is the \
             machine configuration's business. rs274's word checks and messages apply (\
             `No valid P word with M62`, `Zero timeout with wait type != immediate return`, \
             ...), and Kerf also refuses what rs274 passes on but no machine has: a fraction or \
             a negative output number, L above 4, M67/M68 without Q. `#5399` holds the result \
             of the last M66 (1/0, an analog value, -1 after a timeout): a line that reads it \
             waits for the machine's answer (LinuxCNC drains its lookahead there); `kerf plan` \
             and `kerf sim` answer from simulated inputs that are all off unless configured. \
             Details: [LINUXCNC.md](LINUXCNC.md)."
        }
        Dialect::Rockwell => {
            "None. The 9/Series manual text Kerf works from (its seed pages) describes no I/O \
             codes; M codes beyond the table above are the machine builder's (PAL) and are \
             refused as `unknown M code M62`."
        }
        Dialect::Sinumerik => {
            "None. The 840D programming manual text Kerf works from (its seed pages) does not \
             cover the I/O system variables (`$A_OUT[n]`, `$A_IN[n]`, ...), which also need \
             the assignments and expressions Kerf's Sinumerik dialect does not read yet: \
             `$A_OUT[1]=1` is `system variable $A_OUT is not supported yet`, and M codes \
             beyond the table (the machine builder's auxiliary functions) are `unknown M code`."
        }
        Dialect::Heidenhain => {
            "None. The TNC ISO manual text Kerf works from (its seed pages) describes no I/O; \
             M functions beyond the table are the machine builder's and are refused as \
             `unknown M code`."
        }
        Dialect::Fagor => {
            "None. The 8070 manual text Kerf works from (its seed pages) describes no I/O; \
             PLC variables and high-level instructions (`$`, `#`, `V.`) are refused as not \
             supported yet, and M functions beyond the table as `unknown M code`."
        }
    }
}

fn table(out: &mut String, title: &str, codes: &[CodeInfo], sources: &[(String, String)]) {
    let supported: Vec<&CodeInfo> = codes.iter().filter(|c| c.does.is_some()).collect();
    let refused: Vec<&CodeInfo> = codes.iter().filter(|c| c.does.is_none()).collect();
    let _ = writeln!(out, "### {title}\n");
    let _ = writeln!(out, "| code | what it does | used in |\n|---|---|---|");
    for c in supported {
        let _ = writeln!(
            out,
            "| {} | {} | {} |",
            c.code,
            c.does.unwrap_or(""),
            link(sources, &c.code)
        );
    }
    if !refused.is_empty() {
        let _ = writeln!(
            out,
            "\nRefused (the block is not run; the error is `FILE:LINE:COL: error: …` with this text):\n"
        );
        let _ = writeln!(out, "| code | error | tested in |\n|---|---|---|");
        for c in refused {
            let _ = writeln!(
                out,
                "| {} | {} | {} |",
                c.code,
                c.error.as_deref().unwrap_or(""),
                link(sources, &c.code)
            );
        }
    }
    out.push('\n');
}

fn generate() -> String {
    let mut out = String::from(
        "# G and M codes by dialect\n\n\
         Every G and M code each dialect accepts, with what it does and a test or test \
         program that uses it, and the codes it knows but refuses, with the error. A code not \
         listed is refused as `unknown G code` or `unknown M code`. Generated from the \
         interpreter's own tables by `tests/gcode/reference.rs`, which fails when this page \
         and the code differ (`KERF_BLESS=1 cargo test -p kerf-tests reference` rewrites \
         it). LinuxCNC's whole language (parameters, expressions, O-words, canned cycles, \
         cutter compensation) is described in [LINUXCNC.md](LINUXCNC.md). A `—` in the \
         test column: no test program uses the code yet; that page's own test \
         (`every_listed_code_behaves_as_listed`) still checks that it is accepted, or \
         refused with the listed error.\n\n",
    );
    for d in Dialect::ALL {
        let sources = sources(d);
        let _ = writeln!(out, "## {} (`--dialect {}`)\n", extension_note(d), d.name());
        table(&mut out, "G codes", &code_reference(d, true), &sources);
        table(&mut out, "M codes", &code_reference(d, false), &sources);
        let _ = writeln!(
            out,
            "### Other words\n\nAccepted addresses besides G, M and N: {}.\n",
            word_addresses(d)
                .iter()
                .map(|w| format!("`{w}`"))
                .collect::<Vec<_>>()
                .join(", ")
        );
        let _ = writeln!(out, "### Machine I/O\n\n{}\n", io_note(d));
    }
    out
}

#[test]
fn dialects_md_is_generated_from_the_code() {
    let path = root().join("docs/DIALECTS.md");
    let text = generate();
    if std::env::var_os("KERF_BLESS").is_some() {
        std::fs::write(&path, &text).expect("docs/DIALECTS.md is writable");
    }
    let on_disk = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        on_disk == text,
        "docs/DIALECTS.md differs from the code's tables; rerun with KERF_BLESS=1 and review the diff"
    );
}

/// A supported G code is known to the interpreter (not refused as unknown or
/// unsupported), and a refused one gives exactly the listed error.
#[test]
fn every_listed_code_behaves_as_listed() {
    for d in Dialect::ALL {
        for g in [true, false] {
            for c in code_reference(d, g) {
                let code = c.code.split('–').next().unwrap().to_string();
                let text = format!("{code}\n");
                let first = Interpreter::new(text.as_bytes(), d, Settings::default())
                    .find_map(|item| item.err());
                let message = first.map(|e| e.message).unwrap_or_default();
                match &c.error {
                    Some(err) => assert!(message.contains(err.as_str()), "{d:?} {code}: {message}"),
                    None => assert!(
                        !message.contains("unknown") && !message.contains("not supported"),
                        "{d:?} {code} is listed as supported: {message}"
                    ),
                }
            }
        }
    }
}

#[test]
fn uses_matches_whole_codes_only() {
    assert!(uses("G2 X1", "G2"));
    assert!(uses("N10 G02 X1", "G2"));
    assert!(!uses("G20", "G2"));
    assert!(!uses("G2.1", "G2"));
    assert!(uses("G59.1", "G59.1"));
    assert!(!uses("G59.12", "G59.1"));
    assert!(!uses("M30", "M3"));
    assert!(uses("m3 s1000", "M3"));
    assert!(!uses("LOG2", "G2"));
    assert!(uses("G0 X0", "G0"));
    assert!(uses("G00 X0", "G0"));
    assert!(!uses("G01", "G0"));
}
