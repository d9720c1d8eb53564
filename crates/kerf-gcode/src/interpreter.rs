//! The streaming [`Interpreter`]: reads a program one source line at a time, through the
//! lexer or the LinuxCNC language layer, resolves each block and yields its items.

use crate::{Diagnostic, Dialect, InputWait, Item, Settings, interp, lex, ngc};

/// The longest source line accepted, in bytes. Longer lines are an error, which keeps the
/// interpreter's memory bounded on any input.
pub const MAX_LINE_BYTES: usize = 64 * 1024;

/// Streams items from a reader: constant memory, one source line at a time.
///
/// The iterator yields items in program order. After the first `Err` it yields `None`
/// forever: nothing after a failing block is produced. The items of a block are only
/// yielded once the whole block has been resolved without error.
pub struct Interpreter<R: std::io::BufRead> {
    reader: R,
    line: Vec<u8>,
    line_no: u32,
    /// Lines read from the reader (`line_no` is the line being run, which may come from
    /// a subroutine or loop kept in memory).
    reader_line: u32,
    lexer: lex::Lexer,
    words: Vec<lex::Word>,
    block: interp::Block,
    state: interp::State,
    /// The items of the line just resolved, last first: each is moved out by `pop`, in
    /// program order, instead of being cloned out of a buffer read from the front.
    pending: Vec<Item>,
    error: Option<Diagnostic>,
    finished: bool,
    percent_seen: bool,
    blocks_seen: bool,
    /// The LinuxCNC language layer (parameters, expressions, O-words, messages).
    ngc: ngc::Ngc,
}

impl<R: std::io::BufRead> Interpreter<R> {
    /// An interpreter for `dialect` reading from `reader`.
    pub fn new(reader: R, dialect: Dialect, settings: Settings) -> Self {
        Self::with_program_dir(reader, dialect, settings, None)
    }

    /// Like [`Interpreter::new`] for a program read from a file in `dir`: LinuxCNC looks
    /// for subroutine files `NAME.ngc` there first, then on [`Settings::subroutine_path`].
    pub fn with_program_dir(
        reader: R,
        dialect: Dialect,
        settings: Settings,
        dir: Option<&std::path::Path>,
    ) -> Self {
        let program_dir = settings.program_file.as_deref().map(|f| match f.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => std::path::PathBuf::from("."),
        });
        let mut search: Vec<std::path::PathBuf> = dir
            .map(|d| d.to_path_buf())
            .into_iter()
            .chain(program_dir)
            .collect();
        search.extend(settings.subroutine_path.iter().cloned());
        let ngc = ngc::Ngc::new(
            search,
            settings.max_loop_iterations,
            settings.program_file.clone(),
        );
        Interpreter {
            ngc,
            reader,
            line: Vec::with_capacity(256),
            line_no: 0,
            reader_line: 0,
            lexer: lex::Lexer::new(dialect).with_block_delete(settings.block_delete),
            words: Vec::with_capacity(32),
            block: interp::Block::new(),
            state: interp::State::new(dialect, settings),
            pending: Vec::with_capacity(16),
            error: None,
            finished: false,
            percent_seen: false,
            blocks_seen: false,
        }
    }

    /// LinuxCNC: where the answer to an `M66` wait comes from when a later line reads
    /// `#5399` (without one: [`Settings::simulated_inputs`]). The interpreter calls
    /// [`InputWait::wait`] once per `M66`, and only when a line reads `#5399` while that
    /// `M66` is outstanding. The `M66` event and every item before it have been yielded by
    /// then (M62–M68 are refused under cutter compensation, so nothing is held back
    /// behind a move), so the source may block until the machine has run them and
    /// answered. Its error ends the program at the line that reads `#5399`.
    pub fn set_input_wait(&mut self, source: Box<dyn InputWait + Send>) {
        self.state.set_input_wait(source);
    }

    /// [`Interpreter::set_input_wait`], builder style.
    pub fn with_input_wait(mut self, source: Box<dyn InputWait + Send>) -> Self {
        self.set_input_wait(source);
        self
    }

    /// LinuxCNC's persistent numbered parameters #5161–#5390 as they are now (after a
    /// program that ended normally: its end values), in mm and degrees: the G28 and G30
    /// positions, the G92 offset and its flag, the active coordinate system and the
    /// G54–G59.3 offsets and rotations. `kerf run` writes them to the parameter file.
    pub fn persistent_parameters(&self) -> Vec<(u32, f64)> {
        self.state.params.persistent()
    }

    /// True when the program ended with M2 or M30 (or a Heidenhain end line).
    pub fn ended(&self) -> bool {
        self.state.done
    }

    /// The tool table as it is now: the settings' table with the changes the program made
    /// (G10 L1, L10, L11), in the order of the settings.
    pub fn tools(&self) -> &[crate::Tool] {
        self.state.tools()
    }

    /// MDI ([`Settings::mdi`]): the current point becomes `machine_mm_deg` (X, Y, Z mm,
    /// A, B, C degrees, machine coordinates), where the machine stands, as LinuxCNC's
    /// interpreter synchronises with the machine before an MDI command (after a motion
    /// that was aborted or refused, the interpreter's idea of the position is not the
    /// machine's). The modal state, offsets and parameters stay.
    pub fn set_position(&mut self, machine_mm_deg: kerf_geom::PerAxis<f64>) {
        self.state.set_machine_position(machine_mm_deg);
    }

    /// The current point in the program coordinates of the active coordinate system, with
    /// every offset in force taken off (work offset and its rotation, G52/G92, tool
    /// offsets): X, Y, Z mm and A, B, C degrees whatever G20/G21 (LinuxCNC's
    /// #5420–#5425 in mm). What a DRO shows as the work position.
    pub fn program_position(&self) -> kerf_geom::PerAxis<f64> {
        self.state.program_position()
    }

    /// The active coordinate system: 0 = G54, 1 = G55, … 8 = G59.3; `None` for none
    /// (Sinumerik G500, Heidenhain before a datum shift).
    pub fn coordinate_system(&self) -> Option<usize> {
        self.state.coordinate_system()
    }

    /// MDI: a LinuxCNC structure (a subroutine definition, a loop, an `if`) begun on a
    /// line read so far and not yet ended: the line it began on and what it is. The
    /// interpreter waits for more lines before it runs it.
    pub fn unfinished_structure(&self) -> Option<(u32, String)> {
        self.ngc.unfinished()
    }

    fn diag(&self, col: u32, message: impl Into<String>) -> Diagnostic {
        Diagnostic {
            line: self.line_no,
            col,
            message: message.into(),
            file: self.ngc.current_file(),
            called_from: self.ngc.call_chain(),
        }
    }

    /// Reads the next line into `self.line` without its line end. `Ok(false)` at the end
    /// of the input.
    fn read_line(&mut self) -> Result<bool, Diagnostic> {
        self.line.clear();
        let n = match read_line_into(&mut self.reader, &mut self.line, MAX_LINE_BYTES + 1) {
            Ok(n) => n,
            Err(e) => {
                self.reader_line = self.reader_line.saturating_add(1);
                self.line_no = self.reader_line;
                return Err(self.diag(1, format!("read error: {e}")));
            }
        };
        if n == 0 {
            return Ok(false);
        }
        self.reader_line = self.reader_line.saturating_add(1);
        self.line_no = self.reader_line;
        if self.line.last() == Some(&b'\n') {
            self.line.pop();
        } else if self.line.len() > MAX_LINE_BYTES {
            return Err(self.diag(1, format!("line longer than {MAX_LINE_BYTES} bytes")));
        }
        if self.line.last() == Some(&b'\r') {
            self.line.pop();
        }
        if self.line_no == 1 && self.line.starts_with(b"\xef\xbb\xbf") {
            // A UTF-8 byte-order mark, as some Windows editors write: not part of the program.
            // Blanking it keeps the columns of the first line right.
            self.line[..3].copy_from_slice(b"   ");
        }
        Ok(true)
    }

    /// Resolves every block of the current line into `pending`, stopping at the first error.
    fn process_line(&mut self) -> Result<(), Diagnostic> {
        // Plain ASCII without NUL is the common case and needs no further check.
        if nul_or_non_ascii(&self.line) {
            if let Some(i) = self.line.iter().position(|&b| b == 0) {
                return Err(self.diag(lex::col_of(i), "NUL byte in program"));
            }
            if let Err(e) = std::str::from_utf8(&self.line) {
                return Err(self.diag(lex::col_of(e.valid_up_to()), "invalid UTF-8 in program"));
            }
        }
        let dialect = self.state.dialect();
        let mut pos = 0;
        // A LinuxCNC line of plain words is lexed once: the lexer refuses `#`, `[` and
        // O-words and flags a message comment, so only a line it refuses, flags or ends
        // early (block delete, `%`) is scanned for the language layer's bytes.
        let mut lexed = None;
        if dialect == Dialect::LinuxCnc {
            let language = self.ngc.busy() || {
                let first = self.lexer.next_block(&self.line, &mut pos, &mut self.words);
                let language = match &first {
                    Ok(None) => false,
                    Ok(Some(f)) if !(f.message || f.deleted || f.percent) => false,
                    Ok(Some(f)) if f.message => true,
                    _ => ngc::needs_language(&self.line),
                };
                lexed = Some(first);
                language
            };
            if language {
                if self.process_ngc_line()? {
                    return Ok(());
                }
                // The plain path runs the line after all: lex it afresh.
                lexed = None;
                pos = 0;
            }
        }
        loop {
            let start = self.pending.len();
            let next = match lexed.take() {
                Some(first) => first,
                None => self.lexer.next_block(&self.line, &mut pos, &mut self.words),
            };
            let flags = match next {
                Ok(Some(f)) => f,
                Ok(None) => return Ok(()),
                Err(e) => return Err(self.diag(e.col, e.message)),
            };
            if flags.deleted {
                continue;
            }
            if flags.percent && matches!(dialect, Dialect::LinuxCnc | Dialect::Rockwell) {
                // A `%` line opens the program; the next one ends it and the rest of the
                // file is ignored, as on the control.
                if dialect == Dialect::LinuxCnc && !self.percent_seen && self.blocks_seen {
                    // rs274: a `%` closes only a program that a `%` opened.
                    return Err(self.diag(1, "Bad character '%' used"));
                }
                if self.percent_seen || self.blocks_seen {
                    self.finished = true;
                    // LinuxCNC does not run a move held back by cutter compensation
                    // when the program ends at `%`; neither does Kerf.
                    return Ok(());
                }
                self.percent_seen = true;
                continue;
            }
            if self.words.is_empty() && !flags.percent {
                continue;
            }
            self.blocks_seen = true;
            let result = self
                .state
                .build_block(&self.words, &mut self.block)
                .and_then(|()| {
                    let mut out = interp::Out {
                        items: &mut self.pending,
                        line: self.line_no,
                    };
                    self.state.exec(&self.block, flags.percent, &mut out)
                });
            if let Err(e) = result {
                self.pending.truncate(start);
                return Err(self.diag(e.col, e.message));
            }
            if self.state.done {
                self.finished = true;
                return Ok(());
            }
        }
    }
}

/// Appends the bytes of `reader` up to and including the next `\n` to `line`, at most
/// `limit` of them, and returns how many: `reader.take(limit).read_until(b'\n', line)`
/// without the adapter, and with a search for the line end that suits short lines.
fn read_line_into<R: std::io::BufRead>(
    reader: &mut R,
    line: &mut Vec<u8>,
    limit: usize,
) -> std::io::Result<usize> {
    let mut read = 0;
    while read < limit {
        let available = match reader.fill_buf() {
            Ok(b) => b,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e),
        };
        let available = &available[..available.len().min(limit - read)];
        if available.is_empty() {
            break;
        }
        let (used, done) = match newline_at(available) {
            Some(i) => (i + 1, true),
            None => (available.len(), false),
        };
        line.extend_from_slice(&available[..used]);
        reader.consume(used);
        read += used;
        if done {
            break;
        }
    }
    Ok(read)
}

/// A byte of ones in every byte of a word.
const ONES: u64 = 0x0101_0101_0101_0101;
/// The high bit of every byte of a word.
const HIGH: u64 = 0x8080_8080_8080_8080;

/// Eight bytes, the first in the lowest byte of the word.
fn word_of(chunk: &[u8]) -> u64 {
    u64::from_le_bytes(chunk.try_into().expect("a chunk of 8 bytes"))
}

/// `(x - ONES) & !x`, high bits only: nonzero exactly when a byte of `x` is zero, and its
/// lowest set bit marks the first zero byte (the bytes above it can be marked wrongly,
/// never the ones below).
fn zero_bytes(x: u64) -> u64 {
    x.wrapping_sub(ONES) & !x & HIGH
}

/// The offset of the first `\n` in `bytes`, eight bytes at a time.
fn newline_at(bytes: &[u8]) -> Option<usize> {
    let mut chunks = bytes.chunks_exact(8);
    let mut at = 0;
    for chunk in &mut chunks {
        let zero = zero_bytes(word_of(chunk) ^ (ONES * u64::from(b'\n')));
        if zero != 0 {
            return Some(at + zero.trailing_zeros() as usize / 8);
        }
        at += 8;
    }
    chunks
        .remainder()
        .iter()
        .position(|&b| b == b'\n')
        .map(|i| at + i)
}

/// Whether `line` holds a NUL byte or a byte of 0x80 or above (anything but plain ASCII
/// without NUL), tested eight bytes at a time.
fn nul_or_non_ascii(line: &[u8]) -> bool {
    let mut chunks = line.chunks_exact(8);
    for chunk in &mut chunks {
        let x = word_of(chunk);
        // A zero byte, or one with its high bit set (0x80 or above).
        if zero_bytes(x) | (x & HIGH) != 0 {
            return true;
        }
    }
    chunks.remainder().iter().any(|&b| b == 0 || b >= 0x80)
}

impl<R: std::io::BufRead> Interpreter<R> {
    /// A LinuxCNC line through the language layer. `Ok(false)`: the plain path handles it.
    fn process_ngc_line(&mut self) -> Result<bool, Diagnostic> {
        let action = self
            .ngc
            .line(&self.line, self.line_no, &mut self.state, &mut self.words)
            .map_err(|e| self.diag(e.col, e.message))?;
        self.ngc.take_restored(&mut self.pending);
        match action {
            ngc::Action::Nothing => return Ok(true),
            ngc::Action::Plain => return Ok(false),
            ngc::Action::Block => {}
        }
        self.blocks_seen = true;
        let start = self.pending.len();
        let result = self
            .state
            .build_block(&self.words, &mut self.block)
            .map_err(|e| (e.col, e.message))
            .and_then(|()| {
                self.ngc
                    .commit(&mut self.state, &mut self.pending, self.line_no)
                    .map_err(|e| (e.col, e.message))
            })
            .and_then(|()| {
                let mut out = interp::Out {
                    items: &mut self.pending,
                    line: self.line_no,
                };
                self.state
                    .exec(&self.block, false, &mut out)
                    .map_err(|e| (e.col, e.message))
            });
        if let Err((col, message)) = result {
            self.pending.truncate(start);
            return Err(self.diag(col, message));
        }
        if self.state.done {
            self.finished = true;
        }
        Ok(true)
    }
}

impl<R: std::io::BufRead> Iterator for Interpreter<R> {
    type Item = Result<Item, Diagnostic>;

    fn next(&mut self) -> Option<Self::Item> {
        loop {
            if let Some(item) = self.pending.pop() {
                return Some(Ok(item));
            }
            if let Some(e) = self.error.take() {
                self.finished = true;
                return Some(Err(e));
            }
            if self.finished {
                return None;
            }
            let from_memory = if self.state.dialect() == Dialect::LinuxCnc {
                self.ngc.next_line(&mut self.line)
            } else {
                None
            };
            let got = match from_memory {
                Some(n) => {
                    self.line_no = n;
                    Ok(true)
                }
                None => self.read_line(),
            };
            match got {
                Ok(true) => {}
                Ok(false) if self.state.mdi() => {
                    // MDI: what was typed so far has run; the next call reads on.
                    return None;
                }
                Ok(false) => {
                    self.finished = true;
                    if let Some((line, m)) = self.ngc.unfinished() {
                        self.line_no = line;
                        return Some(Err(self.diag(1, m)));
                    }
                    if self.state.dialect() == Dialect::LinuxCnc {
                        // rs274 refuses a program that ends without M2/M30 or its closing
                        // `%`, at the last line of the file; the moves before it have run,
                        // a move held back by cutter compensation has not.
                        self.line_no = self.reader_line.max(1);
                        let m = if self.percent_seen {
                            "File ended with no percent sign"
                        } else {
                            "File ended with no percent sign or program end"
                        };
                        return Some(Err(self.diag(1, m)));
                    }
                    // Moves held back by cutter compensation run at the end of the file.
                    self.state.comp_finish(&mut self.pending);
                    self.pending.reverse();
                    continue;
                }
                Err(e) => {
                    self.finished = true;
                    return Some(Err(e));
                }
            }
            if let Err(e) = self.process_line() {
                if self.state.mdi() {
                    // MDI: the error ends its line only (what the block changed before
                    // it stays, as in LinuxCNC); the next call reads the next line.
                    self.pending.clear();
                    self.ngc.abandon();
                    return Some(Err(e));
                }
                self.error = Some(e);
                self.finished = true;
            }
            // The line's items (those before an error) go out first, in program order.
            self.pending.reverse();
        }
    }
}

#[cfg(test)]
mod tests {
    use std::io::{BufRead, BufReader, Read};

    use super::{newline_at, nul_or_non_ascii, read_line_into};

    #[test]
    fn newline_at_finds_the_first_line_end() {
        for len in 0..=40 {
            for at in 0..len {
                for other in [
                    None,
                    Some(0u8),
                    Some(b'\n' - 1),
                    Some(b'\n' + 1),
                    Some(0x8a),
                ] {
                    let mut bytes = vec![b'X'; len];
                    bytes[at] = b'\n';
                    if let Some(o) = other {
                        bytes[(at + 1) % len] = o;
                        if at > 0 {
                            bytes[at - 1] = o;
                        }
                    }
                    let expected = bytes.iter().position(|&b| b == b'\n');
                    assert_eq!(newline_at(&bytes), expected, "{bytes:?}");
                    let later = at + 1 + (len - at) / 2;
                    if later < len {
                        bytes[later] = b'\n';
                        assert_eq!(newline_at(&bytes), expected, "{bytes:?}");
                    }
                }
            }
            assert_eq!(newline_at(&vec![b'Y'; len]), None);
        }
    }

    #[test]
    fn read_line_into_reads_what_take_read_until_reads() {
        let text: Vec<u8> = b"G1 X1\n\nG2 X2 Y0.5 I1 J0 (a longer line than the buffer)\nlast"
            .iter()
            .copied()
            .chain(std::iter::repeat_n(b'A', 70))
            .chain(*b"\r\n\n")
            .collect();
        for capacity in [1, 2, 3, 7, 8, 9, 64, 8192] {
            for limit in [1, 2, 5, 8, 30, 100, 10_000] {
                let mut ours = BufReader::with_capacity(capacity, text.as_slice());
                let mut theirs = BufReader::with_capacity(capacity, text.as_slice());
                loop {
                    let (mut a, mut b) = (Vec::new(), Vec::new());
                    let n = read_line_into(&mut ours, &mut a, limit).unwrap();
                    let m = (&mut theirs)
                        .take(limit as u64)
                        .read_until(b'\n', &mut b)
                        .unwrap();
                    assert_eq!((n, &a), (m, &b), "capacity {capacity}, limit {limit}");
                    if n == 0 {
                        break;
                    }
                }
                assert!(ours.fill_buf().unwrap().is_empty());
            }
        }
    }

    #[test]
    fn the_eight_byte_test_answers_as_the_byte_by_byte_one() {
        let bytewise = |l: &[u8]| l.iter().any(|&b| b == 0 || b >= 0x80);
        for len in 0..=24 {
            for at in 0..len {
                for b in 0..=255u8 {
                    let mut line = vec![b'G'; len];
                    line[at] = b;
                    assert_eq!(nul_or_non_ascii(&line), bytewise(&line), "{line:?}");
                    // Next to a byte that borrows in the subtraction (0x00, 0x01, 0x80).
                    for other in [0u8, 1, 0x7f, 0x80, 0xff] {
                        let mut two = line.clone();
                        two[(at + 1) % len] = other;
                        assert_eq!(nul_or_non_ascii(&two), bytewise(&two), "{two:?}");
                    }
                }
            }
        }
    }
}
