//! `kerf plan`: resolve a program and print every move and event as one JSON object per line.
//!
//! This output is a contract other tools rely on (docs/OUTPUTS.md). Each line is one of:
//!
//! ```text
//! {"type":"line","line":N,"rapid":false,"start":[x,y,z],"end":[x,y,z],"feed_mm_min":F}
//! {"type":"line","line":N,"rapid":true,"start":[x,y,z],"end":[x,y,z],"feed_mm_min":null}
//! {"type":"arc","line":N,"start":[x,y,z],"end":[x,y,z],"center":[x,y,z],"axis":[ax,ay,az],"sweep_rad":S,"feed_mm_min":F}
//! {"type":"event","line":N,"code":"M3","value":null}
//! {"type":"event","line":N,"code":"S","value":12000.0}
//! {"type":"event","line":N,"code":"M101","value":3.0,"q":-4.5}
//! {"type":"event","line":N,"code":"M62","value":2.0}
//! {"type":"event","line":N,"code":"M66","value":1.0,"p":3.0,"q":2.5,"input":"digital"}
//! {"type":"event","line":N,"code":"M67","value":0.0,"q":7.5}
//! {"type":"event","line":N,"code":"MSG","value":null,"text":"change the clamp"}
//! ```
//!
//! - Lengths are mm in absolute machine coordinates; `line` is the 1-based source line.
//! - A move on a machine with rotary axes in use adds `"abc_start":[a,b,c],"abc_end":[a,b,c]`
//!   (degrees) after `feed_mm_min`.
//! - Events: `code` is one of `M0 M1 M2 M30 M60 M3 M4 M5 M6 M7 M8 M9 M19 M48`–`M53
//!   M62`–`M68 S T G4`, a user M code `M100`…`M199`, or `MSG`, `DEBUG`, `PRINT`, `LOG`
//!   (LinuxCNC's log calls, the call in `text`: `LOGOPEN,file`, `LOGAPPEND,file`,
//!   `LOG,text`, `LOGCLOSE`; Kerf writes no file); `value` is the spindle speed in rpm
//!   for `S`, the tool number for `T`, the dwell in seconds for `G4`, the angle R for
//!   M19, 1 (enabled) or 0 for M50–M53, the output number for M62–M65, M67 and M68, the
//!   input number for M66, the P word (or `null`) for a user M code, and `null`
//!   otherwise. M0, M1 (optional stop) and M60 (pallet change) are program pauses.
//!   `"p":P` is added where the event has a P-like word: M19 its P (the direction mode),
//!   M66 its L (the wait mode, 0–4). `"q":Q` is added where it has a Q word: a user M
//!   code's Q, M19's and M66's timeout in seconds, M67's and M68's analog value. M66 adds
//!   `"input":"digital"` (a P input) or `"input":"analog"` (an E input). A message adds
//!   `"text":"..."` (a JSON string: `"`, `\` and control characters escaped). Events
//!   without them have none of these keys.
//! - Numbers are written in the shortest form that parses back to the same `f64`
//!   (Schubfach via the `zmij` crate, the algorithm `serde_json` uses), e.g. `1.0`, `0.1`,
//!   `-2.5e-7`, `1e+16`. Integers (`line`) are plain decimal.
//!
//! Design decisions:
//! - The JSON is written by hand into a reusable byte buffer that is handed to the writer in
//!   large chunks: formatting must not dominate a parse + resolve that runs at millions of
//!   blocks per second, and there is no nesting that would justify a serializer.
//! - On a program error everything before the failing block has already been written, and
//!   [`plan`] flushes it before returning the error, so a consumer sees exactly the accepted
//!   prefix of the program.
//! - Resolving and formatting cost about the same, so [`plan`] runs the interpreter on a
//!   second thread and hands items over in batches through a bounded queue: the two overlap
//!   on two cores and memory stays constant. [`plan_sequential`] gives the same bytes on one
//!   thread.
//! - The front end never produces non-finite numbers; if one ever appears the output would
//!   not be JSON, so it becomes an error ([`PlanOutputError::NonFinite`]) instead.

use std::io::{self, BufRead, Write};
use std::sync::mpsc;

use kerf_gcode::{
    Diagnostic, Dialect, Event, EventCode, Interpreter, Item, Move, Path, Settings, Vec3,
};

/// How many bytes of output are collected before they are handed to the writer.
const CHUNK_BYTES: usize = 64 * 1024;

/// Why `kerf plan` stopped before the end of the program.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PlanOutputError {
    /// The program is wrong at a place (or could not be read); nothing after it was written.
    #[error("{0}")]
    Program(Diagnostic),
    /// Writing the output failed (for example a closed pipe).
    #[error("writing the plan: {0}")]
    Output(#[from] io::Error),
    /// A resolved move carried a NaN or infinite number, which JSON cannot express.
    #[error("{line}:1: error: internal error: non-finite number in a resolved move")]
    NonFinite {
        /// 1-based source line of the move.
        line: u32,
    },
    /// The interpreter thread stopped without finishing the program (it panicked).
    #[error("internal error: the G-code interpreter stopped before the end of the program")]
    Interrupted,
}

/// Resolves the program read from `reader` in `dialect` and writes one JSON object per
/// move or event to `writer` (see the module documentation for the format).
///
/// Returns the number of items written. `writer` is flushed before this returns, on
/// success and on error alike. The writer needs no buffering of its own.
///
/// The interpreter runs on a second thread and hands over items in batches through a
/// bounded queue, so that parsing and JSON formatting overlap on two cores while memory
/// stays bounded. The output is the same as [`plan_sequential`]'s, byte for byte.
pub fn plan<R: BufRead + Send, W: Write>(
    reader: R,
    writer: W,
    dialect: Dialect,
    settings: Settings,
) -> Result<u64, PlanOutputError> {
    plan_counted(reader, writer, dialect, settings).map(|written| written.items)
}

/// What [`plan_counted`] wrote.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Written {
    /// Items (moves and events).
    pub items: u64,
    /// Moves only: 0 for a program without motion.
    pub moves: u64,
}

/// [`plan`], returning the number of items and of moves written.
pub fn plan_counted<R: BufRead + Send, W: Write>(
    reader: R,
    writer: W,
    dialect: Dialect,
    settings: Settings,
) -> Result<Written, PlanOutputError> {
    let (to_writer, from_interpreter) = mpsc::sync_channel::<Batch>(QUEUE_BATCHES);
    std::thread::scope(|scope| {
        let interpreter = scope.spawn(move || {
            let mut batch = Vec::with_capacity(BATCH_ITEMS);
            for item in Interpreter::new(reader, dialect, settings) {
                let failed = item.is_err();
                batch.push(item);
                if failed {
                    break;
                }
                if batch.len() == BATCH_ITEMS {
                    let full = std::mem::replace(&mut batch, Vec::with_capacity(BATCH_ITEMS));
                    // The writer has gone (an output error); there is nobody to resolve for.
                    if to_writer.send(full).is_err() {
                        return;
                    }
                }
            }
            let _ = to_writer.send(batch);
        });
        // The receiver is consumed here and dropped on return, which stops the interpreter
        // thread at its next batch if the output failed early.
        let written = write_items(from_interpreter.into_iter().flatten(), writer);
        // A panic in the front end (a bug: it must not panic on any input) closes the queue
        // like the end of the program would; joining tells the two apart, so a cut-short
        // output is never reported as a success.
        match interpreter.join() {
            Ok(()) => written,
            Err(_) => Err(PlanOutputError::Interrupted),
        }
    })
}

/// Like [`plan`], on the calling thread only.
pub fn plan_sequential<R: BufRead, W: Write>(
    reader: R,
    writer: W,
    dialect: Dialect,
    settings: Settings,
) -> Result<u64, PlanOutputError> {
    write_items(Interpreter::new(reader, dialect, settings), writer).map(|written| written.items)
}

/// Items handed from the interpreter thread to the writer in one go.
type Batch = Vec<Result<Item, Diagnostic>>;

/// Items per batch: large enough that the queue costs nothing per item.
const BATCH_ITEMS: usize = 1024;

/// Batches in flight: bounds the memory between the two threads to a few hundred KiB.
const QUEUE_BATCHES: usize = 4;

/// Writes items until the first error, then flushes; returns the number of items written.
fn write_items<I, W>(items: I, mut writer: W) -> Result<Written, PlanOutputError>
where
    I: IntoIterator<Item = Result<Item, Diagnostic>>,
    W: Write,
{
    let mut buf: Vec<u8> = Vec::with_capacity(CHUNK_BYTES + 1024);
    let mut json = JsonLines::new();
    let mut count = Written::default();
    let mut failure: Option<PlanOutputError> = None;
    for item in items {
        let is_move = matches!(item, Ok(Item::Move(_)));
        let written = match item {
            Ok(item) => json.write(&mut buf, &item),
            Err(diagnostic) => Err(PlanOutputError::Program(diagnostic)),
        };
        if let Err(e) = written {
            failure = Some(e);
            break;
        }
        count.items += 1;
        count.moves += u64::from(is_move);
        if buf.len() >= CHUNK_BYTES {
            writer.write_all(&buf)?;
            buf.clear();
        }
    }
    // What was accepted before an error still goes out: the consumer must see the prefix.
    writer.write_all(&buf)?;
    writer.flush()?;
    match failure {
        Some(e) => Err(e),
        None => Ok(count),
    }
}

/// Appends the JSON line (with its trailing newline) for `item` to `out`.
///
/// On error `out` is left as it was. A stream of items is written faster by one
/// [`JsonLines`], which reuses the text of each move's end point as the next one's start.
#[cfg(test)]
pub(crate) fn write_item(out: &mut Vec<u8>, item: &Item) -> Result<(), PlanOutputError> {
    JsonLines::new().write(out, item)
}

/// Writes a stream of items as JSON lines.
///
/// Consecutive moves share a point (each starts where the previous one ended), so the
/// formatted end point is kept and copied instead of formatting the same numbers twice.
#[derive(Debug, Default)]
pub struct JsonLines {
    /// Bit patterns of the last move's end point, if its text is in `end_text`.
    end_bits: Option<[u64; 3]>,
    /// The JSON text of the last move's end point, `[x,y,z]`.
    end_text: Vec<u8>,
}

impl JsonLines {
    /// A writer with nothing written yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// Appends the JSON line (with its trailing newline) for `item` to `out`.
    ///
    /// On error `out` is left as it was.
    pub fn write(&mut self, out: &mut Vec<u8>, item: &Item) -> Result<(), PlanOutputError> {
        let mark = out.len();
        let mut w = JsonWriter {
            out,
            floats: zmij::Buffer::new(),
            finite: true,
            cache: self,
        };
        let line = match item {
            Item::Move(m) => {
                w.write_move(m);
                m.line
            }
            Item::Event(e) => {
                w.write_event(e);
                e.line
            }
        };
        if w.finite {
            Ok(())
        } else {
            out.truncate(mark);
            self.end_bits = None;
            Err(PlanOutputError::NonFinite { line })
        }
    }
}

fn bits(v: &Vec3) -> [u64; 3] {
    [v.x.to_bits(), v.y.to_bits(), v.z.to_bits()]
}

/// The largest magnitude printed through the integer fast path: well inside the range
/// where every integer is exact in `f64` and printed without an exponent.
const INTEGER_FAST_PATH_LIMIT: f64 = 1e15;

/// `v == v.trunc() && v.abs() < INTEGER_FAST_PATH_LIMIT` without `trunc`, a library call
/// on baseline x86-64: below the limit the conversion to `i64` truncates exactly.
fn whole_below_limit(v: f64) -> bool {
    v.abs() < INTEGER_FAST_PATH_LIMIT && (v as i64) as f64 == v
}

struct JsonWriter<'a> {
    out: &'a mut Vec<u8>,
    floats: zmij::Buffer,
    /// Cleared when a non-finite number was met; the caller discards the line then.
    finite: bool,
    cache: &'a mut JsonLines,
}

impl JsonWriter<'_> {
    fn raw(&mut self, s: &str) {
        self.out.extend_from_slice(s.as_bytes());
    }

    fn uint(&mut self, v: u32) {
        let mut b = itoa::Buffer::new();
        self.out.extend_from_slice(b.format(v).as_bytes());
    }

    fn float(&mut self, v: f64) {
        if whole_below_limit(v) {
            // Whole numbers are common in G-code (X10, Y0) and print three times faster
            // as integers; the text is the same as the general path's (`10.0`, `-0.0`).
            if v == 0.0 {
                self.raw(if v.is_sign_negative() { "-0.0" } else { "0.0" });
            } else {
                let mut b = itoa::Buffer::new();
                // The value is integral and below 1e15, so the conversion is exact.
                self.out.extend_from_slice(b.format(v as i64).as_bytes());
                self.raw(".0");
            }
        } else if v.is_finite() {
            self.out
                .extend_from_slice(self.floats.format_finite(v).as_bytes());
        } else {
            self.finite = false;
            self.raw("null");
        }
    }

    fn opt_float(&mut self, v: Option<f64>) {
        match v {
            Some(v) => self.float(v),
            None => self.raw("null"),
        }
    }

    fn triple(&mut self, v: [f64; 3]) {
        self.raw("[");
        self.float(v[0]);
        self.raw(",");
        self.float(v[1]);
        self.raw(",");
        self.float(v[2]);
        self.raw("]");
    }

    fn vec3(&mut self, v: &Vec3) {
        self.triple([v.x, v.y, v.z]);
    }

    /// A move's start: usually the previous move's end, whose text is reused.
    fn start_point(&mut self, p: &Vec3) {
        if self.cache.end_bits == Some(bits(p)) {
            self.out.extend_from_slice(&self.cache.end_text);
        } else {
            self.vec3(p);
        }
    }

    /// A move's end, remembered for the next move's start.
    fn end_point(&mut self, p: &Vec3) {
        let mark = self.out.len();
        self.vec3(p);
        self.cache.end_text.clear();
        self.cache.end_text.extend_from_slice(&self.out[mark..]);
        self.cache.end_bits = Some(bits(p));
    }

    fn write_move(&mut self, m: &Move) {
        match &m.path {
            Path::Line(l) => {
                self.raw("{\"type\":\"line\",\"line\":");
                self.uint(m.line);
                self.raw(if m.rapid {
                    ",\"rapid\":true,\"start\":"
                } else {
                    ",\"rapid\":false,\"start\":"
                });
                self.start_point(&l.start);
                self.raw(",\"end\":");
                self.end_point(&l.end);
            }
            Path::Arc(a) => {
                self.raw("{\"type\":\"arc\",\"line\":");
                self.uint(m.line);
                self.raw(",\"start\":");
                self.start_point(&a.start);
                self.raw(",\"end\":");
                self.end_point(&a.end);
                self.raw(",\"center\":");
                self.vec3(&a.center);
                self.raw(",\"axis\":");
                self.vec3(&a.axis);
                self.raw(",\"sweep_rad\":");
                self.float(a.sweep_rad);
            }
        }
        self.raw(",\"feed_mm_min\":");
        // A rapid has no programmed feed by definition, whatever F is modal.
        self.opt_float(if m.rapid { None } else { m.feed_mm_min });
        if let Some((abc_start, abc_end)) = m.abc_deg {
            self.raw(",\"abc_start\":");
            self.triple(abc_start);
            self.raw(",\"abc_end\":");
            self.triple(abc_end);
        }
        self.raw("}\n");
    }

    fn write_event(&mut self, e: &Event) {
        self.raw("{\"type\":\"event\",\"line\":");
        self.uint(e.line);
        self.raw(",\"code\":\"");
        self.raw(e.code.as_str());
        self.raw("\",\"value\":");
        self.opt_float(e.value);
        if let Some(p) = e.p {
            self.raw(",\"p\":");
            self.float(p);
        }
        if let Some(q) = e.q {
            self.raw(",\"q\":");
            self.float(q);
        }
        match e.code {
            EventCode::M66 => self.raw(",\"input\":\"digital\""),
            EventCode::M66Analog => self.raw(",\"input\":\"analog\""),
            _ => {}
        }
        if let Some(text) = &e.text {
            self.raw(",\"text\":");
            self.string(text);
        }
        self.raw("}\n");
    }

    /// A JSON string (RFC 8259 section 7): quote, backslash and control characters
    /// escaped, everything else (valid UTF-8) as it is.
    fn string(&mut self, s: &str) {
        self.raw("\"");
        for c in s.chars() {
            match c {
                '"' => self.raw("\\\""),
                '\\' => self.raw("\\\\"),
                '\n' => self.raw("\\n"),
                '\r' => self.raw("\\r"),
                '\t' => self.raw("\\t"),
                c if (c as u32) < 0x20 => {
                    let code = format!("\\u{:04x}", c as u32);
                    self.raw(&code);
                }
                c => {
                    let mut buf = [0u8; 4];
                    self.raw(c.encode_utf8(&mut buf));
                }
            }
        }
        self.raw("\"");
    }
}

/// Chooses the dialect of a program.
///
/// The rule, most specific first:
/// 1. `--dialect` on the command line;
/// 2. the program file's extension where it names one control unambiguously (`.ngc`
///    LinuxCNC, `.mpf`/`.spf` Sinumerik, `.pim` Fagor, `.h`/`.i` Heidenhain when the file
///    is ISO), judged by [`Dialect::from_path`] from the path and the first bytes of the
///    file;
/// 3. the configuration's `dialect` (the machine's own control);
/// 4. LinuxCNC.
///
/// The extension beats the configuration because it describes the program itself, while the
/// configuration describes the machine's default: a Sinumerik `.mpf` file stays Sinumerik
/// on any machine, and programs whose extension says nothing (`.nc`, `.tap`, standard
/// input) take the machine's dialect.
pub fn choose_dialect(
    command_line: Option<Dialect>,
    program: Option<(&std::path::Path, &[u8])>,
    config: Option<Dialect>,
) -> Dialect {
    choose_dialect_from(command_line, program, config).0
}

/// Which rule of [`choose_dialect`] chose a program's dialect.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DialectSource {
    /// `--dialect` on the command line.
    CommandLine,
    /// The program file's extension.
    Extension,
    /// The configuration's `dialect`.
    Config,
    /// Nothing chose one: LinuxCNC, the default.
    Default,
}

/// [`choose_dialect`], with the rule that chose: a program that fails in a dialect nobody
/// chose gets a note saying which one was assumed and how to choose another
/// ([`assumed_dialect_note`]).
pub fn choose_dialect_from(
    command_line: Option<Dialect>,
    program: Option<(&std::path::Path, &[u8])>,
    config: Option<Dialect>,
) -> (Dialect, DialectSource) {
    if let Some(d) = command_line {
        (d, DialectSource::CommandLine)
    } else if let Some(d) = program.and_then(|(path, head)| Dialect::from_path(path, head)) {
        (d, DialectSource::Extension)
    } else if let Some(d) = config {
        (d, DialectSource::Config)
    } else {
        (Dialect::LinuxCnc, DialectSource::Default)
    }
}

/// The line added under an error in a program whose dialect was assumed by default.
pub fn assumed_dialect_note(dialect: Dialect) -> String {
    let known: Vec<&str> = Dialect::ALL.iter().map(|d| d.name()).collect();
    format!(
        "note: read as {} (the default); choose another with --dialect D ({}) or `dialect` in the configuration",
        dialect.name(),
        known.join(", ")
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use kerf_gcode::{Arc, CornerMode, EventCode, Line};

    fn line_move(rapid: bool, feed: Option<f64>) -> Move {
        Move {
            line: 7,
            rapid,
            path: Path::Line(Line {
                start: Vec3::new(0.0, 0.0, 0.0),
                end: Vec3::new(1.5, -2.0, 0.1),
            }),
            feed_mm_min: feed,
            abc_deg: None,
            corner: CornerMode::ExactStop,
        }
    }

    fn text(item: &Item) -> String {
        let mut buf = Vec::new();
        write_item(&mut buf, item).unwrap();
        String::from_utf8(buf).unwrap()
    }

    #[test]
    fn feed_line_matches_the_contract() {
        assert_eq!(
            text(&Item::Move(line_move(false, Some(300.0)))),
            "{\"type\":\"line\",\"line\":7,\"rapid\":false,\"start\":[0.0,0.0,0.0],\"end\":[1.5,-2.0,0.1],\"feed_mm_min\":300.0}\n"
        );
    }

    #[test]
    fn rapid_has_null_feed_even_if_one_is_modal() {
        assert_eq!(
            text(&Item::Move(line_move(true, Some(300.0)))),
            "{\"type\":\"line\",\"line\":7,\"rapid\":true,\"start\":[0.0,0.0,0.0],\"end\":[1.5,-2.0,0.1],\"feed_mm_min\":null}\n"
        );
    }

    #[test]
    fn arc_with_rotary_axes_matches_the_contract() {
        let m = Move {
            line: 12,
            rapid: false,
            path: Path::Arc(Arc {
                start: Vec3::new(10.0, 0.0, 0.0),
                end: Vec3::new(0.0, 10.0, -1.0),
                center: Vec3::new(0.0, 0.0, 0.0),
                axis: Vec3::new(0.0, 0.0, 1.0),
                sweep_rad: std::f64::consts::FRAC_PI_2,
            }),
            feed_mm_min: Some(1200.0),
            abc_deg: Some(([0.0, 0.0, 90.0], [0.0, 0.0, 180.0])),
            corner: CornerMode::Blend {
                tolerance_mm: None,
                naive_cam_mm: None,
            },
        };
        assert_eq!(
            text(&Item::Move(m)),
            "{\"type\":\"arc\",\"line\":12,\"start\":[10.0,0.0,0.0],\"end\":[0.0,10.0,-1.0],\"center\":[0.0,0.0,0.0],\"axis\":[0.0,0.0,1.0],\"sweep_rad\":1.5707963267948966,\"feed_mm_min\":1200.0,\"abc_start\":[0.0,0.0,90.0],\"abc_end\":[0.0,0.0,180.0]}\n"
        );
    }

    #[test]
    fn events_carry_their_value() {
        let m3 = Event::new(3, EventCode::M3, None);
        assert_eq!(
            text(&Item::Event(m3)),
            "{\"type\":\"event\",\"line\":3,\"code\":\"M3\",\"value\":null}\n"
        );
        let s = Event::new(4, EventCode::S, Some(12000.0));
        assert_eq!(
            text(&Item::Event(s)),
            "{\"type\":\"event\",\"line\":4,\"code\":\"S\",\"value\":12000.0}\n"
        );
    }

    #[test]
    fn io_events_carry_p_q_and_the_kind_of_input() {
        let m62 = Event::new(9, EventCode::M62, Some(2.0));
        assert_eq!(
            text(&Item::Event(m62)),
            "{\"type\":\"event\",\"line\":9,\"code\":\"M62\",\"value\":2.0}\n"
        );
        let mut m66 = Event::new(10, EventCode::M66, Some(1.0));
        (m66.p, m66.q) = (Some(3.0), Some(2.5));
        assert_eq!(
            text(&Item::Event(m66)),
            "{\"type\":\"event\",\"line\":10,\"code\":\"M66\",\"value\":1.0,\"p\":3.0,\"q\":2.5,\"input\":\"digital\"}\n"
        );
        let mut analog = Event::new(11, EventCode::M66Analog, Some(4.0));
        analog.p = Some(0.0);
        assert_eq!(
            text(&Item::Event(analog)),
            "{\"type\":\"event\",\"line\":11,\"code\":\"M66\",\"value\":4.0,\"p\":0.0,\"input\":\"analog\"}\n"
        );
        let mut m68 = Event::new(12, EventCode::M68, Some(0.0));
        m68.q = Some(-1.25);
        assert_eq!(
            text(&Item::Event(m68)),
            "{\"type\":\"event\",\"line\":12,\"code\":\"M68\",\"value\":0.0,\"q\":-1.25}\n"
        );
    }

    #[test]
    fn user_m_codes_and_messages_carry_q_and_text() {
        let mut user = Event::new(5, EventCode::User(1), Some(3.0));
        user.q = Some(-4.5);
        assert_eq!(
            text(&Item::Event(user)),
            "{\"type\":\"event\",\"line\":5,\"code\":\"M101\",\"value\":3.0,\"q\":-4.5}\n"
        );
        let mut msg = Event::new(6, EventCode::Msg, None);
        msg.text = Some("say \"hi\" \\ tab\t\u{1}é".into());
        assert_eq!(
            text(&Item::Event(msg)),
            "{\"type\":\"event\",\"line\":6,\"code\":\"MSG\",\"value\":null,\"text\":\"say \\\"hi\\\" \\\\ tab\\t\\u0001é\"}\n"
        );
        let mut log = Event::new(8, EventCode::Log, None);
        log.text = Some("LOG,X1.000000".into());
        assert_eq!(
            text(&Item::Event(log)),
            "{\"type\":\"event\",\"line\":8,\"code\":\"LOG\",\"value\":null,\"text\":\"LOG,X1.000000\"}\n"
        );
        let m60 = Event::new(7, EventCode::M60, None);
        assert_eq!(
            text(&Item::Event(m60)),
            "{\"type\":\"event\",\"line\":7,\"code\":\"M60\",\"value\":null}\n"
        );
    }

    /// The JSON number grammar (RFC 8259 section 6), checked by hand.
    fn is_json_number(s: &str) -> bool {
        let b = s.as_bytes();
        let mut i = 0;
        let digits = |i: &mut usize| {
            let start = *i;
            while *i < b.len() && b[*i].is_ascii_digit() {
                *i += 1;
            }
            *i > start
        };
        if b.get(i) == Some(&b'-') {
            i += 1;
        }
        match b.get(i) {
            Some(b'0') => i += 1,
            Some(b'1'..=b'9') => {
                digits(&mut i);
            }
            _ => return false,
        }
        if b.get(i) == Some(&b'.') {
            i += 1;
            if !digits(&mut i) {
                return false;
            }
        }
        if matches!(b.get(i), Some(b'e' | b'E')) {
            i += 1;
            if matches!(b.get(i), Some(b'+' | b'-')) {
                i += 1;
            }
            if !digits(&mut i) {
                return false;
            }
        }
        i == b.len()
    }

    #[test]
    fn json_number_grammar_check_rejects_non_numbers() {
        for bad in [
            "", "+1", ".5", "1.", "01", "inf", "NaN", "1e", "--1", "1.0x",
        ] {
            assert!(!is_json_number(bad), "{bad}");
        }
        for good in ["0", "-0.0", "1e+16", "2.5E-7", "10"] {
            assert!(is_json_number(good), "{good}");
        }
    }

    #[test]
    fn floats_round_trip_exactly() {
        // Values chosen to need every digit, tiny and huge magnitudes, and negative zero.
        let values = [
            0.1 + 0.2,
            1.0 / 3.0,
            -2.5e-7,
            1e16,
            123_456_789.123_456_78,
            f64::MIN_POSITIVE,
            f64::MAX,
            -0.0,
            5e-324,
            7.0,
            -300.0,
            999_999_999_999_999.0,
            1e15,
            -4503599627370497.0,
        ];
        for v in values {
            let mut cache = JsonLines::new();
            let mut w = JsonWriter {
                out: &mut Vec::new(),
                floats: zmij::Buffer::new(),
                finite: true,
                cache: &mut cache,
            };
            w.float(v);
            let s = String::from_utf8(w.out.clone()).unwrap();
            let back: f64 = s.parse().unwrap();
            assert_eq!(back.to_bits(), v.to_bits(), "{v} printed as {s}");
            assert!(is_json_number(&s), "{v} printed as {s}, not a JSON number");
        }
    }

    #[test]
    fn integer_fast_path_prints_what_the_general_path_prints() {
        for v in [
            1.0,
            -1.0,
            10.0,
            300.0,
            12000.0,
            -7.0,
            123_456_789_012.0,
            0.0,
            -0.0,
        ] {
            let mut cache = JsonLines::new();
            let mut w = JsonWriter {
                out: &mut Vec::new(),
                floats: zmij::Buffer::new(),
                finite: true,
                cache: &mut cache,
            };
            w.float(v);
            let general = zmij::Buffer::new().format_finite(v).to_string();
            assert_eq!(String::from_utf8(w.out.clone()).unwrap(), general, "{v}");
        }
    }

    #[test]
    fn whole_below_limit_is_the_trunc_test() {
        let mut values = vec![
            0.0,
            -0.0,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::MIN_POSITIVE,
            5e-324,
            f64::MAX,
            f64::MIN,
            INTEGER_FAST_PATH_LIMIT,
            -INTEGER_FAST_PATH_LIMIT,
            9_007_199_254_740_993.0,
            i64::MAX as f64,
            i64::MIN as f64,
        ];
        for i in -4000..4000 {
            let x = f64::from(i);
            values.extend([x, x * 0.25, x / 3.0, x * 1e11 + 0.5, x * 2.5e11]);
            let l = INTEGER_FAST_PATH_LIMIT + x * 0.125;
            values.extend([l, -l, f64::from_bits(l.to_bits() ^ 1)]);
        }
        for v in values {
            let trunc = v == v.trunc() && v.abs() < INTEGER_FAST_PATH_LIMIT;
            assert_eq!(whole_below_limit(v), trunc, "{v:e}");
        }
    }

    #[test]
    fn reused_end_points_give_the_same_text_as_fresh_formatting() {
        let a = line_move(false, Some(100.0));
        let mut b = line_move(false, Some(100.0));
        if let Path::Line(l) = &mut b.path {
            l.start = Vec3::new(1.5, -2.0, 0.1);
            l.end = Vec3::new(-0.0, 1.0 / 3.0, 0.1);
        }
        // Starts at +0.0 where the previous move ended at -0.0: a different number in
        // JSON, so the cached text must not be used.
        let mut c = line_move(true, None);
        if let Path::Line(l) = &mut c.path {
            l.start = Vec3::new(0.0, 1.0 / 3.0, 0.1);
        }
        let event = Item::Event(Event::new(8, EventCode::M5, None));
        let items = [
            Item::Move(a),
            event,
            Item::Move(b),
            Item::Move(c),
            Item::Move(a),
        ];
        let mut streamed = Vec::new();
        let mut json = JsonLines::new();
        let mut one_by_one = Vec::new();
        for item in &items {
            json.write(&mut streamed, item).unwrap();
            write_item(&mut one_by_one, item).unwrap();
        }
        assert_eq!(
            String::from_utf8(streamed).unwrap(),
            String::from_utf8(one_by_one).unwrap()
        );
    }

    #[test]
    fn non_finite_number_is_an_error_and_writes_nothing() {
        let mut buf = b"kept".to_vec();
        let mut m = line_move(false, Some(f64::NAN));
        m.line = 9;
        match write_item(&mut buf, &Item::Move(m)) {
            Err(PlanOutputError::NonFinite { line: 9 }) => {}
            other => panic!("unexpected {other:?}"),
        }
        assert_eq!(buf, b"kept");
    }

    /// A program long enough to fill many batches, with an error near its end.
    fn long_program(blocks: usize, error_at_end: bool) -> String {
        let mut text = String::from("G21 G90 G17 F1000\n");
        for i in 0..blocks {
            text.push_str(&format!("G1 X{} Y{}\n", i % 50 + 1, i % 7));
            if i % 3 == 0 {
                text.push_str("M8\n");
            }
        }
        if error_at_end {
            // A 1 mm radius cannot reach a point 100 mm away.
            text.push_str("G2 X200 Y0 R1\nG1 X0\n");
        }
        // A LinuxCNC program ends with M2.
        text.push_str("M2\n");
        text
    }

    #[test]
    fn threaded_plan_matches_sequential_plan() {
        for error_at_end in [false, true] {
            let text = long_program(5000, error_at_end);
            let mut threaded = Vec::new();
            let mut sequential = Vec::new();
            let a = plan(
                text.as_bytes(),
                &mut threaded,
                Dialect::LinuxCnc,
                Settings::default(),
            );
            let b = plan_sequential(
                text.as_bytes(),
                &mut sequential,
                Dialect::LinuxCnc,
                Settings::default(),
            );
            assert_eq!(threaded, sequential);
            let lines = threaded.iter().filter(|&&c| c == b'\n').count() as u64;
            // 5000 lines plus an M8 event on every third, and the M2 event at the end
            // (not reached after an error).
            let m2 = u64::from(!error_at_end);
            assert_eq!(lines, 5000 + 1667 + m2);
            match (a, b, error_at_end) {
                (Ok(n), Ok(m), false) => assert_eq!((n, m), (lines, lines)),
                (Err(PlanOutputError::Program(d)), Err(PlanOutputError::Program(e)), true) => {
                    assert_eq!(d, e);
                    assert_eq!(d.line, 1 + 5000 + 1667 + 1);
                }
                other => panic!("unexpected {other:?}"),
            }
        }
    }

    /// A writer that accepts `room` bytes and then fails like a closed pipe.
    struct ClosingPipe {
        room: usize,
    }

    impl Write for ClosingPipe {
        fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
            if self.room == 0 {
                return Err(io::Error::from(io::ErrorKind::BrokenPipe));
            }
            let n = buf.len().min(self.room);
            self.room -= n;
            Ok(n)
        }

        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn output_failure_stops_the_interpreter_thread() {
        let text = long_program(100_000, false);
        let result = plan(
            text.as_bytes(),
            ClosingPipe { room: 1000 },
            Dialect::LinuxCnc,
            Settings::default(),
        );
        match result {
            Err(PlanOutputError::Output(e)) => assert_eq!(e.kind(), io::ErrorKind::BrokenPipe),
            other => panic!("unexpected {other:?}"),
        }
    }

    /// A reader that serves `data` and then panics instead of reporting the end, standing in
    /// for a bug in the front end.
    struct PanicsAtEnd {
        data: Vec<u8>,
        at: usize,
    }

    impl io::Read for PanicsAtEnd {
        fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
            let rest = &self.data[self.at..];
            assert!(!rest.is_empty(), "simulated front-end bug");
            let n = rest.len().min(buf.len());
            buf[..n].copy_from_slice(&rest[..n]);
            self.at += n;
            Ok(n)
        }
    }

    #[test]
    fn a_panicking_interpreter_is_an_error_not_a_short_success() {
        let reader = io::BufReader::new(PanicsAtEnd {
            // Without its M2, so that the interpreter reads on to the end of the input.
            data: long_program(3000, false).replace("M2\n", "").into_bytes(),
            at: 0,
        });
        let mut out = Vec::new();
        let result = plan(reader, &mut out, Dialect::LinuxCnc, Settings::default());
        assert!(
            matches!(result, Err(PlanOutputError::Interrupted)),
            "{result:?}"
        );
    }

    #[test]
    fn dialect_precedence() {
        use std::path::Path as FsPath;
        let mpf = FsPath::new("part.mpf");
        let nc = FsPath::new("part.nc");
        let heidenhain = Some(Dialect::Heidenhain);
        // The command line wins over everything.
        assert_eq!(
            choose_dialect(Some(Dialect::Fagor), Some((mpf, b"")), heidenhain),
            Dialect::Fagor
        );
        // Without a command-line choice, the configured machine dialect applies to a file
        // whose extension says nothing, and LinuxCNC is the last resort.
        assert_eq!(
            choose_dialect(None, Some((nc, b"")), heidenhain),
            Dialect::Heidenhain
        );
        assert_eq!(choose_dialect(None, None, heidenhain), Dialect::Heidenhain);
        assert_eq!(
            choose_dialect(None, Some((nc, b"")), None),
            Dialect::LinuxCnc
        );
        // An extension that names a control, when the front end recognises it, beats the
        // configuration.
        if let Some(by_extension) = Dialect::from_path(mpf, b"G1 X1\n") {
            assert_eq!(
                choose_dialect(None, Some((mpf, b"G1 X1\n")), heidenhain),
                by_extension
            );
        }
    }
}
