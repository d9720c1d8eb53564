//! `rs274-diff`: the live comparison of Kerf's LinuxCNC dialect with LinuxCNC's own
//! interpreter rs274 (unpacked by `tests/rs274/fetch.sh`).
//!
//! ```text
//! rs274-diff --rs274-dir DIR [--check-goldens tests/data/ngc] [--ncfiles DIR] [--tool-table FILE]
//! ```
//!
//! - `--check-goldens D`: runs rs274 again on every golden program under D and fails when a
//!   committed `NAME.canon` (or `NAME.err`) differs from what rs274 prints now, so goldens
//!   cannot drift; then compares each with Kerf as the test does.
//! - `--ncfiles D` (default with no other mode: DIR's `nc_files` examples): every `*.ngc`
//!   under D, recursively. If rs274 accepts a program, Kerf must resolve it to the same
//!   motion or refuse it with an out-of-scope error (issue 9's list); anything else fails.
//!   The tool table is `--tool-table FILE` (LinuxCNC format, inches, as LinuxCNC's sim
//!   configurations ship it), by default the package's `sample-configs/common/tool.tbl`.
//!
//! Prints a table and a summary; exits 1 on any mismatch, in-scope refusal or drift.

use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};

use kerf_tests::rs274::{
    Golden, Refusal, Verdict, check_golden, compare, goldens, ngc_files, parse_tool_table, run_kerf,
};

struct Rs274Out {
    exit: i32,
    stdout: String,
    stderr: String,
}

fn canon_sh() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("rs274/canon.sh")
}

fn run_rs274(
    rs274_dir: &Path,
    program: &Path,
    tbl_mm: Option<&Path>,
    var_mm: Option<&Path>,
) -> Result<Rs274Out, String> {
    let mut cmd = Command::new("bash");
    cmd.arg(canon_sh()).arg(program);
    match tbl_mm {
        Some(t) => cmd.arg(t),
        None => cmd.arg("-"),
    };
    if let Some(v) = var_mm {
        cmd.arg(v);
    }
    cmd.env("KERF_RS274_DIR", rs274_dir);
    let out = cmd
        .output()
        .map_err(|e| format!("cannot run {}: {e}", canon_sh().display()))?;
    let exit = out.status.code().unwrap_or(-1);
    if exit == 3 {
        return Err(String::from_utf8_lossy(&out.stderr).into_owned());
    }
    Ok(Rs274Out {
        exit,
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
    })
}

fn abs(p: &Path) -> PathBuf {
    std::fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf())
}

fn check_goldens(rs274_dir: &Path, dir: &Path) -> Result<bool, String> {
    let all: Vec<Golden> = goldens(dir)?;
    let mut ok = true;
    println!("== goldens under {}: {} programs", dir.display(), all.len());
    for g in &all {
        let name = g
            .ngc
            .strip_prefix(dir)
            .unwrap_or(&g.ngc)
            .display()
            .to_string();
        let out = run_rs274(
            rs274_dir,
            &abs(&g.ngc),
            g.tbl.as_deref().map(abs).as_deref(),
            g.var.as_deref().map(abs).as_deref(),
        )?;
        let committed = std::fs::read_to_string(&g.canon).unwrap_or_default();
        let mut drift = Vec::new();
        if committed != out.stdout {
            drift.push(".canon differs from rs274's output");
        }
        let err_now = (out.exit != 0).then(|| Refusal::err_file(out.exit, &out.stderr));
        let err_committed = g.err.as_ref().and_then(|p| std::fs::read_to_string(p).ok());
        if err_now != err_committed {
            drift.push(".err differs from rs274's exit status and standard error");
        }
        let verdict = check_golden(g)?;
        let result = if !drift.is_empty() {
            ok = false;
            format!(
                "DRIFT: {} (regenerate with tests/rs274/golden.sh)",
                drift.join("; ")
            )
        } else if verdict.golden_ok() {
            describe(&verdict)
        } else {
            ok = false;
            format!("FAIL: {}", describe(&verdict))
        };
        println!("{name:<50} {result}");
    }
    Ok(ok)
}

fn describe(v: &Verdict) -> String {
    match v {
        Verdict::Same { moves, events } => format!("same ({moves} moves, {events} events)"),
        Verdict::BothRefuse { line, message } => {
            format!("both refuse (line {line}: {message})")
        }
        Verdict::OutOfScope { construct, diag } => format!("out of scope ({construct}): {diag}"),
        Verdict::Rs274Refuses { rs274, kerf } => format!("rs274 refuses ({rs274}); Kerf {kerf}"),
        Verdict::KerfRefuses { diag } => format!("Kerf refuses: {diag}"),
        Verdict::Mismatch(why) => format!("mismatch: {why}"),
    }
}

/// The default tool table of the nc_files run: the sim configurations' common table.
fn default_tool_table(rs274_dir: &Path) -> PathBuf {
    rs274_dir.join("root/usr/share/doc/linuxcnc/examples/sample-configs/common/tool.tbl")
}

/// A LinuxCNC tool table in inches rewritten in mm (X Y Z U V W D are lengths).
fn table_inch_to_mm(text: &str) -> String {
    let mut out = String::new();
    for line in text.lines() {
        let code = line.split(';').next().unwrap_or("");
        let words: Vec<String> = code
            .split_whitespace()
            .map(|w| {
                let (l, v) = w.split_at(1);
                match (l.to_ascii_uppercase().as_str(), v.parse::<f64>()) {
                    ("X" | "Y" | "Z" | "U" | "V" | "W" | "D", Ok(x)) => format!("{l}{}", x * 25.4),
                    _ => w.to_string(),
                }
            })
            .collect();
        out.push_str(&words.join(" "));
        out.push('\n');
    }
    out
}

fn ncfiles(rs274_dir: &Path, dir: &Path, tool_table: &Path) -> Result<bool, String> {
    let inch = std::fs::read_to_string(tool_table)
        .map_err(|e| format!("{}: {e}", tool_table.display()))?;
    let mm = table_inch_to_mm(&inch);
    let tools = parse_tool_table(&mm)?;
    let tbl_mm = std::env::temp_dir().join(format!("rs274-diff-{}.tbl", std::process::id()));
    std::fs::write(&tbl_mm, &mm).map_err(|e| format!("{}: {e}", tbl_mm.display()))?;
    let files = ngc_files(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    println!(
        "== nc_files under {}: {} programs (tool table {})",
        dir.display(),
        files.len(),
        tool_table.display()
    );
    let (mut same, mut oos, mut mismatch, mut kerf_refuses, mut refused) = (0, 0, 0, 0, 0);
    for ngc in &files {
        let name = ngc.strip_prefix(dir).unwrap_or(ngc).display().to_string();
        let program = abs(ngc);
        let out = run_rs274(rs274_dir, &program, Some(&tbl_mm), None)?;
        let src = std::fs::read(&program).map_err(|e| format!("{}: {e}", program.display()))?;
        let kerf = run_kerf(&src, tools.clone(), &program);
        let refusal = (out.exit != 0).then(|| Refusal::from_stderr(out.exit, &out.stderr));
        let verdict = compare(&src, &kerf, &out.stdout, refusal.as_ref());
        let (result, detail) = match &verdict {
            Verdict::Same { .. } => {
                same += 1;
                ("same", describe(&verdict))
            }
            Verdict::OutOfScope { construct, diag } => {
                oos += 1;
                ("out of scope", format!("{construct}: {diag}"))
            }
            Verdict::BothRefuse { .. } | Verdict::Rs274Refuses { .. } => {
                refused += 1;
                ("rs274 refuses", describe(&verdict))
            }
            Verdict::KerfRefuses { diag } => {
                kerf_refuses += 1;
                ("KERF REFUSES", diag.clone())
            }
            Verdict::Mismatch(why) => {
                mismatch += 1;
                ("MISMATCH", why.replace('\n', "\n        "))
            }
        };
        println!("{name:<58} {result:<14} {detail}");
    }
    let _ = std::fs::remove_file(&tbl_mm);
    println!(
        "== {} programs: {same} same, {oos} out of scope, {mismatch} mismatch, {kerf_refuses} refused by Kerf in scope, {refused} refused by rs274",
        files.len()
    );
    Ok(mismatch == 0 && kerf_refuses == 0)
}

fn usage() -> ExitCode {
    eprintln!(
        "usage: rs274-diff --rs274-dir DIR [--check-goldens DIR] [--ncfiles DIR] [--tool-table FILE]"
    );
    ExitCode::from(2)
}

fn main() -> ExitCode {
    let mut rs274_dir = std::env::var_os("KERF_RS274_DIR").map(PathBuf::from);
    let mut golden_dir = None;
    let mut nc_dir = None;
    let mut tool_table = None;
    let mut args = std::env::args_os().skip(1);
    while let Some(a) = args.next() {
        let mut value = || args.next().map(PathBuf::from);
        match a.to_str() {
            Some("--rs274-dir") => rs274_dir = value(),
            Some("--check-goldens") => golden_dir = value(),
            Some("--ncfiles") => nc_dir = value(),
            Some("--tool-table") => tool_table = value(),
            _ => return usage(),
        }
    }
    let Some(rs274_dir) = rs274_dir.map(|d| abs(&d)) else {
        return usage();
    };
    if golden_dir.is_none() && nc_dir.is_none() {
        nc_dir = Some(rs274_dir.join("root/usr/share/doc/linuxcnc/examples/nc_files"));
    }
    let mut ok = true;
    if let Some(d) = &golden_dir {
        match check_goldens(&rs274_dir, d) {
            Ok(good) => ok &= good,
            Err(e) => {
                eprintln!("rs274-diff: {e}");
                return ExitCode::from(2);
            }
        }
    }
    if let Some(d) = &nc_dir {
        let table = tool_table.unwrap_or_else(|| default_tool_table(&rs274_dir));
        match ncfiles(&rs274_dir, d, &table) {
            Ok(good) => ok &= good,
            Err(e) => {
                eprintln!("rs274-diff: {e}");
                return ExitCode::from(2);
            }
        }
    }
    if ok {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    }
}
