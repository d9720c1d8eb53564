//! The plain-move fast path (`interp::plain`) against the general path: every LinuxCNC
//! program of the test data, hand-written edge cases and generated programs give the same
//! items, the same diagnostics and the same state at the end both ways, as programs and
//! line by line in MDI (where a refused line leaves the changes before its error).

use std::path::{Path, PathBuf};

use crate::interp::GENERAL_PATH_ONLY;
use crate::{Dialect, Interpreter, Settings, Tool};

fn settings(mdi: bool, dir: Option<&Path>) -> Settings {
    let tool = |number, length_mm, radius_mm| Tool {
        number,
        length_mm,
        radius_mm,
        pocket: number,
        ..Tool::default()
    };
    Settings {
        tools: vec![tool(1, 0.0, 5.0), tool(2, 12.5, 2.0), tool(3, -3.0, 12.7)],
        mdi,
        program_file: dir.map(|d| d.join("program.ngc")),
        ..Settings::default()
    }
}

/// Everything a run shows: each item or error (Debug text, so that NaN equals NaN), and
/// the state at the end.
fn run(src: &[u8], mdi: bool, dir: Option<&Path>, general_only: bool) -> Vec<String> {
    GENERAL_PATH_ONLY.with(|g| g.set(general_only));
    let mut interp = Interpreter::with_program_dir(src, Dialect::LinuxCnc, settings(mdi, dir), dir);
    let mut seen = Vec::new();
    // MDI goes on after an error; a program ends at its first.
    for _ in 0..100_000 {
        let Some(r) = interp.next() else { break };
        seen.push(format!("{r:?}"));
    }
    seen.push(format!(
        "end {:?} {:?} {:?} {:?}",
        interp.program_position(),
        interp.coordinate_system(),
        interp.ended(),
        interp.persistent_parameters()
    ));
    GENERAL_PATH_ONLY.with(|g| g.set(false));
    seen
}

fn same_both_ways(name: &str, src: &[u8], dir: Option<&Path>) {
    for mdi in [false, true] {
        let fast = run(src, mdi, dir, false);
        let general = run(src, mdi, dir, true);
        if fast != general {
            let at = fast
                .iter()
                .zip(&general)
                .position(|(a, b)| a != b)
                .unwrap_or(fast.len().min(general.len()));
            panic!(
                "{name} (mdi {mdi}): the fast path differs at output {at}:\n  fast:    {:?}\n  general: {:?}",
                fast.get(at),
                general.get(at)
            );
        }
    }
}

fn files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() {
            files(&p, out);
        } else if matches!(p.extension().and_then(|x| x.to_str()), Some("ngc" | "bin")) {
            out.push(p);
        }
    }
}

#[test]
fn plain_path_equals_general_path_on_the_test_programs() {
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/data");
    let mut all = Vec::new();
    files(&data.join("ngc"), &mut all);
    files(&data.join("fuzz/linuxcnc"), &mut all);
    files(&data.join("programs/linuxcnc"), &mut all);
    files(&data.join("errors/linuxcnc"), &mut all);
    all.sort();
    assert!(
        all.len() > 100,
        "{} programs under {}",
        all.len(),
        data.display()
    );
    for p in &all {
        let src = std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        same_both_ways(&p.display().to_string(), &src, p.parent());
    }
}

#[test]
fn plain_path_equals_general_path_on_edge_cases() {
    let cases = [
        // Modal motion, F in the block, zero-length lines, G0 without F.
        "G1 X1 F100\nX2\nX2\nY1 F200\nG0 X0 Y0\nG0 X0\nG1 Z-1\nM2\n",
        // No feed yet, F0, a negative F, F on a rapid.
        "G1 X1\nM2\n",
        "G1 X1 F0\nM2\n",
        "G1 X1 F-5\nM2\n",
        "G0 X1 F-0\nG1 X2\nM2\n",
        // Axis words before any motion mode; after G80.
        "X1\nM2\n",
        "G0 X1\nG80\nX2\nM2\n",
        // Arcs: centre words, whole circles, missing centre, out-of-plane K, radius
        // mismatch, the whole-turn rule, G90.1 with one word, P turns.
        "G1 F100\nG2 X2 I1\nG3 X0 I-1\nG2 I1\nG3 X1 Y1 J1\nM2\n",
        "G1 F100\nG2 X2\nM2\n",
        "G1 F100\nG2 X2 I1 K1\nM2\n",
        "G1 F100\nG2 X3 I1\nM2\n",
        "G1 F100\nG2 X2.00001 I1\nM2\n",
        "G1 F100\nG3 X3 I1 J0\nM2\n",
        "G1 F100\nG90.1\nG2 X2 I1\nM2\n",
        "G1 F100\nG90.1\nG2 X2 I1 J0\nM2\n",
        "G1 F100\nG2 X2 I1 P2\nM2\n",
        "G1 F100\nG18\nG2 X2 K1\nG2 X4 I1\nG19\nG3 Y2 J1\nM2\n",
        "G1 F100\nG2 X2 Y0 Z3 I1\nM2\n",
        "G1 F100\nI1 J1\nM2\n",
        // Incremental, inch, work offsets, G92, G52.
        "G91 G1 X1 F100\nX1 Y1\nG90 X0\nG20\nX1 F10\nG21\nG2 X3 I1\nM2\n",
        "G20 G1 X1 F1\nG3 X0 Y1 I-1\nM2\n",
        "G10 L2 P1 X5 Y5\nG1 X1 F100\nG55 X2\nG92 X0\nX3\nG52 X1\nX4\nM2\n",
        // Rotated coordinate system.
        "G10 L2 P1 R30\nG1 X1 F100\nG2 X2 I0.5\nG10 L2 P1 R0\nX3\nM2\n",
        // Rotary axes: abc in use afterwards.
        "G1 X1 F100\nA10\nX2\nG2 X3 I0.5\nB5 X4\nM2\n",
        // Feed modes.
        "G93 G1 X1 F2\nX2\nG94 X3\nX4 F50\nG95 S100 X5 F1\nX6\nM2\n",
        // Tool change read-back, tool length offsets.
        "G1 X1 F100\nT2 M6\nG43 H2\nX2\nG2 X3 I0.5\nG49\nX4\nM2\n",
        "G1 X1 F100\nT2 M6 G43 H2\nG2 X3 I1\nM2\n",
        // Cutter compensation, arcs after G40.
        "G1 F100\nG41 D1 X10\nY10\nG2 X20 I5\nG40 X30\nG2 X40 I5\nM2\n",
        "G1 F100 X-10\nG42 D2\nX10\nG3 Y10 J5\nX0\nG40\nX-20\nG1 X-30\nM2\n",
        "G1 F100\nG41.1 D4 X5\nY5\nG40 X0 Y0\nX1\nM2\n",
        // Canned cycles and the motion after them.
        "G1 F100 Z5\nG81 X1 Y1 Z-1 R2\nX2\nG1 X3\nG81 X4 Y4 Z-1 R2\nG0 X5\nX6\nG80\nM2\n",
        "G1 F100 Z5\nG83 X1 Y1 Z-3 R2 Q1\nG2 X3 I1\nL2\nM2\n",
        "G1 F100 Z5\nG98 G81 X1 Y1 Z-1 R2\nG1 Z10\nG81 X2 Y2 Z-1 R2\nG0 Z12\nX3\nG81 X4 Z-1 R2\nM2\n",
        "G1 F100 Z5\nG98 G81 X1 Y1 Z-1 R2\nG1 Z10\nG81 X2 Y2 Z-1 R2\nG1 X3\nG81 X4 Z-1 R2\nM2\n",
        // Words a plain block does not hold, and codes beside the motion.
        "G1 X1 Y1 F100 S1000\nX2 M3\nG1 X3 G4 P1\nN10 X4\nG61 X5\nG64 P0.1 X6\nG1 G90 X7\nX8 E1\nX9 L1\nX10 P1\nX11 Q1\nX12 R1\nX13 D1\nX14 H1\nM2\n",
        "G1 X1 F100\nG17 G2 X2 I0.5\nG53 G0 X0\nG0 G53 X1\nM2\n",
        // Polar words.
        "G1 F100 @1 ^45\nX2\nG1 @2\nM2\n",
        // Block delete, messages, parameters, a subroutine.
        "G1 F100 X1\n/X2\n(MSG, hi)\nX3\n#1=4\nX#1\nX[#1+1]\no100 sub\nG1 X7\no100 endsub\no100 call\nX8\nM2\n",
        // Program ends inside, M0, M2 after a move.
        "G1 X1 F100\nM0\nX2\nM30\nX3\n",
        "%\nG1 X1 F100\nX2\n%\nX3\n",
        // Huge and tiny numbers.
        "G1 F100 X1e300\nX1e308 Y1e308\nM2\n",
        "G1 F100 X0.0000000001\nX0.0000000002\nG2 X0.0000000004 I0.0000000001\nM2\n",
    ];
    for (i, src) in cases.iter().enumerate() {
        same_both_ways(&format!("case {i}: {src:?}"), src.as_bytes(), None);
    }
}

/// A generator of small programs (a fixed linear congruential sequence: the same programs
/// on every run).
struct Gen(u64);

impl Gen {
    fn next(&mut self, n: u64) -> u64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (self.0 >> 33) % n
    }

    fn num(&mut self) -> String {
        match self.next(6) {
            0 => "0".into(),
            1 => format!("{}", self.next(20) as i64 - 10),
            2 => format!("{}.5", self.next(6) as i64 - 3),
            3 => format!("-{}.25", self.next(3)),
            _ => format!("{}", self.next(5)),
        }
    }

    fn line(&mut self) -> String {
        let mut words = Vec::new();
        const CODES: [&str; 26] = [
            "G0", "G1", "G2", "G3", "G1", "G2", "G3", "G1", "G20", "G21", "G90", "G91", "G90.1",
            "G91.1", "G17", "G18", "G19", "G80", "G81", "G93", "G94", "G41 D1", "G42 D2", "G40",
            "G43 H2", "G49",
        ];
        if self.next(3) == 0 {
            words.push(CODES[self.next(CODES.len() as u64) as usize].to_string());
        }
        for letter in ["X", "Y", "Z", "I", "J", "K", "F", "A", "R", "P", "S"] {
            let chance = match letter {
                "X" | "Y" => 2,
                "Z" | "I" | "J" => 4,
                "F" => 6,
                _ => 30,
            };
            if self.next(chance) == 0 {
                let v = self.num();
                words.push(format!("{letter}{v}"));
            }
        }
        match self.next(40) {
            0 => words.push("M6 T2".into()),
            1 => words.push("M3".into()),
            2 => words.push("G10 L2 P1 R15".into()),
            _ => {}
        }
        words.join(" ")
    }
}

#[test]
fn plain_path_equals_general_path_on_generated_programs() {
    let mut g = Gen(31);
    for n in 0..400 {
        let mut src = String::from("G21 G90 G17 F100\n");
        for _ in 0..60 {
            src.push_str(&g.line());
            src.push('\n');
        }
        src.push_str("M2\n");
        same_both_ways(
            &format!("generated program {n}:\n{src}"),
            src.as_bytes(),
            None,
        );
    }
}
