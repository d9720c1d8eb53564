//! The LinuxCNC language: parameters, expressions, messages and O-word control flow.
//!
//! Every expected value comes from LinuxCNC's own interpreter (`rs274`, run with
//! `tests/rs274/canon.sh` on the same program) or from the LinuxCNC manual; the comment at
//! each test names the canonical calls it reproduces.

use kerf_tests::*;

const L: Dialect = Dialect::LinuxCnc;

/// The end points (program mm) of the moves of a program.
fn ends(src: &str) -> Vec<[f64; 3]> {
    moves(L, src)
        .iter()
        .map(|m| {
            let e = match m.path {
                Path::Line(l) => l.end,
                Path::Arc(a) => a.end,
            };
            [e[0], e[1], e[2]]
        })
        .collect()
}

fn assert_ends(src: &str, want: &[[f64; 3]]) {
    let got = ends(src);
    assert_eq!(got.len(), want.len(), "move count of\n{src}\ngot {got:?}");
    for (g, w) in got.iter().zip(want) {
        for k in 0..3 {
            assert!(
                (g[k] - w[k]).abs() < 1e-9,
                "program\n{src}\ngot {got:?}\nwant {want:?}"
            );
        }
    }
}

fn texts(src: &str) -> Vec<(EventCode, String)> {
    items(L, src)
        .into_iter()
        .filter_map(|i| match i {
            Item::Event(e) => e.text.map(|t| (e.code, t.to_string())),
            Item::Move(_) => None,
        })
        .collect()
}

#[test]
fn assignments_take_effect_after_the_line_is_read() {
    // rs274: STRAIGHT_FEED(5, 1, 0) then STRAIGHT_FEED(0, 1, 0): `#2=[#1+1]` reads #1
    // before `#1=5` of the same line takes effect, and so does `X#3`.
    assert_ends(
        "#1=5 #2=[#1+1]\nG21 G90 F100\nG1 X#1 Y#2\n#3=1 #3=2 G1 X#3\nG1 Y#3\nM2\n",
        &[[5.0, 1.0, 0.0], [0.0, 1.0, 0.0], [0.0, 2.0, 0.0]],
    );
}

#[test]
fn operators_and_precedence() {
    // rs274: X8 Y1 Z2 / X19 Y0 Z2 / X1 (comparison then AND).
    assert_ends(
        "F1\nG1 X[2**3] Y[7 MOD 3] Z[-7 MOD 3]\nG1 X[1+2*3**2] Y[2-1-1] Z[8/2/2]\nG1 X[1 LT 2 AND 3]\nM2\n",
        &[[8.0, 1.0, 2.0], [19.0, 0.0, 2.0], [1.0, 0.0, 2.0]],
    );
}

#[test]
fn functions() {
    // rs274: ATAN[1]/[1] = 45, FIX[-2.5] = -3, FUP[-2.5] = -2, ROUND[2.5] = 3,
    // ROUND[-2.5] = -3, EXISTS 1 and 0.
    assert_ends(
        "F1\nG1 X[ATAN[1]/[1]] Y[FIX[-2.5]] Z[FUP[-2.5]]\nG1 X[ROUND[2.5]] Y[ROUND[-2.5]] Z[1 EQ 1]\n#<foo>=3\nG1 X[EXISTS[#<foo>]] Y[EXISTS[#<bar>]] Z[SQRT[16]+ABS[-1]]\nG1 X[SIN[30]*2] Y[COS[60]*4] Z[ACOS[0]]\nM2\n",
        &[
            [45.0, -3.0, -2.0],
            [3.0, -3.0, 1.0],
            [1.0, 0.0, 5.0],
            [1.0, 2.0, 90.0],
        ],
    );
}

#[test]
fn unary_minus_and_plus_before_values() {
    // rs274: X-[1], X[-[1]] = -1; X[+1], X[--1] = 1.
    assert_ends(
        "F1\nG1 X-[1]\nG1 X[+1]\nG1 X[-[1]]\nG1 X[--1]\nM2\n",
        &[
            [-1.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [-1.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
        ],
    );
}

#[test]
fn named_parameters_ignore_case_and_spaces() {
    // rs274: STRAIGHT_FEED(3.5, ...) from `#<foo>=3.5` read as `#<f o o>`.
    assert_ends("F1\n#<Foo>=3.5\nG1 X#<f o o>\nM2\n", &[[3.5, 0.0, 0.0]]);
}

#[test]
fn indirect_parameters_and_expression_codes() {
    // `##1` is the parameter whose number #1 holds; `G[1]` is G1 (rs274 accepts both).
    assert_ends("F1\n#1=7\n#7=2.5\nG[0+1] X##1\nM2\n", &[[2.5, 0.0, 0.0]]);
}

#[test]
fn current_position_parameters() {
    // rs274: after G1 X19, `Y#5420` is Y19; #<_x> is the same value.
    assert_ends(
        "F1\nG1 X19\nG1 Y#5420 Z#<_x>\nM2\n",
        &[[19.0, 0.0, 0.0], [19.0, 19.0, 19.0]],
    );
}

#[test]
fn messages_as_events() {
    // rs274: MESSAGE(" hello world"), MESSAGE(" x is 5.000000 and ###### and [1+2]"),
    // and PRINT writes "val=5.000000".
    let got = texts(
        "#1=5\n(MSG, hello world)\n(debug, x is #1 and #<nope> and [1+2])\n(PRINT,val=#1)\n( Msg,b)\n(msg ,c)\nM2\n",
    );
    assert_eq!(
        got,
        vec![
            (EventCode::Msg, " hello world".to_string()),
            (
                EventCode::Debug,
                " x is 5.000000 and ###### and [1+2]".to_string()
            ),
            (EventCode::Print, "val=5.000000".to_string()),
            (EventCode::Msg, "b".to_string()),
        ]
    );
}

#[test]
fn subroutine_with_arguments_and_return_value() {
    // rs274: STRAIGHT_FEED(3, 4, 0), then Z6 (#<_value>), then Z2 (#<_value_returned>+1).
    assert_ends(
        "F1\no<s> sub\nG1 X#1 Y#2\no<s> endsub [#1*2]\no<s> call [3] [4]\nG1 Z#<_value>\nG1 Z[#<_value_returned>+1]\nM2\n",
        &[[3.0, 4.0, 0.0], [3.0, 4.0, 6.0], [3.0, 4.0, 2.0]],
    );
}

#[test]
fn numbered_locals_are_restored_after_a_call() {
    // rs274: X5 in the sub (argument), then Z1: #1 is 1 again after the call.
    assert_ends(
        "#1=1\no1 sub\nG0 X#1 Y#2\n#1=9\no1 endsub\no1 call [5]\nG0 Z#1\nM2\n",
        &[[5.0, 0.0, 0.0], [5.0, 0.0, 1.0]],
    );
}

#[test]
fn repeat_do_while_and_while_with_break_and_continue() {
    // rs274: X8, X9, X10.
    assert_ends(
        "F1\n#1=7\no1 repeat [3]\n#1=[#1+1]\nG1 X#1\no1 endrepeat\nM2\n",
        &[[8.0, 0.0, 0.0], [9.0, 0.0, 0.0], [10.0, 0.0, 0.0]],
    );
    // rs274: X1, X2, X3.
    assert_ends(
        "F1\n#1=0\no1 do\n#1=[#1+1]\nG1 X#1\no1 while [#1 LT 3]\nM2\n",
        &[[1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [3.0, 0.0, 0.0]],
    );
    // rs274: (0,1), (1,1), (1,3), (3,3).
    assert_ends(
        "F1\n#1=0\no1 while [1]\n#1=[#1+1]\no2 if [#1 EQ 2]\no1 continue\no2 elseif [#1 EQ 4]\no1 break\no2 else\nG1 Y#1\no2 endif\nG1 X#1\no1 endwhile\nM2\n",
        &[
            [0.0, 1.0, 0.0],
            [1.0, 1.0, 0.0],
            [1.0, 3.0, 0.0],
            [3.0, 3.0, 0.0],
        ],
    );
    // rs274: STRAIGHT_FEED(100000, 0, 0) after 100000 iterations.
    assert_ends(
        "F1\n#1=0\no1 while [#1 lt 100000]\n#1=[#1+1]\no1 endwhile\nG1 X#1\nM2\n",
        &[[100000.0, 0.0, 0.0]],
    );
}

#[test]
fn if_else() {
    // rs274: STRAIGHT_TRAVERSE(1, 0, 0) only.
    assert_ends(
        "o1 if [1]\nG0 X1\no1 else\nG0 X2\no1 endif\no2 if [0]\nG0 Y5\no2 endif\nM2\n",
        &[[1.0, 0.0, 0.0]],
    );
}

#[test]
fn endless_loop_is_bounded() {
    let settings = Settings {
        max_loop_iterations: 1000,
        ..Settings::default()
    };
    let d = error_with(L, settings, "F1\no1 while [1]\no1 endwhile\nM2\n");
    assert_diag(&d, 3, 1, &["o1", "max_loop_iterations"]);
}

#[test]
fn errors_in_linuxcnc_words() {
    // Each message is rs274's for the same line.
    for (src, line, col, msg) in [
        (
            "G1 X#<nope> F1\n",
            1,
            5,
            "Named parameter #<nope> not defined",
        ),
        ("G1 X#6000 F1\n", 1, 5, "Parameter number out of range"),
        ("#0=1\n", 1, 1, "Parameter number out of range"),
        ("G1 X#0 F1\n", 1, 5, "Parameter number out of range"),
        ("G1 X#1.5 F1\n", 1, 5, "Non integer value for integer"),
        ("G1 X[1/0] F1\n", 1, 7, "Attempt to divide by zero"),
        ("G1 X[1 FOO 2] F1\n", 1, 8, "Unknown operation"),
        ("G1 X[SQRT[-1]] F1\n", 1, 6, "Negative argument to sqrt"),
        ("G1 X[LN[0]] F1\n", 1, 6, "Zero or negative argument to ln"),
        ("G1 X[ACOS[2]] F1\n", 1, 6, "Argument to acos out of range"),
        ("G1 X[1+2 F1\n", 1, 10, "Unknown operation"),
        (
            "G1 X[[-2]**0.5] F1\n",
            1,
            10,
            "Attempt to raise negative to non integer power",
        ),
        (
            "o<s> sub\n#<_x>=1\no<s> endsub\no<s> call\n",
            2,
            1,
            "Cannot assign to read-only parameter #<_x>",
        ),
        (
            "#<a>=1\no<s> sub\nG0 X#<a>\no<s> endsub\no<s> call\n",
            3,
            5,
            "Named parameter #<a> not defined",
        ),
        (
            "o<r> sub\no<r> call\no<r> endsub\no<r> call\n",
            2,
            1,
            "Too many subroutine levels",
        ),
    ] {
        let d = error(L, src);
        assert_diag(&d, line, col, &[msg]);
    }
}

#[test]
fn words_after_an_o_word_are_an_error() {
    // rs274: "Unexpected character after O-word" (an O-word line runs nothing else).
    for (src, col) in [
        ("o1 if [1] G0 X5\no1 endif\n", 11),
        ("o1 repeat [2]\no1 endrepeat X1\n", 14),
        ("o1 sub\no1 endsub\no1 call [1] [2] G1\n", 17),
    ] {
        let d = error(L, src);
        assert_eq!(d.message, "Unexpected character after O-word", "{src}");
        assert_eq!(d.col, col, "{src}");
    }
    // Comments may follow.
    assert_ends(
        "o1 if [1] (yes)\nG0 X5\no1 endif (done)\n",
        &[[5.0, 0.0, 0.0]],
    );
}

#[test]
fn nothing_after_a_failing_block() {
    let out = run_bytes(L, Settings::default(), b"F1\nG1 X1\nG1 X[1/0]\nG1 X3\n");
    assert_eq!(out.items.len(), 1);
    assert!(out.error.is_some());
}

#[test]
fn subroutine_files_on_the_search_path() {
    let dir = std::env::temp_dir().join(format!("kerf-lang-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(
        dir.join("square.ngc"),
        "(a square of side #1)\no<square> sub\nG1 X#1\nG1 Y#1\nG1 X0\nG1 Y[1/#2]\no<square> endsub\nM2\n",
    )
    .unwrap();
    let settings = Settings {
        subroutine_path: vec![dir.clone()],
        ..Settings::default()
    };
    let ms = moves_with(L, settings.clone(), "F1\no<square> call [4] [1]\nM2\n");
    assert_eq!(ms.len(), 4);
    // A division by zero inside the file names the file and line, then the calling line.
    let d = error_with(L, settings, "F1\n\no<square> call [4] [0]\nM2\n");
    assert_eq!(d.line, 6);
    assert!(
        d.file.as_deref().is_some_and(|f| f.ends_with("square.ngc")),
        "{d:?}"
    );
    assert_eq!(d.called_from, vec![(None, 3)]);
    assert!(
        d.render("prog.ngc")
            .contains("prog.ngc:3: note: called from here")
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// LinuxCNC's log calls are LOG events holding the call; the texts are those of rs274's
/// calls for the same comments (`LOGOPEN("out#1.txt")`, `LOG("v=5.000000")`,
/// `LOGAPPEND(" b.txt ")`, `LOGCLOSE()`; `(LOGCLOSE,x)` and `(logclose )` are comments).
#[test]
fn log_comments_are_events() {
    let items = run(
        L,
        "#1=5\n(LOGOPEN,out#1.txt)\n(LOG,v=#1)\n( LOGCLOSE)\n(logappend, b.txt )\n(LOGCLOSE,x)\n(logclose )\n(LogClose)\nM2\n",
    )
    .unwrap();
    let logs: Vec<(u32, String)> = items
        .iter()
        .filter_map(|i| match i {
            Item::Event(e) if e.code == EventCode::Log => {
                Some((e.line, e.text.as_deref().unwrap_or("").to_string()))
            }
            _ => None,
        })
        .collect();
    assert_eq!(
        logs,
        vec![
            (2, "LOGOPEN,out#1.txt".to_string()),
            (3, "LOG,v=5.000000".to_string()),
            (4, "LOGCLOSE".to_string()),
            (5, "LOGAPPEND, b.txt ".to_string()),
            (8, "LOGCLOSE".to_string()),
        ]
    );
}

/// The end points of the motion calls of an rs274 canon file, in mm, without the
/// zero-length lines that rs274 prints and Kerf does not emit (positions are program
/// coordinates; the lang programs set no offsets, so they are machine coordinates too).
fn canon_ends(canon: &str) -> Vec<[f64; 3]> {
    let mut scale = 1.0;
    let mut out: Vec<[f64; 3]> = Vec::new();
    for line in canon.lines() {
        if line.contains("USE_LENGTH_UNITS(CANON_UNITS_INCHES)") {
            scale = INCH_MM;
        } else if line.contains("USE_LENGTH_UNITS(CANON_UNITS_MM)") {
            scale = 1.0;
        }
        for call in ["STRAIGHT_FEED(", "STRAIGHT_TRAVERSE(", "ARC_FEED("] {
            let Some(i) = line.find(call) else { continue };
            let args: Vec<f64> = line[i + call.len()..]
                .trim_end_matches(')')
                .split(',')
                .map(|a| a.trim().parse().unwrap())
                .collect();
            let end = if call == "ARC_FEED(" {
                [args[0] * scale, args[1] * scale, args[5] * scale]
            } else {
                [args[0] * scale, args[1] * scale, args[2] * scale]
            };
            let prev = out.last().copied().unwrap_or([0.0; 3]);
            if call != "ARC_FEED(" && (0..3).all(|k| (end[k] - prev[k]).abs() < 1e-9) {
                continue;
            }
            out.push(end);
        }
    }
    out
}

#[test]
fn golden_programs_match_rs274() {
    // Every tests/data/ngc/lang program moves to rs274's end points (printed with four
    // decimals, so within 0.0001 program units), with the same number of moves.
    let dir = data_dir().join("ngc/lang");
    let mut files = files_with_ext(&dir, "ngc");
    files.extend(files_with_ext(&dir.join("subfiles"), "ngc"));
    assert!(files.len() >= 9, "{files:?}");
    for path in files {
        let canon = std::fs::read_to_string(path.with_extension("canon")).unwrap();
        let src = std::fs::read(&path).unwrap();
        let settings = Settings {
            subroutine_path: vec![path.parent().unwrap().to_path_buf()],
            program_file: Some(path.clone()),
            ..Settings::default()
        };
        // Loops yield more items than the program has bytes: collect without the
        // item bound of `run_bytes` (the loops are bounded by max_loop_iterations).
        let all: Vec<Item> = Interpreter::new(&src[..], L, settings)
            .collect::<Result<_, _>>()
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let got: Vec<[f64; 3]> = all
            .iter()
            .filter_map(|i| match i {
                Item::Move(m) => Some(match m.path {
                    Path::Line(l) => [l.end[0], l.end[1], l.end[2]],
                    Path::Arc(a) => [a.end[0], a.end[1], a.end[2]],
                }),
                Item::Event(_) => None,
            })
            .collect();
        // MSG and DEBUG are rs274's MESSAGE calls, with the same text.
        let messages: Vec<String> = canon
            .lines()
            .filter_map(|l| {
                l.split_once("MESSAGE(\"")
                    .map(|(_, t)| t.trim_end_matches("\")").to_string())
            })
            .collect();
        let texts: Vec<String> = all
            .iter()
            .cloned()
            .filter_map(|i| match i {
                Item::Event(e) if matches!(e.code, EventCode::Msg | EventCode::Debug) => {
                    e.text.map(|t| t.to_string())
                }
                _ => None,
            })
            .collect();
        assert_eq!(texts, messages, "{}", path.display());
        let want = canon_ends(&canon);
        assert_eq!(got.len(), want.len(), "{}", path.display());
        for (i, (g, w)) in got.iter().zip(&want).enumerate() {
            for k in 0..3 {
                assert!(
                    (g[k] - w[k]).abs() <= 0.0001 * INCH_MM,
                    "{} move {i}: got {g:?}, rs274 {w:?}",
                    path.display()
                );
            }
        }
    }
}

#[test]
fn a_sub_defined_after_m2_is_found_in_the_program_file() {
    // rs274 seeks forward for a sub it has not seen: TRAVERSE to X2, then Y1, then the end.
    // Reaching the definition of such a sub before M2 is its error "found in illegal
    // location" (rs274: "sub: o|100| found in illegal location").
    let dir = std::env::temp_dir().join(format!("kerf-lang-fw-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let after_m2 = dir.join("after_m2.ngc");
    let src = "o100 call [2]\nG0 Y1\nM2\no100 sub\nG0 X#1\no100 endsub\n";
    std::fs::write(&after_m2, src).unwrap();
    let settings = Settings {
        program_file: Some(after_m2.clone()),
        ..Settings::default()
    };
    let ms = moves_with(L, settings, src);
    let ends: Vec<Vec3> = ms.iter().map(|m| as_line(m).end).collect();
    assert_eq!(ends, vec![v(2.0, 0.0, 0.0), v(2.0, 1.0, 0.0)]);

    let before_m2 = dir.join("before_m2.ngc");
    let src = "o100 call [2]\nG0 Y1\no100 sub\nG0 X#1\no100 endsub\nM2\n";
    std::fs::write(&before_m2, src).unwrap();
    let settings = Settings {
        program_file: Some(before_m2.clone()),
        ..Settings::default()
    };
    let d = error_with(L, settings, src);
    assert_diag(&d, 3, 1, &["o100 found in illegal location"]);
    // Without the file (standard input) the sub cannot be found.
    let d = error(L, "o100 call [2]\nM2\no100 sub\no100 endsub\n");
    assert_diag(&d, 1, 1, &["o100 called but not defined"]);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn nine_nested_calls_at_most() {
    // rs274 prints "level 1.000000" … "level 9.000000", then "Too many subroutine levels"
    // at the call on line 3.
    let out = run_bytes(
        L,
        Settings::default(),
        b"o<r> sub\n(debug,level #<_call_level>)\no<r> call\no<r> endsub\no<r> call\nM2\n",
    );
    let levels: Vec<String> = out
        .items
        .iter()
        .filter_map(|i| match i {
            Item::Event(e) => e.text.as_deref().map(str::to_string),
            Item::Move(_) => None,
        })
        .collect();
    let want: Vec<String> = (1..=9).map(|n| format!("level {n}.000000")).collect();
    assert_eq!(levels, want);
    let d = out.error.expect("an error");
    assert_diag(&d, 3, 1, &["Too many subroutine levels"]);
    assert_eq!(d.called_from.len(), 9);
}

#[test]
fn rs274_corner_cases() {
    // rs274: `#<a>=1 #<a>=[#<a>+1]` reads #<a> (never set) as 0 because the line assigns
    // it; X#<a> then reads the old value too: a zero-length move at X0 is all rs274 prints,
    // so the next move starts from X0 and #<a> ends at 1.
    assert_ends(
        "#<a>=1 #<a>=[#<a>+1] G1 X#<a> F1\nG1 X[#<a>+2]\nM2\n",
        &[[3.0, 0.0, 0.0]],
    );
    // rs274: `repeat [2.7]` runs 3 times, `repeat [2.4]` twice.
    assert_ends(
        "o1 repeat [2.7]\nG91 G0 X1\no1 endrepeat\no2 repeat [2.4]\nG91 G0 Y1\no2 endrepeat\nM2\n",
        &[
            [1.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [3.0, 0.0, 0.0],
            [3.0, 1.0, 0.0],
            [3.0, 2.0, 0.0],
        ],
    );
    // rs274: "Parameter is readonly" for #5400-#5428, not for #5399 or #5429.
    for n in [5400, 5401, 5410, 5420, 5428] {
        let d = error(L, &format!("#{n}=1\n"));
        assert_diag(&d, 1, 1, &["Parameter is readonly"]);
    }
    assert_ends(
        "#5399=1 #5429=2\nG0 X#5399 Y#5429\nM2\n",
        &[[1.0, 2.0, 0.0]],
    );
}

#[test]
fn rs274_calls_and_definitions() {
    // rs274: a parameter without an argument reads 0 in the sub (`o1 call [1]` with
    // #2=7 before: the move is to X0 Y1), and #2 is restored after the call.
    assert_ends(
        "#2=7\no1 sub\nG0 X#2 Y#1\no1 endsub\no1 call [1]\nG0 X#2\nM2\n",
        &[[0.0, 1.0, 0.0], [7.0, 1.0, 0.0]],
    );
    // rs274: "Nested subroutine definition".
    let d = error(
        L,
        "o1 sub\no2 sub\nG0 X2\no2 endsub\no1 endsub\no1 call\no2 call\nM2\n",
    );
    assert_diag(&d, 2, 1, &["Nested subroutine definition"]);
    // rs274: EXISTS[#1] is 1.
    assert_ends(
        "G0 X[EXISTS[#<_a>]] Y[EXISTS[#1]]\nM2\n",
        &[[1.0, 1.0, 0.0]],
    );
}
