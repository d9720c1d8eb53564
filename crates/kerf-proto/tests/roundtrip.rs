//! Every item of every sample program encodes to a `MoveMsg` and decodes to exactly the
//! same `Move` or `Event`, and the whole program passes `StreamCheck`.

use std::path::{Path as FsPath, PathBuf};

use kerf_gcode::{Dialect, Interpreter, Item, Settings};
use kerf_geom::{CornerMode, Path};
use kerf_proto::{MoveMsg, Resolved, StreamCheck};

fn workspace() -> PathBuf {
    FsPath::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The dialect from the extension, else from the directory name (tests/data/programs/<dialect>/).
fn dialect_of(path: &FsPath, text: &[u8]) -> Dialect {
    Dialect::from_path(path, &text[..text.len().min(4096)])
        .or_else(|| {
            let dir = path.parent()?.file_name()?.to_str()?;
            Dialect::from_name(dir)
        })
        .unwrap_or_else(|| panic!("no dialect for {}", path.display()))
}

fn programs() -> Vec<PathBuf> {
    let root = workspace().join("tests/data/programs");
    let mut files = Vec::new();
    for dir in std::fs::read_dir(&root).expect("tests/data/programs") {
        let dir = dir.expect("dir entry").path();
        if dir.is_dir() {
            for f in std::fs::read_dir(&dir).expect("dialect dir") {
                files.push(f.expect("file entry").path());
            }
        }
    }
    files.push(workspace().join("config/examples/part.ngc"));
    files.sort();
    files
}

/// Runs the items of `text` through encode → StreamCheck → decode; returns the items.
fn round_trip(name: &str, text: &[u8], dialect: Dialect, program_id: u64) -> Vec<Item> {
    // The sample programs call tools 1 to 20; LinuxCNC refuses a tool missing from the
    // tool table.
    let settings = Settings {
        tools: (1..=20)
            .map(|number| kerf_gcode::Tool {
                number,
                ..kerf_gcode::Tool::default()
            })
            .collect(),
        ..Settings::default()
    };
    let items: Vec<Item> = Interpreter::new(text, dialect, settings)
        .map_while(Result::ok)
        .collect();
    let mut check = StreamCheck::new();
    let begin = MoveMsg::begin(program_id, [0.0; 6], items.len() as u64);
    assert!(matches!(check.check(&begin), Ok(Resolved::Begin { .. })));
    for (i, item) in items.iter().enumerate() {
        let seq = i as u64 + 1;
        let msg = MoveMsg::from_item(program_id, seq, item);
        let alone =
            Resolved::try_from(&msg).unwrap_or_else(|e| panic!("{name} item {seq} {item:?}: {e}"));
        let in_stream = check
            .check(&msg)
            .unwrap_or_else(|e| panic!("{name} item {seq} {item:?}: {e}"));
        assert_eq!(alone, in_stream);
        match (item, alone) {
            (Item::Move(a), Resolved::Move(b)) => assert_eq!(*a, b, "{name} item {seq}"),
            (Item::Event(a), Resolved::Event(b)) => assert_eq!(*a, b, "{name} item {seq}"),
            (a, b) => panic!("{name} item {seq}: {a:?} decoded as {b:?}"),
        }
    }
    let end = MoveMsg::end(program_id, items.len() as u64);
    assert!(matches!(check.check(&end), Ok(Resolved::End { .. })));
    assert_eq!(check.program_id(), None);
    items
}

#[test]
fn every_sample_program_round_trips() {
    let mut counts = [0usize; 6]; // lines, rapids, arcs, helices, events, events with value
    let files = programs();
    assert!(files.len() >= 8, "{files:?}");
    for (n, path) in files.iter().enumerate() {
        let text = std::fs::read(path).expect("program");
        let name = path.display().to_string();
        let items = round_trip(&name, &text, dialect_of(path, &text), n as u64 + 1);
        assert!(!items.is_empty(), "{name}: no items");
        for item in &items {
            match item {
                Item::Move(m) => match m.path {
                    Path::Line(_) if m.rapid => counts[1] += 1,
                    Path::Line(_) => counts[0] += 1,
                    Path::Arc(a) if (a.end - a.start).dot(&a.axis).abs() > 1e-9 => counts[3] += 1,
                    Path::Arc(_) => counts[2] += 1,
                },
                Item::Event(e) => {
                    counts[4] += 1;
                    if e.value.is_some() {
                        counts[5] += 1;
                    }
                }
            }
        }
    }
    // The corpus covers every kind of item, so the round trip above means something.
    assert!(counts.iter().all(|&c| c > 0), "{counts:?}");
}

#[test]
fn rotary_axes_tolerances_and_exact_stop_round_trip() {
    let program = "G21 G90 F600\nG64 P0.05\nG1 X10 A30\nG61\nG3 X0 Y10 I-10 J0 Z-1 B5\nG64\nG0 Z5 C90\nG4 P0.5\nM3 S1200\nG64 P0\nG1 X3\nM30\n";
    let items = round_trip("inline", program.as_bytes(), Dialect::LinuxCnc, 42);
    let mut corners = Vec::new();
    let mut abc_moves = 0;
    for item in &items {
        if let Item::Move(m) = item {
            corners.push(m.corner);
            abc_moves += usize::from(m.abc_deg.is_some());
        }
    }
    assert_eq!(
        corners,
        [
            // LinuxCNC: the naive-CAM tolerance is P when Q is absent.
            CornerMode::Blend {
                tolerance_mm: Some(0.05),
                naive_cam_mm: Some(0.05)
            },
            CornerMode::ExactStop,
            CornerMode::Blend {
                tolerance_mm: None,
                naive_cam_mm: None
            },
            CornerMode::Blend {
                tolerance_mm: Some(0.0),
                naive_cam_mm: Some(0.0)
            },
        ]
    );
    assert_eq!(abc_moves, 4);
    assert_eq!(items.len(), 4 + 4); // G4, M3, S, M30
}

#[test]
fn a_program_that_errors_stops_at_the_error() {
    // Line 3 is an error: the items before it still round trip, nothing after it exists.
    let program = "G21 G90 F600\nG1 X10\nG1 X20 Q7\nG1 X30\n";
    let items = round_trip("bad", program.as_bytes(), Dialect::LinuxCnc, 7);
    assert_eq!(items.len(), 1);
}
