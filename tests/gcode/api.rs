//! Dialect selection (issue 2: by name, alias, and by file extension where unambiguous).

use std::cell::Cell;
use std::io::{BufReader, Read};
use std::path::Path as FsPath;
use std::rc::Rc;

use kerf_tests::*;

#[test]
fn dialect_names_and_alias() {
    assert_eq!(Dialect::from_name("linuxcnc"), Some(Dialect::LinuxCnc));
    assert_eq!(Dialect::from_name("tormach"), Some(Dialect::LinuxCnc));
    assert_eq!(Dialect::from_name("rockwell"), Some(Dialect::Rockwell));
    assert_eq!(Dialect::from_name("sinumerik"), Some(Dialect::Sinumerik));
    assert_eq!(Dialect::from_name("heidenhain"), Some(Dialect::Heidenhain));
    assert_eq!(Dialect::from_name("fagor"), Some(Dialect::Fagor));
    assert_eq!(Dialect::from_name("fanuc"), None);
    assert_eq!(Dialect::from_name(""), None);
    for d in Dialect::ALL {
        assert_eq!(Dialect::from_name(d.name()), Some(d));
    }
    assert_eq!(Dialect::ALL.len(), 5);
}

#[test]
fn dialect_from_unambiguous_extensions() {
    let p = |s: &str| FsPath::new(s).to_path_buf();
    assert_eq!(
        Dialect::from_path(&p("part.ngc"), b"G0 X0\n"),
        Some(Dialect::LinuxCnc)
    );
    assert_eq!(
        Dialect::from_path(&p("PART.MPF"), b"N10 G0 X0\n"),
        Some(Dialect::Sinumerik)
    );
    assert_eq!(
        Dialect::from_path(&p("sub.spf"), b"N10 G0 X0\n"),
        Some(Dialect::Sinumerik)
    );
}

#[test]
fn heidenhain_extensions_only_for_iso_programs() {
    let p = |s: &str| FsPath::new(s).to_path_buf();
    let iso = b"%PART G71 *\nN10 G00 X+0 *\n";
    assert_eq!(
        Dialect::from_path(&p("part.h"), iso),
        Some(Dialect::Heidenhain)
    );
    assert_eq!(
        Dialect::from_path(&p("part.i"), iso),
        Some(Dialect::Heidenhain)
    );
    // A conversational (Klartext) program is not TNC ISO: Kerf does not claim it.
    let klartext = b"0 BEGIN PGM PART MM\n1 BLK FORM 0.1 Z X+0 Y+0 Z-20\n";
    assert_ne!(
        Dialect::from_path(&p("part.h"), klartext),
        Some(Dialect::Heidenhain)
    );
}

#[test]
fn ambiguous_extensions_are_not_guessed() {
    let p = |s: &str| FsPath::new(s).to_path_buf();
    assert_eq!(Dialect::from_path(&p("part.nc"), b"G0 X0\n"), None);
    assert_eq!(Dialect::from_path(&p("part.txt"), b"G0 X0\n"), None);
    assert_eq!(Dialect::from_path(&p("part"), b""), None);
}

/// An endless program, generated on the fly, that counts the bytes read from it.
struct EndlessProgram {
    next_line: u64,
    pending: Vec<u8>,
    bytes_read: Rc<Cell<usize>>,
}

impl Read for EndlessProgram {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        if self.pending.is_empty() {
            self.next_line += 1;
            let x = self.next_line % 100;
            self.pending = format!("G1 X{x} Y{} F1000\n", x % 7).into_bytes();
        }
        let n = buf.len().min(self.pending.len());
        buf[..n].copy_from_slice(&self.pending[..n]);
        self.pending.drain(..n);
        self.bytes_read.set(self.bytes_read.get() + n);
        Ok(n)
    }
}

#[test]
fn interpreter_streams_without_reading_ahead() {
    // Issue 2: `kerf plan` streams in constant memory. The interpreter must yield moves as
    // it reads, so taking the first 10,000 moves of an endless program reads only about as
    // many lines (plus the reader's buffer), never the whole input.
    let bytes_read = Rc::new(Cell::new(0));
    let program = EndlessProgram {
        next_line: 0,
        pending: Vec::new(),
        bytes_read: bytes_read.clone(),
    };
    let interp = Interpreter::new(
        BufReader::new(program),
        Dialect::LinuxCnc,
        Settings::default(),
    );
    let mut count = 0;
    for item in interp.take(10_000) {
        let item = item.unwrap_or_else(|e| panic!("{e}"));
        assert!(matches!(item, Item::Move(_)));
        count += 1;
    }
    assert_eq!(count, 10_000);
    // 10,000 lines of at most 18 bytes, plus one 8 KiB buffer and some slack.
    assert!(
        bytes_read.get() < 10_000 * 18 + 64 * 1024,
        "read {} bytes for 10,000 lines",
        bytes_read.get()
    );
}

/// A reader that fails after its content.
struct FailingReader {
    content: std::io::Cursor<Vec<u8>>,
}

impl Read for FailingReader {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.content.read(buf)?;
        if n == 0 {
            Err(std::io::Error::other("disk on fire"))
        } else {
            Ok(n)
        }
    }
}

#[test]
fn read_error_is_a_diagnostic_not_a_panic() {
    // Invariant 6: the blocks read before the failure are yielded, then one error, then
    // nothing.
    let reader = FailingReader {
        content: std::io::Cursor::new(b"G1 X1 F100\nG1 X2\n".to_vec()),
    };
    let out = run_reader(
        Dialect::LinuxCnc,
        Settings::default(),
        BufReader::new(reader),
        18,
    );
    assert_eq!(
        only_moves(&out.items).len(),
        2,
        "{}",
        describe_items(&out.items)
    );
    let e = out
        .error
        .expect("an I/O error must surface as a diagnostic");
    assert!(e.line >= 2, "{e}");
}
