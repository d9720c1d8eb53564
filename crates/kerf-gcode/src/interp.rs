//! Modal state and per-dialect resolution of blocks into moves and events.

use kerf_geom::{CornerMode, Vec3};

use crate::arc::Plane;
use crate::codes::*;
use crate::lex::{Form, K_AP, K_AT, K_CARET, K_CR, K_RP, K_TURN, N_KEYS, Word};
use crate::{Dialect, Event, EventCode, Item, Settings, Tool};

mod comp;
pub(crate) mod cycles;
mod geometry;
mod modal;
mod offsets;
pub(crate) mod params;
mod query;

pub(crate) use modal::FeedMode;
pub(crate) use modal::linuxcnc_m_refusal_of;
use modal::{ModalFrame, Spindle, StateOp};
pub(crate) use offsets::ToolLength;

const MM_PER_INCH: f64 = 25.4;

/// The most tools a program may define with Heidenhain G99.
const MAX_TOOLS: usize = 10_000;

/// The longest dwell accepted, in the unit of the dwell word (seconds; spindle revolutions
/// for Sinumerik `G4 S`): 1e6 s is eleven and a half days, far beyond any dwell a part
/// needs (the ISO dwell word of Fanuc-style controls stops at 99,999.999 s) and short of
/// the values at which adding it to a clock loses precision.
const MAX_DWELL: f64 = 1e6;

/// The words that describe motion or geometry: a dwell block may not hold them, except
/// in LinuxCNC, where the motion runs after the dwell.
const MOTION_WORDS: [u8; 18] = [
    KX, KY, KZ, KA, KB, KC, KI, KJ, KK, KR, KQ, KH, K_CR, K_TURN, K_RP, K_AP, K_AT, K_CARET,
];

/// The LinuxCNC words a motion uses (H and Q belong to G43 and G64 there).
const LINUXCNC_MOTION_WORDS: [u8; 12] = [KX, KY, KZ, KA, KB, KC, KI, KJ, KK, KR, K_AT, K_CARET];

pub(crate) use crate::lex::BlockError;

fn fail<T>(col: u32, message: impl Into<String>) -> Result<T, BlockError> {
    Err(BlockError {
        col,
        message: message.into(),
    })
}

/// The words of one block, indexed by key. Values are only meaningful where `present`
/// has the key's bit set, so a block is reset by clearing one integer.
pub(crate) struct Block {
    present: u32,
    vals: [f64; N_KEYS],
    cols: [u32; N_KEYS],
    forms: [Form; N_KEYS],
    gs: [(u16, u32); 16],
    ng: usize,
    ms: [(u16, u32); 8],
    nm: usize,
    first_col: u32,
}

impl Block {
    pub(crate) fn new() -> Self {
        Block {
            present: 0,
            vals: [0.0; N_KEYS],
            cols: [0; N_KEYS],
            forms: [Form::Plain; N_KEYS],
            gs: [(0, 0); 16],
            ng: 0,
            ms: [(0, 0); 8],
            nm: 0,
            first_col: 1,
        }
    }

    fn has(&self, k: u8) -> bool {
        self.present & (1 << k) != 0
    }

    fn get(&self, k: u8) -> Option<f64> {
        if self.has(k) {
            Some(self.vals[k as usize])
        } else {
            None
        }
    }

    fn col(&self, k: u8) -> u32 {
        self.cols[k as usize]
    }

    fn any(&self, keys: &[u8]) -> bool {
        keys.iter().any(|&k| self.has(k))
    }

    fn first_of(&self, keys: &[u8]) -> Option<u8> {
        keys.iter().copied().find(|&k| self.has(k))
    }
}

/// Interpreter state carried from block to block.
pub(crate) struct State {
    dialect: Dialect,
    settings: Settings,
    /// Current position, machine mm.
    pos: Vec3,
    abc: [f64; 3],
    abc_used: bool,
    inch: bool,
    feed_inch: bool,
    absolute: bool,
    arc_absolute: bool,
    plane: Plane,
    motion: Option<Motion>,
    feed_mm_min: Option<f64>,
    corner: CornerMode,
    comp: Comp,
    tool_selected: Option<u32>,
    tool_loaded: Option<u32>,
    /// The last programmed spindle speed, rpm (Sinumerik `G4 S` dwells in revolutions;
    /// LinuxCNC G95 feeds per revolution of it).
    spindle_rpm: Option<f64>,
    /// LinuxCNC feed mode G93/G94/G95.
    feed_mode: FeedMode,
    /// LinuxCNC G95: the feed per spindle revolution, mm.
    feed_mm_rev: Option<f64>,
    /// The spindle (M3/M4/M5) and coolant (M7, M8; M9 both off) as programmed.
    spindle: Spindle,
    mist: bool,
    flood: bool,
    /// LinuxCNC M70–M73: the saved modal state of each call level (the program first).
    modal_frames: Vec<ModalFrame>,
    /// G43 is in force (G49 not).
    tool_length_on: bool,
    /// The tool offsets in effect (G43 family): X, Y, Z mm, A, B, C degrees (LinuxCNC
    /// applies every axis of the entry; the other controls Z only).
    tool_offset: [f64; 6],
    /// LinuxCNC: the tool offsets in effect when the last move was made. rs274 reads its
    /// position back after a tool change from the last point it printed, which follows the
    /// moves and the work offsets but not the tool offsets changed since.
    tool_offset_at_move: [f64; 6],
    /// LinuxCNC: an M6 ran in the block being executed.
    m6_in_block: bool,
    /// LinuxCNC: after a tool change whose read-back moved the current point (see
    /// `tool_offset_at_move`), where the machine really is (XYZ, ABC): the next move
    /// starts there.
    readback_from: Option<(Vec3, [f64; 3])>,
    /// The active coordinate system (0 = G54), `None` for none (Sinumerik G500).
    coord_system: Option<usize>,
    /// Program zero in frame coordinates (work offset + G52/G92 + tool offset), cached
    /// from the parameters by `update_origin`.
    origin: Vec3,
    /// Program zero of A, B, C, degrees (work offset + G52/G92 + tool offset).
    origin_abc: [f64; 3],
    /// LinuxCNC: the XY rotation of the active coordinate system, degrees (G10 L2 R).
    rotation_deg: f64,
    /// The centre of that rotation, machine X and Y (work offset + tool offset).
    rotation_center: [f64; 2],
    /// Sinumerik pole, machine coordinates (`None` = workpiece zero).
    pole: Option<Vec3>,
    /// Sinumerik stored RP (mm) and AP (degrees).
    rp_mm: Option<f64>,
    ap_deg: Option<f64>,
    /// Heidenhain circle centre and pole (machine coordinates).
    cc: Option<Vec3>,
    /// Fagor polar origin (machine coordinates; `None` = part zero).
    polar_origin: Option<Vec3>,
    /// Last programmed polar radius (mm) and angle (degrees) about the pole, while the
    /// position still is that polar point and the pole has not moved (Heidenhain, Fagor;
    /// LinuxCNC always measures the current point).
    polar_last: Option<(f64, f64)>,
    /// Direction of the last arc (`true` = counter-clockwise), for Heidenhain G05/G15.
    last_ccw: Option<bool>,
    /// A Heidenhain `%` header has been read.
    header_seen: bool,
    /// The program has ended (M2/M30 or a Heidenhain end line).
    pub(crate) done: bool,
    /// LinuxCNC numbered parameters (read and written by the expression language and by
    /// the codes whose data lives in parameters: work offsets, G92, G28/G30, tools).
    pub(crate) params: params::Params,
    /// LinuxCNC canned cycles: sticky words, initial level, spindle direction.
    cycles: cycles::CycleState,
    /// LinuxCNC G99 (canned cycles retract to R, the default of rs274) rather than G98
    /// (to the initial level).
    retract_r: bool,
    /// LinuxCNC cutter radius compensation (side, radius, programmed point, held moves).
    crc: comp::Crc,
    /// LinuxCNC: the block being run holds M19, whose R word is its angle.
    m19_in_block: bool,
    /// LinuxCNC: the end of an arc whose end lies on the ray from its centre through its
    /// start, reached by a radial line after the whole turn (`geometry::arc_path`).
    arc_tail: Option<Vec3>,
}

/// Output of a block, in execution order.
pub(crate) struct Out<'a> {
    pub items: &'a mut Vec<Item>,
    pub line: u32,
}

impl Out<'_> {
    fn event(&mut self, code: EventCode, value: Option<f64>) {
        self.items
            .push(Item::Event(Event::new(self.line, code, value)));
    }
}

impl State {
    pub(crate) fn dialect(&self) -> Dialect {
        self.dialect
    }

    /// The block delete switch ([`Settings::block_delete`]).
    pub(crate) fn block_delete(&self) -> bool {
        self.settings.block_delete
    }

    pub(crate) fn new(dialect: Dialect, settings: Settings) -> Self {
        let coord_system = match dialect {
            Dialect::LinuxCnc | Dialect::Rockwell | Dialect::Fagor => Some(0),
            Dialect::Sinumerik | Dialect::Heidenhain => None,
        };
        let motion = match dialect {
            Dialect::LinuxCnc | Dialect::Heidenhain => None,
            Dialect::Rockwell => Some(Motion::Linear),
            Dialect::Sinumerik | Dialect::Fagor => Some(Motion::Rapid),
        };
        let start = settings.start_mm_deg;
        let mut s = State {
            dialect,
            settings,
            pos: Vec3::new(start[0], start[1], start[2]),
            abc: [start[3], start[4], start[5]],
            abc_used: false,
            inch: false,
            feed_inch: false,
            absolute: true,
            arc_absolute: false,
            plane: Plane::Xy,
            motion,
            feed_mm_min: None,
            corner: CornerMode::Blend {
                tolerance_mm: None,
                naive_cam_mm: None,
            },
            comp: Comp::Off,
            tool_selected: None,
            spindle_rpm: None,
            feed_mode: FeedMode::PerMinute,
            feed_mm_rev: None,
            spindle: Spindle::Off,
            mist: false,
            flood: false,
            modal_frames: Vec::new(),
            tool_length_on: false,
            tool_loaded: None,
            tool_offset: [0.0; 6],
            tool_offset_at_move: [0.0; 6],
            m6_in_block: false,
            readback_from: None,
            coord_system,
            origin: Vec3::zeros(),
            origin_abc: [0.0; 3],
            rotation_deg: 0.0,
            rotation_center: [0.0; 2],
            pole: None,
            rp_mm: None,
            ap_deg: None,
            cc: None,
            polar_origin: None,
            polar_last: None,
            last_ccw: None,
            header_seen: false,
            done: false,
            params: params::Params::new(),
            cycles: cycles::CycleState::new(),
            retract_r: true,
            crc: comp::Crc::new(),
            m19_in_block: false,
            arc_tail: None,
        };
        s.init_params();
        s.update_origin();
        s
    }

    fn scale(&self) -> f64 {
        if self.inch { MM_PER_INCH } else { 1.0 }
    }

    fn tool(&self, number: Option<u32>) -> Option<&Tool> {
        let n = number?;
        self.settings.tools.iter().find(|t| t.number == n)
    }

    /// Fills `blk` from the lexed words, checking repeats and per-dialect letters.
    pub(crate) fn build_block(&self, words: &[Word], blk: &mut Block) -> Result<(), BlockError> {
        blk.present = 0;
        blk.ng = 0;
        blk.nm = 0;
        blk.first_col = words.first().map_or(1, |w| w.col);
        // Heidenhain lets G90/G91 switch per axis inside a block: the words after a G90 or
        // G91 take that mode, the ones before the first one the modal one (the mode before
        // the block), which exec() would otherwise replace before reading them.
        let mut local: Option<bool> = None;
        let modal = if self.absolute { Form::Abs } else { Form::Inc };
        // The I/O codes Kerf refuses take words it does not know (M67 E0): the code is
        // named first.
        for w in words.iter().filter(|w| w.key == crate::lex::key(b'M')) {
            if let Some(msg) = code10(w.value).and_then(|c| self.linuxcnc_m_refusal(c / 10)) {
                return fail(w.col, msg);
            }
        }
        for w in words {
            let letter = if w.key < 26 { b'A' + w.key } else { 0 };
            match letter {
                b'G' => {
                    if blk.ng == blk.gs.len() {
                        return fail(w.col, "too many G codes in one block");
                    }
                    let code = code10(w.value).ok_or_else(|| BlockError {
                        col: w.col,
                        message: format!("unknown G code G{}", w.value),
                    })?;
                    if self.dialect == Dialect::Heidenhain && (code == 900 || code == 910) {
                        if local.is_none() {
                            for k in 0..N_KEYS as u8 {
                                if blk.has(k)
                                    && takes_distance_mode(k)
                                    && blk.forms[k as usize] == Form::Plain
                                {
                                    blk.forms[k as usize] = modal;
                                }
                            }
                        }
                        local = Some(code == 900);
                    }
                    blk.gs[blk.ng] = (code, w.col);
                    blk.ng += 1;
                    continue;
                }
                b'M' => {
                    if blk.nm == blk.ms.len() {
                        return fail(w.col, "too many M codes in one block");
                    }
                    let code =
                        code10(w.value)
                            .filter(|c| c % 10 == 0)
                            .ok_or_else(|| BlockError {
                                col: w.col,
                                message: format!("unknown M code M{}", w.value),
                            })?;
                    blk.ms[blk.nm] = (code / 10, w.col);
                    blk.nm += 1;
                    continue;
                }
                b'N' => continue,
                _ => {}
            }
            self.check_letter(w)?;
            if blk.has(w.key) {
                return fail(w.col, format!("word {} repeated", key_name(w.key)));
            }
            let k = w.key as usize;
            blk.present |= 1 << w.key;
            blk.vals[k] = w.value;
            blk.cols[k] = w.col;
            blk.forms[k] = match (w.form, local) {
                (Form::Plain, Some(abs)) if takes_distance_mode(w.key) => {
                    if abs {
                        Form::Abs
                    } else {
                        Form::Inc
                    }
                }
                (f, _) => f,
            };
        }
        Ok(())
    }

    fn check_letter(&self, w: &Word) -> Result<(), BlockError> {
        let k = w.key;
        let ok = allowed_keys(self.dialect) & (1u32 << k) != 0;
        if ok {
            return Ok(());
        }
        if matches!(k, 20..=22) {
            return fail(w.col, "U, V and W axes are not supported");
        }
        if self.dialect == Dialect::Sinumerik && k == KR {
            return fail(w.col, "R parameters are not supported yet");
        }
        if self.dialect == Dialect::Heidenhain && k == KQ {
            return fail(w.col, "Q parameters are not supported yet");
        }
        if self.dialect == Dialect::Fagor && k == KP {
            return fail(w.col, "arithmetic parameters (P) are not supported yet");
        }
        fail(w.col, format!("unknown word {}", key_name(k)))
    }

    /// Resolves one block into `out`. On error, the caller discards what this block pushed.
    ///
    /// LinuxCNC: after a block with M6, the current point is read back as rs274 reads it:
    /// the program point of the last move, in which tool offset changes made since that
    /// move (`T1 M6 G43 H1`, or a G43 before the M6) are not yet counted. So the axes the
    /// next move does not name go to that program point with the new offsets, as rs274
    /// prints it (the machine moves by the offset change), and the move starts where the
    /// machine is. (A real LinuxCNC reads back the machine position instead; the issue
    /// makes rs274 the reference.) An arc cannot start at two points: an arc as that next
    /// move, with the point changed, is an error.
    pub(crate) fn exec(
        &mut self,
        blk: &Block,
        percent: bool,
        out: &mut Out<'_>,
    ) -> Result<(), BlockError> {
        let start = out.items.len();
        self.m6_in_block = false;
        let readback = self.readback_from;
        self.exec_block(blk, percent, out)?;
        let mut moved = false;
        if let Some(i) = (start..out.items.len()).find(|&i| matches!(out.items[i], Item::Move(_))) {
            moved = true;
            if let (Some((pos, abc)), Item::Move(m)) = (readback, &mut out.items[i]) {
                match &mut m.path {
                    kerf_geom::Path::Line(l) => l.start = pos,
                    kerf_geom::Path::Arc(a) if (a.start - pos).norm() <= 1e-9 => {}
                    kerf_geom::Path::Arc(_) => {
                        return fail(
                            blk.first_col,
                            "an arc right after a tool change that changed the tool offset is not supported (LinuxCNC reads the position back there; program a straight move first)",
                        );
                    }
                }
                if let Some((s, _)) = &mut m.abc_deg {
                    *s = abc;
                }
            }
        }
        if moved {
            self.readback_from = None;
            self.tool_offset_at_move = self.tool_offset;
        }
        if self.m6_in_block && !moved {
            let delta: [f64; 6] =
                std::array::from_fn(|i| self.tool_offset[i] - self.tool_offset_at_move[i]);
            if delta.iter().any(|&d| d != 0.0) {
                if self.readback_from.is_none() {
                    self.readback_from = Some((self.pos, self.abc));
                }
                for i in 0..3 {
                    self.pos[i] += delta[i];
                    self.abc[i] += delta[i + 3];
                }
                // Seen from the machine, the offsets are now in effect from this point.
                self.tool_offset_at_move = self.tool_offset;
            }
        }
        Ok(())
    }

    fn exec_block(
        &mut self,
        blk: &Block,
        percent: bool,
        out: &mut Out<'_>,
    ) -> Result<(), BlockError> {
        if percent && self.dialect == Dialect::Heidenhain {
            // `%NAME G71 *` opens the program and names its unit; the same line at the end
            // closes it.
            if self.header_seen {
                self.done = true;
                return Ok(());
            }
            self.header_seen = true;
            for &(code, col) in &blk.gs[..blk.ng] {
                match code {
                    700 => self.inch = true,
                    710 => self.inch = false,
                    _ => return fail(col, "only G70 or G71 may follow the program name"),
                }
            }
            self.feed_inch = self.inch;
            return Ok(());
        }
        if blk.ng == 0 && blk.nm == 0 && blk.present == 0 {
            return Ok(());
        }
        let d = self.dialect;
        self.cycles.block_plane = self.plane;
        self.comp_begin_block(out);

        // Classify G codes and check modal groups. Each group holds at most one code per
        // block, so the block's codes are kept in one slot per group.
        let mut slots: [Option<(G, u32)>; N_GROUPS] = [None; N_GROUPS];
        for &(code, col) in &blk.gs[..blk.ng] {
            let g = classify_g(d, code).ok_or_else(|| BlockError {
                col,
                message: format!("unknown G code {}", g_name(code)),
            })?;
            if let G::Unsupported(msg) = g {
                return fail(col, msg);
            }
            if g == G::NoOp {
                continue;
            }
            let grp = group(g);
            let heidenhain_distance = d == Dialect::Heidenhain && grp == GROUP_DISTANCE;
            // rs274 takes G80 beside a motion code of group 1 (`G80 G0 X5`): the motion.
            let g80_with_motion = d == Dialect::LinuxCnc
                && grp == 1
                && matches!(
                    (slots[1], g),
                    (Some((G::NoMotion, _)), G::Motion(_)) | (Some((G::Motion(_), _)), G::NoMotion)
                );
            if g80_with_motion {
                if g != G::NoMotion {
                    slots[1] = Some((g, col));
                }
                continue;
            }
            if slots[grp].is_some() && !heidenhain_distance {
                return fail(col, "two G codes used from same modal group");
            }
            slots[grp] = Some((g, col));
        }
        if matches!(slots[0], Some((G::BlankForm, _))) {
            // Heidenhain G30/G31 describe the blank for the control's graphics: no motion.
            // Anything else in the block would be dropped: an error instead.
            if let Some(&(_, col)) = blk.ms[..blk.nm].first() {
                return fail(col, "a blank form block (G30/G31) holds no M codes");
            }
            if let Some(k) = blk.first_of(&[KF, KS, KT]) {
                return fail(
                    blk.col(k),
                    format!("a blank form block (G30/G31) holds no {} word", key_name(k)),
                );
            }
            return Ok(());
        }
        let slot = |grp: usize| slots[grp];

        // M codes: check they are known before anything is emitted.
        let mut m_pre: [Option<EventCode>; 8] = [None; 8];
        let mut m_post: [Option<EventCode>; 8] = [None; 8];
        let mut m_groups = 0u8;
        let mut state_op: Option<(StateOp, u32)> = None;
        let mut user_m: Option<u8> = None;
        let mut m61: Option<u32> = None;
        for (i, &(code, col)) in blk.ms[..blk.nm].iter().enumerate() {
            if d == Dialect::LinuxCnc && code == 61 {
                // M61 Q: set the tool number (tool change group), no event.
                if m_groups & 2 != 0 {
                    return fail(col, "two M codes used from same modal group");
                }
                m_groups |= 2;
                m61 = Some(col);
                continue;
            }
            if let Some(msg) = self.linuxcnc_m_refusal(code) {
                return fail(col, msg);
            }
            let ev = match (m_event(code), self.linuxcnc_m(code)) {
                (Some(ev), _) | (None, Some(Ok(ev))) => ev,
                (None, Some(Err(op))) => {
                    // LinuxCNC keeps M70–M73 in the spindle group (M3 M70 is refused).
                    if m_groups & 4 != 0 {
                        return fail(col, "two M codes used from same modal group");
                    }
                    m_groups |= 4;
                    state_op = Some((op, col));
                    continue;
                }
                (None, None) => return fail(col, format!("unknown M code M{code}")),
            };
            if let EventCode::User(n) = ev {
                if user_m.is_some() {
                    return fail(col, "two M codes used from same modal group");
                }
                user_m = Some(n);
                continue;
            }
            // Modal groups of M codes (stop, tool change, spindle, coolant): at most one
            // of each per block, except that mist (M7) and flood (M8) may be turned on together.
            let grp = match ev {
                EventCode::M0 | EventCode::M1 | EventCode::M2 | EventCode::M30 | EventCode::M60 => {
                    1
                }
                EventCode::M6 => 2,
                EventCode::M3 | EventCode::M4 | EventCode::M5 | EventCode::M19 => 4,
                // LinuxCNC modal group 9: the override controls.
                EventCode::M48
                | EventCode::M49
                | EventCode::M50
                | EventCode::M51
                | EventCode::M52
                | EventCode::M53 => 32,
                // LinuxCNC (rs274) refuses M7 and M8 in one block: one coolant group.
                EventCode::M7 | EventCode::M8 if d == Dialect::LinuxCnc => 8 | 16,
                EventCode::M7 => 8,
                EventCode::M8 => 16,
                _ => 8 | 16,
            };
            if m_groups & grp != 0 {
                return fail(col, "two M codes used from same modal group");
            }
            m_groups |= grp;
            let after = match ev {
                EventCode::M0 | EventCode::M1 | EventCode::M2 | EventCode::M30 | EventCode::M60 => {
                    true
                }
                // TNC: M5 and M9 take effect at the end of the block, M3/M4/M8 at its start.
                EventCode::M5 | EventCode::M9 => d == Dialect::Heidenhain,
                _ => false,
            };
            if after {
                m_post[i] = Some(ev);
            } else {
                m_pre[i] = Some(ev);
            }
        }

        let orient = m_pre.contains(&Some(EventCode::M19));
        if orient {
            State::check_m19(blk)?;
        }
        let override_p = [
            EventCode::M50,
            EventCode::M51,
            EventCode::M52,
            EventCode::M53,
        ]
        .iter()
        .any(|&ev| m_pre.contains(&Some(ev)));
        self.m19_in_block = orient;

        // LinuxCNC sets the modes after F, S, T, the M codes and the dwell (its order of
        // execution: `G20 F40` is 40 mm/min); the other controls read every value of the
        // block in its new unit.
        let linuxcnc = d == Dialect::LinuxCnc;
        if !linuxcnc {
            self.apply_modes(&slots, blk)?;
        }

        // Dwell: the time word is checked here, before F and S are read, because on
        // Sinumerik and Heidenhain the F (and Sinumerik S) of a dwell block is the dwell,
        // not a feed or a spindle speed.
        let dwell_col = slot(0).filter(|&(g, _)| g == G::Dwell).map(|(_, c)| c);
        let dwell_checked = match dwell_col {
            Some(col) => Some(self.check_dwell(blk, col)?),
            None => None,
        };
        let dwell_word = dwell_checked.and_then(|(word, _)| word);

        // Feed mode (LinuxCNC), then feed.
        if let Some((G::FeedMode(m), _)) = slot(11) {
            self.set_feed_mode(m);
        }
        if let Some(f) = blk.get(KF).filter(|_| dwell_word != Some(KF)) {
            if f < 0.0 {
                if linuxcnc {
                    return fail(blk.col(KF), "Negative F word used");
                }
                return fail(blk.col(KF), "negative F word");
            }
            if linuxcnc {
                self.set_feed_word(f);
            } else {
                let s = if self.feed_inch { MM_PER_INCH } else { 1.0 };
                self.feed_mm_min = Some(f * s);
            }
        }

        // Spindle, tool and coolant events run before the motion of the block.
        if let Some(s) = blk.get(KS).filter(|_| dwell_word != Some(KS)) {
            if s < 0.0 {
                return fail(blk.col(KS), "negative spindle speed");
            }
            self.spindle_rpm = Some(s);
            out.event(EventCode::S, Some(s));
        }
        if let Some(t) = blk.get(KT) {
            let n = tool_number(t).ok_or_else(|| BlockError {
                col: blk.col(KT),
                message: "tool number must be a non-negative integer".into(),
            })?;
            if d != Dialect::Heidenhain || slot(0).is_none_or(|(g, _)| g != G::ToolDef) {
                self.check_tool_exists(n, blk.col(KT))?;
                self.tool_selected = Some(n);
                if d != Dialect::LinuxCnc {
                    // On the other controls the T word (Heidenhain tool call, Sinumerik
                    // T with automatic change) makes the tool current.
                    self.tool_loaded = Some(n);
                }
                if matches!(d, Dialect::Sinumerik | Dialect::Heidenhain | Dialect::Fagor)
                    && let Some(tool) = self.tool(Some(n)).filter(|t| t.length_mm != 0.0)
                {
                    // These controls apply the called tool's length (Sinumerik with D1
                    // active after the change); Kerf does not, so it refuses the call
                    // rather than cut at the wrong depth.
                    return fail(
                        blk.col(KT),
                        format!(
                            "tool length compensation is not supported (tool {} has a non-zero length)",
                            tool.number
                        ),
                    );
                }
                out.event(EventCode::T, Some(f64::from(n)));
            }
        }
        for ev in [
            EventCode::M6,
            EventCode::M3,
            EventCode::M4,
            EventCode::M5,
            EventCode::M19,
            EventCode::M7,
            EventCode::M8,
            EventCode::M9,
        ] {
            if blk.nm == 0 {
                break;
            }
            if ev == EventCode::M7
                && let Some((op, col)) = state_op
            {
                // LinuxCNC M70–M73 run after the spindle and before the coolant.
                self.state_op(op, col, out)?;
            }
            if blk.nm > 0 && m_pre.contains(&Some(ev)) {
                if ev == EventCode::M6 {
                    if d == Dialect::LinuxCnc {
                        self.comp_refuse(
                            blk.first_col,
                            "Cannot change tools with cutter radius compensation on",
                        )?;
                        self.load_tool(self.tool_selected, true);
                        self.m6_in_block = true;
                        // After a tool change LinuxCNC reads its current point back from
                        // where the tool is: after G40, the last compensated end, not the
                        // programmed point (LinuxCNC's useful-subroutines.ngc).
                        self.crc.exit_ref = None;
                        // LinuxCNC stops the spindle for the change (rs274:
                        // STOP_SPINDLE_TURNING before CHANGE_TOOL).
                        self.spindle = Spindle::Off;
                    } else {
                        self.tool_loaded = self.tool_selected;
                    }
                }
                if ev == EventCode::M19 {
                    // The spindle stops to orient (rs274: "Spindle not turning" after it).
                    self.note_machine_event(EventCode::M5);
                    self.cycles.note_spindle(EventCode::M5);
                    self.orient_event(blk, out);
                    continue;
                }
                self.note_machine_event(ev);
                self.cycles.note_spindle(ev);
                out.event(ev, None);
            }
        }
        // LinuxCNC M48–M53 after the coolant, before the user M codes.
        for ev in [
            EventCode::M48,
            EventCode::M49,
            EventCode::M50,
            EventCode::M51,
            EventCode::M52,
            EventCode::M53,
        ] {
            if blk.nm > 0 && m_pre.contains(&Some(ev)) {
                self.override_event(ev, blk, out);
            }
        }
        if let Some(n) = user_m {
            self.user_m_event(n, blk, out);
        }

        if let Some(col) = m61 {
            self.exec_m61(blk, col)?;
        }

        // The dwell runs after the spindle and coolant events and before the motion (the
        // LinuxCNC order of execution); a G4 without a time word still stops the motion.
        if let Some((_, seconds)) = dwell_checked {
            out.event(EventCode::G4, Some(seconds));
        }
        if linuxcnc {
            self.apply_modes(&slots, blk)?;
        }

        // Heidenhain G99: tool definition (T number, L length, R radius).
        if d == Dialect::Heidenhain && slot(0).is_some_and(|(g, _)| g == G::ToolDef) {
            if let Some(k) = blk.first_of(&[KX, KY, KZ, KA, KB, KC, KI, KJ, KK, KH]) {
                return fail(
                    blk.col(k),
                    format!("{} word in a tool definition (G99)", key_name(k)),
                );
            }
            let Some(t) = blk.get(KT).and_then(tool_number) else {
                return fail(blk.first_col, "G99 needs a tool number T");
            };
            let tool = Tool {
                number: t,
                length_mm: blk.get(KL).unwrap_or(0.0) * self.scale(),
                radius_mm: blk.get(KR).unwrap_or(0.0) * self.scale(),
                ..Tool::default()
            };
            // Redefinition replaces the entry and the table is capped, so that memory stays
            // bounded whatever the program does.
            let tools = &mut self.settings.tools;
            if let Some(entry) = tools.iter_mut().find(|t| t.number == tool.number) {
                *entry = tool;
            } else if tools.len() < MAX_TOOLS {
                tools.push(tool);
            } else {
                return fail(
                    blk.first_col,
                    format!("more than {MAX_TOOLS} tools defined"),
                );
            }
            return self.finish_block(blk, &m_post, out);
        }
        if d == Dialect::Heidenhain && blk.has(KL) {
            return fail(blk.col(KL), "L word with no G99 to use it");
        }

        // Tool offset words that Kerf does not apply: refused where they would act.
        self.check_tool_offset_words(blk, slot(6))?;

        // Cutter radius compensation.
        if d == Dialect::LinuxCnc {
            self.linuxcnc_comp(blk, slot(6), out)?;
        } else {
            if let Some((G::Comp(c) | G::CompDiameter(c), _)) = slot(6) {
                self.comp = c;
            }
            if self.comp != Comp::Off {
                let number = match (d, blk.get(KD)) {
                    (Dialect::Rockwell, Some(dv)) => tool_number(dv),
                    _ => self.tool_loaded.or(self.tool_selected),
                };
                if self.tool(number).is_some_and(|t| t.radius_mm != 0.0) {
                    let col = slot(6).map_or(blk.first_col, |(_, c)| c);
                    return fail(
                        col,
                        "cutter compensation not supported (the active tool has a non-zero radius)",
                    );
                }
            }
        }

        // LinuxCNC: one G code of the block may use the axis words.
        let axis_g0 = slot(0)
            .filter(|&(g, _)| matches!(g, G::G92Set | G::LocalOffset | G::SetData | G::Home(_)));
        let motion_in_block = matches!(slot(1), Some((G::Motion(_), _)));
        if d == Dialect::LinuxCnc
            && motion_in_block
            && let Some((_, col)) = axis_g0
        {
            return fail(col, "Cannot use two g codes that both use axis values");
        }

        // Tool length offset.
        let mut consumed_axes = false;
        if let Some((G::ToolLength(kind), col)) = slot(7) {
            if kind == ToolLength::Cancel
                && matches!(d, Dialect::LinuxCnc | Dialect::Rockwell)
                && blk.has(KH)
            {
                return fail(blk.col(KH), "H word with no G43 to use it");
            }
            if d == Dialect::LinuxCnc {
                self.comp_refuse(
                    col,
                    "Cannot change tool offset with cutter radius compensation on",
                )?;
            }
            consumed_axes = self.exec_tool_length(blk, kind, col, motion_in_block)?;
            self.tool_length_on = kind != ToolLength::Cancel;
        } else if blk.has(KH) && matches!(d, Dialect::LinuxCnc | Dialect::Rockwell) {
            return fail(blk.col(KH), "H word with no G43 to use it");
        }

        // G52/G92 family, G10, G28/G30 and their stored positions (LinuxCNC order of
        // execution: after the tool length offset and the coordinate system selection,
        // before the motion).
        if let Some((g, col)) = slot(0) {
            if d == Dialect::LinuxCnc
                && matches!(
                    g,
                    G::G92Set | G::G92Reset | G::G92Suspend | G::G92Restore | G::LocalOffset
                )
            {
                self.comp_refuse(col, "Cannot change axis offsets with cutter radius comp")?;
            }
            match g {
                G::G92Set | G::G92Reset | G::G92Suspend | G::G92Restore | G::LocalOffset => {
                    self.exec_g92(blk, g, col)?;
                    consumed_axes = true;
                }
                G::SetData => {
                    self.exec_g10(blk, col)?;
                    consumed_axes = true;
                }
                G::HomeSet(g30) => {
                    if let Some(k) = blk.first_of(&[KX, KY, KZ, KA, KB, KC]) {
                        return fail(
                            blk.col(k),
                            "Cannot use axis values without a g code that uses them",
                        );
                    }
                    self.store_home(g30);
                }
                G::Home(g30) => {
                    self.exec_home(blk, g30, col, out)?;
                    consumed_axes = true;
                }
                _ => {}
            }
        }
        // Poles and polar origins.
        if let Some((G::Pole(r), col)) = slot(0) {
            self.set_sinumerik_pole(blk, r, col)?;
            consumed_axes = true;
        }
        if slot(0).is_some_and(|(g, _)| g == G::PoleFromLast) {
            self.cc = Some(self.pos);
            self.polar_last = None;
        }
        if let Some((_, col)) = slot(0).filter(|&(g, _)| g == G::PolarOrigin) {
            if let Some(k) = blk.first_of(&[KX, KY, KZ, KA, KB, KC, KR, KQ]) {
                return fail(
                    blk.col(k),
                    format!("{} word with G30 (polar origin)", key_name(k)),
                );
            }
            self.set_fagor_origin(blk, col)?;
            return self.finish_block(blk, &m_post, out);
        }
        if d == Dialect::Heidenhain && blk.any(&IJK) {
            self.set_heidenhain_cc(blk)?;
        }

        // Motion.
        let motion_g = slot(1);
        if d == Dialect::LinuxCnc {
            self.cycle_motion_code(blk, motion_g)?;
        }
        match motion_g {
            Some((G::Motion(m), _)) => self.motion = Some(m),
            Some((G::NoMotion, _)) => self.motion = None,
            _ => {}
        }
        let machine = slot(0).filter(|&(g, _)| g == G::MachineCoords);
        let exact_once = slot(10).is_some();
        let abs_centre_once = slot(12).is_some();
        let dwell = dwell_col.is_some();
        let g64 = matches!(slot(9), Some((G::Corner { exact: false }, _)));
        if d == Dialect::LinuxCnc {
            let explicit_cycle = matches!(motion_g, Some((G::Motion(Motion::Cycle(_)), _)));
            // G10 and G41.1/G42.1 take L too, and check it themselves.
            let g10 = slot(0).is_some_and(|(g, _)| g == G::SetData);
            let g41_1 = matches!(slot(6), Some((G::CompDiameter(_), _)));
            if !g10 && !g41_1 {
                self.check_l_word(blk, explicit_cycle)?;
            }
        }
        if d == Dialect::LinuxCnc
            && blk.present & (1 << KP | 1 << KQ) != 0
            && !self.axes_without_motion(blk)
        {
            // LinuxCNC refuses words that no G code of the block uses.
            let arc = matches!(self.motion, Some(Motion::Arc(_)));
            let user = user_m.is_some();
            let g10 = slot(0).is_some_and(|(g, _)| g == G::SetData);
            if blk.has(KP)
                && !(dwell
                    || g64
                    || arc
                    || user
                    || g10
                    || orient
                    || override_p
                    || self.cycle_uses_p())
            {
                return fail(blk.col(KP), cycles::unused_word_message(KP));
            }
            if blk.has(KQ)
                && !(g64 || user || g10 || orient || m61.is_some() || self.cycle_uses_q())
            {
                return fail(blk.col(KQ), cycles::unused_word_message(KQ));
            }
        }
        if d == Dialect::Heidenhain
            && blk.has(KR)
            && matches!(self.motion, Some(Motion::Rapid | Motion::Linear))
        {
            return fail(blk.col(KR), "R word with no G02, G03, G10 or G11 to use it");
        }
        // A dwell block holds no motion words (checked above), except in LinuxCNC, whose
        // motion then runs after the dwell.
        let motion_after_dwell = d == Dialect::LinuxCnc && blk.any(&LINUXCNC_MOTION_WORDS);
        // The axis words belong to the G52/G92 or G28/G30 code (a motion code with them
        // was refused above): the centre words have no arc to use them.
        let axis_code = slot(0).is_some_and(|(g, _)| {
            matches!(
                g,
                G::G92Set
                    | G::G92Reset
                    | G::G92Suspend
                    | G::G92Restore
                    | G::LocalOffset
                    | G::Home(_)
            )
        });
        if consumed_axes && axis_code {
            self.check_unused(blk, false)?;
        }
        if d == Dialect::Rockwell {
            // P is the dwell time, Q and R belong to cycles (not supported) and arcs.
            if blk.has(KP) && !dwell {
                return fail(blk.col(KP), "P word with no G code that uses it");
            }
            if blk.has(KQ) {
                return fail(blk.col(KQ), "Q word with no G code that uses it");
            }
        }
        if let (Some(Motion::Cycle(kind)), false) = (self.motion, consumed_axes) {
            let explicit = motion_g.map(|(_, c)| c);
            if let Some((_, col)) = machine {
                return fail(col, "must use G0 or G1 with G53");
            }
            self.cycle(blk, out, kind, explicit)?;
        } else if !consumed_axes && (!dwell || motion_after_dwell) {
            let motion_col = motion_g.map_or(blk.first_col, |(_, c)| c);
            self.motion(
                blk,
                out,
                motion_col,
                machine.map(|(_, c)| c),
                exact_once,
                abs_centre_once,
            )?;
        }
        self.finish_block(blk, &m_post, out)?;
        self.comp_end_block(out)
    }

    /// Units, then the modal G codes of distance, arc distance, plane, path control and
    /// coordinate system of a block.
    fn apply_modes(
        &mut self,
        slots: &[Option<(G, u32)>; N_GROUPS],
        blk: &Block,
    ) -> Result<(), BlockError> {
        let d = self.dialect;
        // Units first: every value in the block is read in the new unit.
        if let Some((G::Units { inch, feed_too }, _)) = slots[3] {
            self.inch = inch;
            // Sinumerik G70/G71 leave F in the basic unit of the control (mm); only
            // G700/G710 make F follow the geometry unit.
            self.feed_inch = feed_too && inch;
        }
        // Each group's slot is read directly (a plain move has none of them). Heidenhain
        // may repeat G90/G91 in a block; the slot holds the last one, which stays modal.
        if let Some((G::Plane(p), col)) = slots[2]
            && p != self.plane
        {
            self.comp_refuse(
                col,
                "Cannot change planes with cutter radius compensation on",
            )?;
            self.set_plane(p);
        }
        if let Some((G::Distance { absolute }, _)) = slots[GROUP_DISTANCE] {
            self.absolute = absolute;
        }
        if let Some((G::ArcDistance { absolute }, _)) = slots[5] {
            self.arc_absolute = absolute;
        }
        if let Some((G::CoordSystem(cs), col)) = slots[8] {
            self.comp_refuse(
                col,
                "Cannot change coordinate systems with cutter radius compensation on",
            )?;
            self.coord_system = cs;
            if let Some(i) = cs {
                self.params.set(params::COORD_SYSTEM, i as f64 + 1.0);
            }
            self.update_origin();
        }
        if let Some((G::Retract { r_plane }, _)) = slots[13] {
            self.retract_r = r_plane;
        }
        if let Some((G::Corner { exact }, _)) = slots[9] {
            self.corner = if exact {
                CornerMode::ExactStop
            } else if d == Dialect::LinuxCnc {
                self.g64_corner(blk)?
            } else {
                CornerMode::Blend {
                    tolerance_mm: None,
                    naive_cam_mm: None,
                }
            };
        }
        Ok(())
    }

    /// D words: LinuxCNC and Rockwell take D (the tool whose radius compensation uses)
    /// only with G41/G42 in the block ("D word with no G41 or G42 to use it"); Sinumerik
    /// and Fagor D select the tool's offsets (length and radius), which Kerf does not
    /// apply: D0 (no offsets) is accepted, and D1 and up only while the active tool has a
    /// zero length and radius. Sinumerik H words are auxiliary functions for the machine's
    /// logic, which Kerf does not have: an error.
    #[inline]
    fn check_tool_offset_words(
        &self,
        blk: &Block,
        comp: Option<(G, u32)>,
    ) -> Result<(), BlockError> {
        let d = self.dialect;
        if d == Dialect::Sinumerik && blk.has(KH) {
            return fail(blk.col(KH), "H auxiliary functions are not supported");
        }
        let Some(dv) = blk.get(KD) else {
            return Ok(());
        };
        match d {
            Dialect::LinuxCnc | Dialect::Rockwell => {
                if !matches!(
                    comp,
                    Some((G::Comp(Comp::Left | Comp::Right) | G::CompDiameter(_), _))
                ) {
                    return fail(blk.col(KD), "D word with no G41 or G42 to use it");
                }
            }
            Dialect::Sinumerik | Dialect::Fagor => {
                if dv != 0.0
                    && let Some(t) = self.tool(self.tool_loaded.or(self.tool_selected))
                    && (t.length_mm != 0.0 || t.radius_mm != 0.0)
                {
                    return fail(
                        blk.col(KD),
                        format!(
                            "tool offsets (D) are not supported (tool {} has a non-zero length or radius)",
                            t.number
                        ),
                    );
                }
            }
            Dialect::Heidenhain => {}
        }
        Ok(())
    }

    /// A plane change; it forgets the Sinumerik polar values and the Fagor polar origin,
    /// as their manuals say.
    fn set_plane(&mut self, p: Plane) {
        self.plane = p;
        self.rp_mm = None;
        self.ap_deg = None;
        self.polar_origin = None;
        self.polar_last = None;
    }

    /// Checks the dwell word of a G4 block (`col` is the G4) and returns its key, if given,
    /// and the dwell time in seconds (zero without a time word).
    ///
    /// The dwell word: LinuxCNC `P` (seconds, required); Rockwell `X` or `P`; Sinumerik `F`
    /// (seconds) or `S` (spindle revolutions, timed at the last programmed spindle
    /// speed); Heidenhain `F` (seconds); Fagor `K` (seconds). Its value must be from 0 to
    /// [`MAX_DWELL`]. Except in LinuxCNC, the block
    /// may not hold motion words (the Sinumerik manual: "G4 must be programmed in a
    /// separate block"); a word that would be an axis elsewhere is never silently dropped.
    fn check_dwell(&self, blk: &Block, col: u32) -> Result<(Option<u8>, f64), BlockError> {
        let d = self.dialect;
        let (g, words): (&str, &[u8]) = match d {
            Dialect::LinuxCnc => ("G4", &[KP]),
            Dialect::Rockwell => ("G04", &[KX, KP]),
            Dialect::Sinumerik => ("G4", &[KF, KS]),
            Dialect::Heidenhain => ("G04", &[KF]),
            Dialect::Fagor => ("G04", &[KK]),
        };
        if d != Dialect::LinuxCnc
            && let Some(k) = MOTION_WORDS
                .iter()
                .copied()
                .filter(|k| !words.contains(k))
                .find(|&k| blk.has(k))
        {
            return fail(
                blk.col(k),
                format!(
                    "{g} must be programmed in a separate block ({} word with {g})",
                    key_name(k)
                ),
            );
        }
        let mut given = words.iter().copied().filter(|&k| blk.has(k));
        let Some(word) = given.next() else {
            if d == Dialect::LinuxCnc {
                return fail(col, "Dwell time P word missing with G4");
            }
            // Rockwell, Sinumerik, Heidenhain and Fagor accept G4 without a time: a dwell
            // of zero, still an exact stop.
            return Ok((None, 0.0));
        };
        if let Some(second) = given.next() {
            return fail(
                blk.col(second),
                format!(
                    "dwell time given twice with {g} ({} and {})",
                    key_name(word),
                    key_name(second)
                ),
            );
        }
        let name = key_name(word);
        let value = blk.vals[word as usize];
        if value < 0.0 {
            if d == Dialect::LinuxCnc {
                return fail(blk.col(word), "Negative P word used");
            }
            return fail(
                blk.col(word),
                format!("negative dwell time {name} with {g}"),
            );
        }
        if !(0.0..=MAX_DWELL).contains(&value) {
            return fail(
                blk.col(word),
                format!("dwell time {name} with {g} must be at most 1000000, found {value}"),
            );
        }
        if word != KS {
            return Ok((Some(word), value));
        }
        // Sinumerik G4 S: spindle revolutions at the programmed speed.
        match self.spindle_rpm.filter(|&rpm| rpm > 0.0) {
            Some(rpm) => Ok((Some(word), value * 60.0 / rpm)),
            None => fail(
                blk.col(KS),
                "G4 S dwells in spindle revolutions: no spindle speed S programmed",
            ),
        }
    }

    fn finish_block(
        &mut self,
        blk: &Block,
        m_post: &[Option<EventCode>; 8],
        out: &mut Out<'_>,
    ) -> Result<(), BlockError> {
        if blk.nm == 0 {
            return Ok(());
        }
        self.comp_before_stops(m_post, blk.first_col, out)?;
        for ev in [
            EventCode::M5,
            EventCode::M9,
            EventCode::M0,
            EventCode::M1,
            EventCode::M60,
            EventCode::M2,
            EventCode::M30,
        ] {
            if m_post.contains(&Some(ev)) {
                out.event(ev, None);
                if matches!(ev, EventCode::M2 | EventCode::M30) {
                    self.done = true;
                    if self.dialect == Dialect::LinuxCnc {
                        // LinuxCNC's program end selects G54 again (#5220 = 1).
                        self.coord_system = Some(0);
                        self.params.set(params::COORD_SYSTEM, 1.0);
                    }
                }
            }
        }
        Ok(())
    }
}

/// Heidenhain words whose value G90/G91 make absolute or incremental.
fn takes_distance_mode(k: u8) -> bool {
    XYZ.contains(&k) || ABC.contains(&k) || IJK.contains(&k) || k == KR || k == KH
}

fn tool_number(v: f64) -> Option<u32> {
    if v >= 0.0 && v <= f64::from(u32::MAX) && v.fract() == 0.0 {
        Some(v as u32)
    } else {
        None
    }
}
