//! Modal state and per-dialect resolution of blocks into moves and events.
//!
//! [`State`] is the interpreter state carried from block to block; a block's words are
//! gathered in a [`Block`] (`block`) and executed stage by stage (`exec`).

use kerf_geom::PerAxis;
use kerf_geom::{CornerMode, Vec3};

use crate::arc::Plane;
use crate::codes::*;
use crate::lex::{K_AT, K_CARET};
use crate::{Dialect, Event, EventCode, Item, Settings, Tool};

mod arcs;
mod block;
mod comp;
pub(crate) mod cycles;
mod dwell;
mod exec;
mod geometry;
mod io;
mod mcodes;
mod modal;
mod motion;
mod offsets;
pub(crate) mod params;
mod plain;
mod polar;
mod query;
mod tooling;
mod unused;

pub(crate) use block::Block;
pub(crate) use modal::FeedMode;
pub(crate) use modal::linuxcnc_m_refusal_of;
use modal::{ModalFrame, Spindle};
pub(crate) use offsets::ToolLength;
#[cfg(test)]
pub(crate) use plain::GENERAL_PATH_ONLY;

const MM_PER_INCH: f64 = 25.4;

/// The LinuxCNC words a motion uses (H and Q belong to G43 and G64 there).
const LINUXCNC_MOTION_WORDS: [u8; 12] = [KX, KY, KZ, KA, KB, KC, KI, KJ, KK, KR, K_AT, K_CARET];

pub(crate) use crate::lex::BlockError;

fn fail<T>(col: u32, message: impl Into<String>) -> Result<T, BlockError> {
    Err(BlockError {
        col,
        message: message.into(),
    })
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
    tool_offset: PerAxis<f64>,
    /// LinuxCNC: the tool offsets in effect when the last move was made. rs274 reads its
    /// position back after a tool change from the last point it printed, which follows the
    /// moves and the work offsets but not the tool offsets changed since.
    tool_offset_at_move: PerAxis<f64>,
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
    /// start, reached by a radial line after the whole turn (`arcs::arc_path`).
    arc_tail: Option<Vec3>,
    /// LinuxCNC: the answers to M66 waits, read through `#5399` (`io`).
    inputs: io::InputCell,
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

    /// MDI input ([`Settings::mdi`]).
    pub(crate) fn mdi(&self) -> bool {
        self.settings.mdi
    }

    /// The tool table with the program's G10 L1/L10/L11 changes.
    pub(crate) fn tools(&self) -> &[Tool] {
        &self.settings.tools
    }

    /// The current point in program coordinates (see
    /// [`crate::Interpreter::program_position`]).
    pub(crate) fn program_position(&self) -> PerAxis<f64> {
        self.program_point()
    }

    /// The active coordinate system, 0 = G54 (`None`: none).
    pub(crate) fn coordinate_system(&self) -> Option<usize> {
        self.coord_system
    }

    /// The current point becomes the machine position `m` (see
    /// [`crate::Interpreter::set_position`]).
    pub(crate) fn set_machine_position(&mut self, m: PerAxis<f64>) {
        self.pos = self.machine_to_frame(Vec3::new(m[0], m[1], m[2]));
        self.abc = [m[3], m[4], m[5]];
        self.polar_last = None;
        self.readback_from = None;
        self.tool_offset_at_move = self.tool_offset;
        self.arc_tail = None;
    }

    pub(crate) fn new(dialect: Dialect, settings: Settings) -> Self {
        let tool_loaded = settings.tool_in_spindle;
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
            tool_loaded,
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
            inputs: io::InputCell::default(),
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
}

fn tool_number(v: f64) -> Option<u32> {
    if v >= 0.0 && v <= f64::from(u32::MAX) && v.fract() == 0.0 {
        Some(v as u32)
    } else {
        None
    }
}
