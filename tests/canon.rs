//! LinuxCNC's canonical machining calls (the standard output of `rs274`, as
//! `tests/rs274/canon.sh` prints it) turned into the motion a machine makes.
//!
//! rs274 prints every position in *program* units and *program* coordinates: the offsets
//! are separate calls. [`parse`] replays them as LinuxCNC's canon layer does and yields
//! [`CanonItem`]s in absolute machine millimetres, the form of Kerf's own output, so the two
//! can be compared item by item ([`crate::rs274`]).
//!
//! Conventions (each checked by experiment with rs274; see `docs/linuxcnc/harness.md`):
//!
//! - `USE_LENGTH_UNITS(CANON_UNITS_MM|INCHES)`: the unit of every length printed after it,
//!   offsets and feeds included. A value is converted with the unit active when it was
//!   printed and kept in mm from then on (`SET_G5X_OFFSET` printed under G20 stays valid
//!   after G21).
//! - Machine point of a program point p: `R(θ)·(p + g92) + g5x + tool`, with R the rotation
//!   about Z of `SET_XY_ROTATION(θ degrees)` applied to X and Y. A, B, C are degrees and
//!   are only offset.
//! - `USE_TOOL_LENGTH_OFFSET(x y z, a b c, u v w)`.
//! - `ARC_FEED(first_end, second_end, first_axis, second_axis, rotation, axis_end_point,
//!   a, b, c)`: XY plane first = X, second = Y, axis = Z; XZ plane (G18) first = Z,
//!   second = X, axis = Y; YZ plane (G19) first = Y, second = Z, axis = X. So (first,
//!   second, axis) is right-handed in every plane. `rotation` > 0 turns counter-clockwise
//!   about the axis (G3), < 0 clockwise (G2); |rotation| is the number of times the arc
//!   passes its end angle: 1 = less than one turn (a whole turn when the end angle is the
//!   start angle, also for a spiral whose end radius differs), each more adds a full turn
//!   (G2/G3 `P`).
//! - `SET_FEED_RATE(f)`: units per minute in the units active when printed, or units per
//!   spindle revolution after `SET_FEED_MODE(spindle, 1)` (G95; resolved here with the last
//!   `SET_SPINDLE_SPEED`, as Kerf resolves it from S). Inverse time (G93) never reaches the
//!   canon: rs274 prints the resulting units/min before every move.
//! - Events: `SET_SPINDLE_SPEED` = S, `START_SPINDLE_CLOCKWISE` = M3, `..._COUNTERCLOCKWISE`
//!   = M4, `STOP_SPINDLE_TURNING` = M5, `MIST_ON` = M7, `FLOOD_ON` = M8, `MIST_OFF` (+
//!   `FLOOD_OFF`) = M9, `SELECT_TOOL` = T, `START_CHANGE`/`STOP_SPINDLE_TURNING`/
//!   `CHANGE_TOOL` = M6 (the spindle stop belongs to the change), `DWELL` = G4,
//!   `PROGRAM_STOP` = M0, `OPTIONAL_PROGRAM_STOP` = M1, `PALLET_SHUTTLE` + `PROGRAM_STOP` =
//!   M60, `PROGRAM_END` = M2 (after `PALLET_SHUTTLE`: M30; the spindle and coolant stops
//!   LinuxCNC prints as part of the end, after the end's `SET_G5X_OFFSET`, belong to it),
//!   `MESSAGE` = MSG or DEBUG, a line that is not a canonical call = PRINT, `LOGOPEN("f")`,
//!   `LOGAPPEND("f")`, `LOG("t")`, `LOGCLOSE()` = LOG with the text `LOGOPEN,f`,
//!   `LOGAPPEND,f`, `LOG,t`, `LOGCLOSE`.
//!   `CHANGE_TOOL_NUMBER` (M61) moves nothing and makes no event.
//! - `SET_MOTION_CONTROL_MODE(CANON_EXACT_STOP)` (G61.1), `(CANON_EXACT_PATH)` (G61),
//!   `(CANON_CONTINUOUS, tolerance)` (G64 \[P\], tolerance in the units active when printed,
//!   0 without P); continuous without tolerance at start. `SET_NAIVECAM_TOLERANCE(q)`
//!   (printed by G64 after the mode, 4 decimals) is the naive-CAM tolerance of the
//!   continuous mode in force.
//! - Calls that move the machine in a way Kerf does not model (probing, rigid tapping,
//!   spindle-synchronised motion, NURBS) become [`CanonItem::Other`]: they never match.
//! - Every value is printed with 4 decimals: each converted coordinate carries the sum of
//!   the half-units of the last digit of every printed value it was computed from.

use kerf_gcode::{EventCode, Vec3};

/// Half a unit of the last printed digit (rs274 prints 4 decimals).
pub const HALF_DIGIT: f64 = 0.5e-4;

/// The absolute part of every tolerance, mm (or degrees, rad, mm/min).
pub const BASE_TOL: f64 = 1e-6;

/// What a move is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MoveKind {
    /// `STRAIGHT_TRAVERSE` (G0).
    Rapid,
    /// `STRAIGHT_FEED`.
    Feed,
    /// `ARC_FEED`.
    Arc,
}

/// How a move joins the next (`SET_MOTION_CONTROL_MODE`, modal; LinuxCNC starts in
/// continuous mode without a tolerance).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CanonCorner {
    /// `CANON_EXACT_STOP` (G61.1).
    ExactStop,
    /// `CANON_EXACT_PATH` (G61).
    ExactPath,
    /// `CANON_CONTINUOUS` (G64) with its path tolerance in mm (0: none given).
    Continuous {
        /// Path tolerance, mm.
        tolerance_mm: f64,
        /// How far the printed tolerance may be from the exact one, mm (6 decimals).
        tol_mm: f64,
        /// The naive-CAM tolerance (`SET_NAIVECAM_TOLERANCE`, printed after the mode by
        /// G64), mm; 0 when none was given.
        naive_cam_mm: f64,
        /// How far the printed naive-CAM tolerance may be from the exact one, mm.
        naive_tol_mm: f64,
    },
}

/// The circle of an `ARC_FEED`, in machine mm.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CanonArc {
    /// Centre, in the plane of the start point.
    pub center_mm: Vec3,
    /// Unit normal of the plane (right-handed with the plane's first and second axes).
    pub axis: Vec3,
    /// Signed swept angle about `axis`, whole turns included.
    pub sweep_rad: f64,
    /// Distance from the centre to the start point, in the plane.
    pub start_radius_mm: f64,
    /// Distance from the centre to the end point, in the plane (LinuxCNC accepts a
    /// difference and spirals).
    pub end_radius_mm: f64,
}

/// One move, in machine mm.
#[derive(Clone, Debug, PartialEq)]
pub struct CanonMove {
    /// 1-based line of the canon output.
    pub canon_line: usize,
    /// Rapid, feed line or arc.
    pub kind: MoveKind,
    /// Start point (the end of the previous move; the machine origin at first).
    pub start_mm: Vec3,
    /// End point.
    pub end_mm: Vec3,
    /// A, B, C at the start, degrees.
    pub start_abc_deg: [f64; 3],
    /// A, B, C at the end, degrees.
    pub end_abc_deg: [f64; 3],
    /// The circle of an arc.
    pub arc: Option<CanonArc>,
    /// Feed along the path, mm/min; `None` for rapids.
    pub feed_mm_min: Option<f64>,
    /// How far the printed numbers may be from the exact feed, mm/min.
    pub feed_tol_mm_min: f64,
    /// How far each coordinate of the end point and the centre may be from the exact
    /// value, mm (degrees for A, B, C).
    pub tol_mm: f64,
    /// The corner mode in force.
    pub corner: CanonCorner,
}

/// A non-motion event.
#[derive(Clone, Debug, PartialEq)]
pub struct CanonEvent {
    /// 1-based line of the canon output.
    pub canon_line: usize,
    /// The event, in Kerf's terms (`Msg` stands for a MESSAGE: MSG or DEBUG).
    pub code: EventCode,
    /// S rpm, T tool number, G4 seconds.
    pub value: Option<f64>,
    /// How far `value` may be from the exact value.
    pub value_tol: f64,
    /// M67/M68: the analog value (Kerf's Q word); `None` for the other events.
    pub q: Option<f64>,
    /// MESSAGE and PRINT text.
    pub text: Option<String>,
}

/// One item of the canon output, as the machine sees it.
#[derive(Clone, Debug, PartialEq)]
pub enum CanonItem {
    /// A move.
    Move(CanonMove),
    /// An event.
    Event(CanonEvent),
    /// A call that moves or waits in a way the comparison does not model (probing,
    /// rigid tapping, spindle synchronisation, NURBS, unknown calls with arguments).
    Other {
        /// 1-based line of the canon output.
        canon_line: usize,
        /// The call as printed.
        call: String,
    },
}

impl CanonItem {
    /// The line of the canon output the item comes from.
    pub fn canon_line(&self) -> usize {
        match self {
            CanonItem::Move(m) => m.canon_line,
            CanonItem::Event(e) => e.canon_line,
            CanonItem::Other { canon_line, .. } => *canon_line,
        }
    }
}

/// A canon output that cannot be read.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("canon line {line}: {message}")]
pub struct CanonError {
    /// 1-based line of the canon output.
    pub line: usize,
    /// What is wrong.
    pub message: String,
}

/// Splits one line of rs274's output into (N field, call). `None` for a line that is not a
/// canonical call (the text of a `(PRINT,…)`).
pub fn split_line(line: &str) -> Option<(&str, &str)> {
    let rest = line.trim_start();
    let digits = rest.bytes().take_while(u8::is_ascii_digit).count();
    if digits == 0 {
        return None;
    }
    let rest = rest[digits..].strip_prefix(' ')?;
    let rest = rest.strip_prefix('N')?;
    let n_end = rest.find(' ')?;
    let (n, call) = rest.split_at(n_end);
    let call = call.trim();
    let name_end = call.find('(')?;
    let name = &call[..name_end];
    if name.is_empty()
        || !name
            .bytes()
            .all(|b| b.is_ascii_uppercase() || b == b'_' || b.is_ascii_digit() || b == b'.')
    {
        // (`SPINDLE.0.WAIT_ORIENT_COMPLETE(Q)` names the spindle.)
        return None;
    }
    Some((n, call))
}

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Plane {
    Xy,
    Xz,
    Yz,
}

/// A 6-vector (X Y Z mm, A B C degrees) with its uncertainty (mm for XYZ, degrees ABC).
#[derive(Clone, Copy, Debug, Default)]
struct Offset {
    v: [f64; 6],
    tol_len: f64,
    tol_ang: f64,
}

struct State {
    unit_mm: f64,
    g5x: Offset,
    g92: Offset,
    tool: Offset,
    rot_deg: f64,
    plane: Plane,
    feed: f64,
    feed_unit_mm: f64,
    per_rev: bool,
    spindle_rpm: f64,
    pos_mm: Vec3,
    abc_deg: [f64; 3],
    corner: CanonCorner,
    items: Vec<CanonItem>,
    /// Index into `items` at the last `SET_G5X_OFFSET` (program end resets start there).
    last_g5x_item: usize,
    pallet: bool,
    changing_tool: bool,
    mist_off_just_before: bool,
}

fn numbers(args: &str, line: usize, want: usize) -> Result<Vec<f64>, CanonError> {
    let vals: Result<Vec<f64>, _> = args
        .split(|c: char| c == ',' || c.is_whitespace())
        .filter(|s| !s.is_empty())
        .map(str::parse::<f64>)
        .collect();
    let vals = vals.map_err(|e| CanonError {
        line,
        message: format!("bad number in ({args}): {e}"),
    })?;
    if vals.len() < want {
        return Err(CanonError {
            line,
            message: format!("expected {want} numbers in ({args}), got {}", vals.len()),
        });
    }
    Ok(vals)
}

fn args_of(call: &str) -> &str {
    let open = call.find('(').map_or(call.len(), |i| i + 1);
    let close = call.rfind(')').unwrap_or(call.len()).max(open);
    &call[open..close]
}

fn quoted(args: &str) -> String {
    let t = args.trim();
    let t = t.strip_prefix('"').unwrap_or(t);
    let t = t.strip_suffix('"').unwrap_or(t);
    t.to_string()
}

impl State {
    fn new() -> State {
        State {
            unit_mm: 1.0,
            g5x: Offset::default(),
            g92: Offset::default(),
            tool: Offset::default(),
            rot_deg: 0.0,
            plane: Plane::Xy,
            feed: 0.0,
            feed_unit_mm: 1.0,
            per_rev: false,
            spindle_rpm: 0.0,
            pos_mm: Vec3::zeros(),
            abc_deg: [0.0; 3],
            corner: CanonCorner::Continuous {
                tolerance_mm: 0.0,
                tol_mm: 0.0,
                naive_cam_mm: 0.0,
                naive_tol_mm: 0.0,
            },
            items: Vec::new(),
            last_g5x_item: 0,
            pallet: false,
            changing_tool: false,
            mist_off_just_before: false,
        }
    }

    fn offset(&self, v: &[f64]) -> Offset {
        let mut o = Offset::default();
        for (i, x) in v.iter().take(6).enumerate() {
            o.v[i] = if i < 3 { x * self.unit_mm } else { *x };
        }
        o.tol_len = HALF_DIGIT * self.unit_mm;
        o.tol_ang = HALF_DIGIT;
        o
    }

    /// Machine point (mm, degrees) of program point `p` (program units, degrees) and the
    /// uncertainty of its lengths.
    fn to_machine(&self, p: [f64; 6]) -> ([f64; 6], f64, f64) {
        let mut q = [0.0; 6];
        for (i, qi) in q.iter_mut().enumerate() {
            let scale = if i < 3 { self.unit_mm } else { 1.0 };
            *qi = p[i] * scale + self.g92.v[i];
        }
        let (s, c) = self.rot_deg.to_radians().sin_cos();
        let (x, y) = (q[0], q[1]);
        q[0] = c * x - s * y;
        q[1] = s * x + c * y;
        for (i, qi) in q.iter_mut().enumerate() {
            *qi += self.g5x.v[i] + self.tool.v[i];
        }
        let rot_tol = if self.rot_deg == 0.0 {
            0.0
        } else {
            x.hypot(y) * HALF_DIGIT.to_radians()
        };
        let tol_len = BASE_TOL
            + HALF_DIGIT * self.unit_mm
            + self.g92.tol_len
            + self.g5x.tol_len
            + self.tool.tol_len
            + rot_tol;
        let tol_ang =
            BASE_TOL + HALF_DIGIT + self.g92.tol_ang + self.g5x.tol_ang + self.tool.tol_ang;
        (q, tol_len, tol_ang)
    }

    fn feed_now(&self) -> (f64, f64) {
        let f_mm = self.feed * self.feed_unit_mm;
        let f_tol = HALF_DIGIT * self.feed_unit_mm;
        if self.per_rev {
            (
                f_mm * self.spindle_rpm,
                BASE_TOL + f_tol * self.spindle_rpm + f_mm * HALF_DIGIT,
            )
        } else {
            (f_mm, BASE_TOL + f_tol)
        }
    }

    fn event(&mut self, line: usize, code: EventCode, value: Option<f64>, text: Option<String>) {
        self.items.push(CanonItem::Event(CanonEvent {
            canon_line: line,
            code,
            value,
            value_tol: BASE_TOL + HALF_DIGIT,
            q: None,
            text,
        }));
    }

    /// An output call of M62–M65 (`NAME(index)`) or M67/M68 (`NAME(index,value)`).
    fn output(&mut self, line: usize, code: EventCode, args: &str) -> Result<(), CanonError> {
        let analog = matches!(code, EventCode::M67 | EventCode::M68);
        let v = numbers(args, line, if analog { 2 } else { 1 })?;
        self.event(line, code, Some(v[0]), None);
        if analog && let Some(CanonItem::Event(e)) = self.items.last_mut() {
            e.q = Some(v[1]);
        }
        Ok(())
    }

    fn straight(&mut self, line: usize, call: &str, kind: MoveKind) -> Result<(), CanonError> {
        let v = numbers(args_of(call), line, 6)?;
        let p = [v[0], v[1], v[2], v[3], v[4], v[5]];
        let (q, tol_len, tol_ang) = self.to_machine(p);
        let end = Vec3::new(q[0], q[1], q[2]);
        let end_abc = [q[3], q[4], q[5]];
        let start = self.pos_mm;
        let start_abc = self.abc_deg;
        self.pos_mm = end;
        self.abc_deg = end_abc;
        let still = (end - start).amax() <= tol_len
            && end_abc
                .iter()
                .zip(start_abc.iter())
                .all(|(a, b)| (a - b).abs() <= tol_ang);
        if still {
            // Kerf's rule: a zero-length line is not emitted (the control would not move).
            return Ok(());
        }
        let (feed, feed_tol) = match kind {
            MoveKind::Rapid => (None, 0.0),
            _ => {
                let (f, t) = self.feed_now();
                (Some(f), t)
            }
        };
        self.items.push(CanonItem::Move(CanonMove {
            canon_line: line,
            kind,
            start_mm: start,
            end_mm: end,
            start_abc_deg: start_abc,
            end_abc_deg: end_abc,
            arc: None,
            feed_mm_min: feed,
            feed_tol_mm_min: feed_tol,
            tol_mm: tol_len,
            corner: self.corner,
        }));
        Ok(())
    }

    fn arc(&mut self, line: usize, call: &str) -> Result<(), CanonError> {
        let v = numbers(args_of(call), line, 9)?;
        let (fe, se, fa, sa, rot, aep) = (v[0], v[1], v[2], v[3], v[4], v[5]);
        let turns = rot.round();
        if turns == 0.0 || (rot - turns).abs() > 1e-9 {
            self.items.push(CanonItem::Other {
                canon_line: line,
                call: call.to_string(),
            });
            return Ok(());
        }
        // Program end point and centre (the centre's axis coordinate is fixed below).
        let (end_p, center_p, unit_axes) = match self.plane {
            Plane::Xy => ([fe, se, aep], [fa, sa, aep], (0, 1, 2)),
            Plane::Xz => ([se, aep, fe], [sa, aep, fa], (2, 0, 1)),
            Plane::Yz => ([aep, fe, se], [aep, fa, sa], (1, 2, 0)),
        };
        let (qe, tol_len, _) = self.to_machine([end_p[0], end_p[1], end_p[2], v[6], v[7], v[8]]);
        let (qc, _, _) = self.to_machine([center_p[0], center_p[1], center_p[2], v[6], v[7], v[8]]);
        let (s, c) = self.rot_deg.to_radians().sin_cos();
        let unit = |i: usize| -> Vec3 {
            match i {
                0 => Vec3::new(c, s, 0.0),
                1 => Vec3::new(-s, c, 0.0),
                _ => Vec3::new(0.0, 0.0, 1.0),
            }
        };
        let (u, w, n) = (unit(unit_axes.0), unit(unit_axes.1), unit(unit_axes.2));
        let start = self.pos_mm;
        let end = Vec3::new(qe[0], qe[1], qe[2]);
        let mut center = Vec3::new(qc[0], qc[1], qc[2]);
        center -= n * (center - start).dot(&n);
        let rs = start - center;
        let re = end - center;
        let a0 = rs.dot(&w).atan2(rs.dot(&u));
        let a1 = re.dot(&w).atan2(re.dot(&u));
        let r_start = (rs - n * rs.dot(&n)).norm();
        let r_end = (re - n * re.dot(&n)).norm();
        let tau = std::f64::consts::TAU;
        let mut d = if turns > 0.0 { a1 - a0 } else { a0 - a1 };
        d = d.rem_euclid(tau);
        // LinuxCNC makes a whole turn of an arc whose end angle is its start angle (also
        // when the radii differ: a spiral). Within the print precision that is an angle
        // whose arc length is below the position tolerance.
        if d * r_start.max(r_end) <= tol_len {
            d = tau;
        }
        let sweep = (d + (turns.abs() - 1.0) * tau) * turns.signum();
        let (feed, feed_tol) = self.feed_now();
        let start_abc = self.abc_deg;
        let end_abc = [qe[3], qe[4], qe[5]];
        self.pos_mm = end;
        self.abc_deg = end_abc;
        self.items.push(CanonItem::Move(CanonMove {
            canon_line: line,
            kind: MoveKind::Arc,
            start_mm: start,
            end_mm: end,
            start_abc_deg: start_abc,
            end_abc_deg: end_abc,
            arc: Some(CanonArc {
                center_mm: center,
                axis: n,
                sweep_rad: sweep,
                start_radius_mm: r_start,
                end_radius_mm: r_end,
            }),
            feed_mm_min: Some(feed),
            feed_tol_mm_min: feed_tol,
            tol_mm: tol_len,
            corner: self.corner,
        }));
        Ok(())
    }

    fn call(&mut self, line: usize, call: &str) -> Result<bool, CanonError> {
        let name = &call[..call.find('(').unwrap_or(call.len())];
        let args = args_of(call);
        let was_mist_off = std::mem::replace(&mut self.mist_off_just_before, false);
        let was_pallet = std::mem::replace(&mut self.pallet, false);
        match name {
            "USE_LENGTH_UNITS" => {
                self.unit_mm = match args.trim() {
                    "CANON_UNITS_MM" => 1.0,
                    "CANON_UNITS_INCHES" => 25.4,
                    "CANON_UNITS_CM" => 10.0,
                    other => {
                        return Err(CanonError {
                            line,
                            message: format!("unknown length unit {other}"),
                        });
                    }
                }
            }
            "SET_G5X_OFFSET" => {
                let v = numbers(args, line, 7)?;
                self.g5x = self.offset(&v[1..]);
                self.last_g5x_item = self.items.len();
            }
            "SET_G92_OFFSET" => {
                let v = numbers(args, line, 6)?;
                self.g92 = self.offset(&v);
            }
            "USE_TOOL_LENGTH_OFFSET" => {
                let v = numbers(args, line, 6)?;
                self.tool = self.offset(&v);
            }
            "SET_XY_ROTATION" => {
                self.rot_deg = numbers(args, line, 1)?[0];
            }
            "SELECT_PLANE" => {
                self.plane = match args.trim() {
                    "CANON_PLANE_XY" => Plane::Xy,
                    "CANON_PLANE_XZ" => Plane::Xz,
                    "CANON_PLANE_YZ" => Plane::Yz,
                    other => {
                        return Err(CanonError {
                            line,
                            message: format!("plane {other} is not modelled"),
                        });
                    }
                }
            }
            "SET_FEED_RATE" => {
                self.feed = numbers(args, line, 1)?[0];
                self.feed_unit_mm = self.unit_mm;
            }
            "SET_MOTION_CONTROL_MODE" => {
                let (mode, tol) = args.split_once(',').unwrap_or((args, ""));
                self.corner = match mode.trim() {
                    "CANON_EXACT_STOP" => CanonCorner::ExactStop,
                    "CANON_EXACT_PATH" => CanonCorner::ExactPath,
                    "CANON_CONTINUOUS" => CanonCorner::Continuous {
                        tolerance_mm: numbers(tol, line, 1)?[0] * self.unit_mm,
                        tol_mm: 0.5e-6 * self.unit_mm,
                        naive_cam_mm: 0.0,
                        naive_tol_mm: 0.0,
                    },
                    other => {
                        return Err(CanonError {
                            line,
                            message: format!("motion control mode {other} is not modelled"),
                        });
                    }
                };
            }
            "SET_NAIVECAM_TOLERANCE" => {
                let t = numbers(args, line, 1)?[0] * self.unit_mm;
                if let CanonCorner::Continuous {
                    naive_cam_mm,
                    naive_tol_mm,
                    ..
                } = &mut self.corner
                {
                    *naive_cam_mm = t;
                    *naive_tol_mm = 0.5e-4 * self.unit_mm;
                }
            }
            "SET_FEED_MODE" => {
                let v = numbers(args, line, 2)?;
                self.per_rev = v[1] != 0.0;
            }
            "STRAIGHT_TRAVERSE" => self.straight(line, call, MoveKind::Rapid)?,
            "STRAIGHT_FEED" => self.straight(line, call, MoveKind::Feed)?,
            "ARC_FEED" => self.arc(line, call)?,
            "DWELL" => {
                let t = numbers(args, line, 1)?[0];
                self.event(line, EventCode::G4, Some(t), None);
            }
            "SET_SPINDLE_SPEED" => {
                let v = numbers(args, line, 2)?;
                self.spindle_rpm = v[1];
                self.event(line, EventCode::S, Some(v[1]), None);
            }
            "START_SPINDLE_CLOCKWISE" => self.event(line, EventCode::M3, None, None),
            "START_SPINDLE_COUNTERCLOCKWISE" => self.event(line, EventCode::M4, None, None),
            // The spindle stop of a tool change belongs to M6.
            "STOP_SPINDLE_TURNING" if !self.changing_tool => {
                self.event(line, EventCode::M5, None, None);
            }
            "MIST_ON" => self.event(line, EventCode::M7, None, None),
            "FLOOD_ON" => self.event(line, EventCode::M8, None, None),
            "MIST_OFF" => {
                self.event(line, EventCode::M9, None, None);
                self.mist_off_just_before = true;
            }
            // M9 prints MIST_OFF then FLOOD_OFF: one event.
            "FLOOD_OFF" if !was_mist_off => {
                self.event(line, EventCode::M9, None, None);
            }
            "SELECT_TOOL" => {
                let t = numbers(args, line, 1)?[0];
                self.event(line, EventCode::T, Some(t), None);
            }
            "START_CHANGE" => self.changing_tool = true,
            "CHANGE_TOOL" => {
                self.changing_tool = false;
                self.event(line, EventCode::M6, None, None);
            }
            "PALLET_SHUTTLE" => self.pallet = true,
            "PROGRAM_STOP" => {
                let code = if was_pallet {
                    EventCode::M60
                } else {
                    EventCode::M0
                };
                self.event(line, code, None, None);
            }
            "OPTIONAL_PROGRAM_STOP" => self.event(line, EventCode::M1, None, None),
            "PROGRAM_END" => {
                // The spindle and coolant stops of the end's reset belong to M2/M30.
                let from = self.last_g5x_item.min(self.items.len());
                let mut i = from;
                while i < self.items.len() {
                    let reset = matches!(
                        &self.items[i],
                        CanonItem::Event(e) if matches!(e.code, EventCode::M5 | EventCode::M9)
                    );
                    if reset {
                        self.items.remove(i);
                    } else {
                        i += 1;
                    }
                }
                let code = if was_pallet {
                    EventCode::M30
                } else {
                    EventCode::M2
                };
                self.event(line, code, None, None);
                return Ok(false);
            }
            "MESSAGE" => self.event(line, EventCode::Msg, None, Some(quoted(args))),
            // The log calls: Kerf's LOG events hold the call as text.
            "LOGOPEN" | "LOGAPPEND" | "LOG" => {
                let text = format!("{name},{}", quoted(args));
                self.event(line, EventCode::Log, None, Some(text));
            }
            "LOGCLOSE" => self.event(line, EventCode::Log, None, Some("LOGCLOSE".into())),
            "ORIENT_SPINDLE" => {
                // `ORIENT_SPINDLE(spindle, angle, mode)` (M19, and G87's orientations).
                let v = numbers(args, line, 3)?;
                self.event(line, EventCode::M19, Some(v[1]), None);
            }
            // M48 prints ENABLE_FEED_OVERRIDE then ENABLE_SPEED_OVERRIDE (M49 the DISABLE
            // pair), as M50 then M51 would: each call is its own event, and the harness
            // compares Kerf's M48/M49 as that pair (`rs274::compare`).
            "ENABLE_FEED_OVERRIDE" => self.event(line, EventCode::M50, Some(1.0), None),
            "DISABLE_FEED_OVERRIDE" => self.event(line, EventCode::M50, Some(0.0), None),
            "ENABLE_SPEED_OVERRIDE" => self.event(line, EventCode::M51, Some(1.0), None),
            "DISABLE_SPEED_OVERRIDE" => self.event(line, EventCode::M51, Some(0.0), None),
            "ENABLE_ADAPTIVE_FEED" => self.event(line, EventCode::M52, Some(1.0), None),
            "DISABLE_ADAPTIVE_FEED" => self.event(line, EventCode::M52, Some(0.0), None),
            "ENABLE_FEED_HOLD" => self.event(line, EventCode::M53, Some(1.0), None),
            "DISABLE_FEED_HOLD" => self.event(line, EventCode::M53, Some(0.0), None),
            // M62–M65 and M67/M68 (rs274 prints no call for M66's WAIT).
            "SET_MOTION_OUTPUT_BIT" => self.output(line, EventCode::M62, args)?,
            "CLEAR_MOTION_OUTPUT_BIT" => self.output(line, EventCode::M63, args)?,
            "SET_AUX_OUTPUT_BIT" => self.output(line, EventCode::M64, args)?,
            "CLEAR_AUX_OUTPUT_BIT" => self.output(line, EventCode::M65, args)?,
            "SET_MOTION_OUTPUT_VALUE" => self.output(line, EventCode::M67, args)?,
            "SET_AUX_OUTPUT_VALUE" => self.output(line, EventCode::M68, args)?,
            "STRAIGHT_PROBE"
            | "RIGID_TAP"
            | "NURBS_FEED"
            | "START_SPEED_FEED_SYNCH"
            | "START_SPEED_FEED_SYNC"
            | "SPINDLE_RETRACT_TRAVERSE"
            | "USER_DEFINED_FUNCTION"
            | "SET_SPINDLE_MODE_CSS" => {
                self.items.push(CanonItem::Other {
                    canon_line: line,
                    call: call.to_string(),
                });
            }
            "SET_SPINDLE_MODE" => {
                // `SET_SPINDLE_MODE(spindle css_max)`: a non-zero maximum is constant
                // surface speed (G96), which changes the spindle speed with the position.
                let v = numbers(args, line, 2)?;
                if v[1] != 0.0 {
                    self.items.push(CanonItem::Other {
                        canon_line: line,
                        call: call.to_string(),
                    });
                }
            }
            _ => {
                // Everything else changes no position and makes no event of its own:
                // comments, feed reference, motion control mode, overrides, ON_RESET,
                // CHANGE_TOOL_NUMBER, cutter compensation bookkeeping, FINISH, ...
            }
        }
        Ok(true)
    }
}

/// Replays the canon output `text` (rs274's standard output) and returns what the machine
/// does, in order. Reading stops after `PROGRAM_END`.
pub fn parse(text: &str) -> Result<Vec<CanonItem>, CanonError> {
    let mut st = State::new();
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        match split_line(raw) {
            Some((_, call)) => {
                if !st.call(line, call)? {
                    break;
                }
            }
            None if raw.trim().is_empty() => {}
            None => {
                st.mist_off_just_before = false;
                st.pallet = false;
                st.event(line, EventCode::Print, None, Some(raw.to_string()));
            }
        }
    }
    Ok(st.items)
}

/// The canon output line `n` (1-based) of `text`, without its two leading columns.
pub fn call_at(text: &str, n: usize) -> String {
    let raw = text.lines().nth(n.saturating_sub(1)).unwrap_or("");
    match split_line(raw) {
        Some((nw, call)) if nw.starts_with('.') => call.to_string(),
        Some((nw, call)) => format!("N{nw} {call}"),
        None => raw.to_string(),
    }
}
