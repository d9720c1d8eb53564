//! Geometry of one motion block: end points (Cartesian and polar), poles and arcs.

use std::f64::consts::TAU;

use kerf_geom::{CornerMode, Line, Move, Path, Vec3};

use super::modal::MoveFeed;
use super::{Block, BlockError, MM_PER_INCH, Out, State, fail};
use crate::arc::{self, ArcError, Tolerance};
use crate::codes::*;
use crate::lex::{Form, K_AP, K_AT, K_CARET, K_CR, K_RP, K_TURN};
use crate::{Dialect, Item};

/// Two polar angles closer than this (degrees) name the same point: the angle of a point
/// measured from its coordinates carries rounding errors of about 1e-14°.
const POLAR_SAME_ANGLE_DEG: f64 = 1e-9;

impl State {
    /// The machine coordinate of linear axis `i` after a word with `value`, honouring the
    /// word's form, the modal distance mode and the program origin.
    pub(super) fn linear_target(&self, blk: &Block, k: u8, i: usize) -> f64 {
        match blk.get(k) {
            None => self.pos[i],
            Some(v) => {
                let v = v * self.scale();
                if self.word_absolute(blk, k) {
                    v + self.origin[i]
                } else {
                    self.pos[i] + v
                }
            }
        }
    }

    pub(super) fn word_absolute(&self, blk: &Block, k: u8) -> bool {
        match blk.forms[k as usize] {
            Form::Abs => true,
            Form::Inc => false,
            Form::Plain => self.absolute,
        }
    }

    pub(super) fn abc_target(&self, blk: &Block) -> [f64; 3] {
        let mut abc = self.abc;
        for (i, &k) in ABC.iter().enumerate() {
            if let Some(v) = blk.get(k) {
                abc[i] = if self.word_absolute(blk, k) {
                    v + self.origin_abc[i]
                } else {
                    self.abc[i] + v
                };
            }
        }
        abc
    }

    pub(super) fn set_sinumerik_pole(
        &mut self,
        blk: &Block,
        r: PoleRef,
        col: u32,
    ) -> Result<(), BlockError> {
        let (u, v, _) = self.plane.axes();
        let reference = match r {
            PoleRef::LastPosition => self.pos,
            PoleRef::Workpiece => self.origin,
            PoleRef::LastPole => self.pole.unwrap_or(self.origin),
        };
        let mut pole = reference;
        let polar = blk.has(K_RP) || blk.has(K_AP);
        let cart = blk.has(XYZ[u]) || blk.has(XYZ[v]);
        if polar && cart {
            return fail(col, "pole given both in polar and in Cartesian coordinates");
        }
        if polar {
            let rp = blk.get(K_RP).unwrap_or(0.0) * self.scale();
            let ap = blk.get(K_AP).unwrap_or(0.0).to_radians();
            pole[u] += rp * ap.cos();
            pole[v] += rp * ap.sin();
        } else {
            for (i, &k) in XYZ.iter().enumerate() {
                if let Some(val) = blk.get(k) {
                    // G110/G111/G112 are not affected by G90/G91 (only AC/IC forms matter).
                    pole[i] = reference[i] + val * self.scale();
                }
            }
        }
        self.pole = Some(pole);
        self.rp_mm = None;
        self.ap_deg = None;
        Ok(())
    }

    pub(super) fn set_fagor_origin(&mut self, blk: &Block, _col: u32) -> Result<(), BlockError> {
        let mut o = self.pos;
        let given = blk.any(&IJK);
        if given {
            let (u, v, w) = self.plane.axes();
            if let Some(k) = blk.first_of(&[IJK[w]]) {
                return fail(
                    blk.col(k),
                    format!("{} word in {} plane", key_name(k), self.plane.name()),
                );
            }
            o = self.origin;
            for i in [u, v] {
                if let Some(val) = blk.get(IJK[i]) {
                    o[i] = self.origin[i] + val * self.scale();
                }
            }
            o[w] = self.pos[w];
        }
        self.polar_origin = Some(o);
        self.polar_last = None;
        Ok(())
    }

    pub(super) fn set_heidenhain_cc(&mut self, blk: &Block) -> Result<(), BlockError> {
        let mut cc = self.pos;
        for (i, &k) in IJK.iter().enumerate() {
            if let Some(v) = blk.get(k) {
                let v = v * self.scale();
                cc[i] = if self.word_absolute(blk, k) {
                    v + self.origin[i]
                } else {
                    self.pos[i] + v
                };
            }
        }
        self.cc = Some(cc);
        self.polar_last = None;
        Ok(())
    }

    pub(super) fn arc_tolerance(&self) -> Tolerance {
        match self.dialect {
            Dialect::LinuxCnc => Tolerance::LinuxCnc {
                t_mm: if self.inch {
                    0.002828 * MM_PER_INCH
                } else {
                    0.02828
                },
            },
            _ => Tolerance::AbsRel {
                abs_mm: self.settings.arc_tolerance_mm,
                rel: self.settings.arc_tolerance_rel,
            },
        }
    }

    pub(super) fn arc_error(&self, e: ArcError, col: u32) -> BlockError {
        let message = match e {
            ArcError::ZeroRadius => "zero-radius arc".to_string(),
            ArcError::RadiusTooSmall => "arc radius too small to reach end point".to_string(),
            ArcError::SamePoint => match self.dialect {
                Dialect::Sinumerik => "CR= cannot program a full circle".to_string(),
                Dialect::Heidenhain => "a full circle with R needs two half circles".to_string(),
                Dialect::Fagor => "R cannot program a full circle".to_string(),
                _ => "current point same as end point of arc".to_string(),
            },
            ArcError::EndRadiusDiffers { r_start, r_end } => {
                let what = match self.dialect {
                    Dialect::Sinumerik => "circle end point error",
                    Dialect::Heidenhain => "circle end position incorrect",
                    _ => "radius to end of arc differs from radius to start",
                };
                format!("{what}: r1={r_start:.4} mm r2={r_end:.4} mm")
            }
        };
        BlockError { col, message }
    }

    /// One motion block. While LinuxCNC cutter compensation is active, the block's end point
    /// is resolved from the programmed point (as LinuxCNC does) and `comp` makes the moves.
    pub(super) fn motion(
        &mut self,
        blk: &Block,
        out: &mut Out<'_>,
        motion_col: u32,
        machine: Option<u32>,
        exact_once: bool,
        abs_centre_once: bool,
    ) -> Result<(), BlockError> {
        if self.dialect != Dialect::LinuxCnc {
            return self.motion_inner(blk, out, motion_col, machine, exact_once, abs_centre_once);
        }
        if let Some(reference) = self.crc.exit_ref {
            // The move after G40: its words refer to the programmed point (LinuxCNC's
            // current point after G40); it starts where the tool is.
            let actual = self.pos;
            self.pos = reference;
            self.crc.exit_actual = Some(actual);
            let r = self.motion_inner(blk, out, motion_col, machine, exact_once, abs_centre_once);
            if self.crc.exit_actual.take().is_some() {
                self.pos = actual;
            }
            return r;
        }
        if !self.comp_active() {
            return self.motion_inner(blk, out, motion_col, machine, exact_once, abs_centre_once);
        }
        let actual = self.pos;
        if let Some(p) = self.comp_reference() {
            self.pos = p;
        }
        self.crc.actual = Some(actual);
        let r = self.motion_inner(blk, out, motion_col, machine, exact_once, abs_centre_once);
        if self.crc.actual.take().is_some() {
            // No move was made: the position stays the compensated one.
            self.pos = actual;
        }
        r
    }

    #[allow(clippy::too_many_arguments)]
    fn motion_inner(
        &mut self,
        blk: &Block,
        out: &mut Out<'_>,
        motion_col: u32,
        machine: Option<u32>,
        exact_once: bool,
        abs_centre_once: bool,
    ) -> Result<(), BlockError> {
        let d = self.dialect;
        let (u, v, w) = self.plane.axes();
        let has_axes = blk.any(&XYZ) || blk.any(&ABC);
        if blk.any(&ABC) {
            self.abc_used = true;
        }
        let Some(motion) = self.motion else {
            let polar_words: &[u8] = match d {
                Dialect::LinuxCnc => &[K_AT, K_CARET],
                Dialect::Sinumerik => &[K_RP, K_AP],
                Dialect::Heidenhain => &[KR, KH],
                Dialect::Fagor => &[KR, KQ],
                Dialect::Rockwell => &[],
            };
            if has_axes || blk.any(polar_words) {
                let k = blk
                    .first_of(&[KX, KY, KZ, KA, KB, KC])
                    .or(blk.first_of(polar_words))
                    .unwrap_or(KX);
                return fail(
                    blk.col(k),
                    "cannot use axis values without a G code that uses them",
                );
            }
            return self.check_unused(blk, false);
        };
        let has_polar = match d {
            Dialect::LinuxCnc => blk.has(K_AT) || blk.has(K_CARET),
            Dialect::Sinumerik => blk.has(K_RP) || blk.has(K_AP),
            Dialect::Heidenhain => {
                blk.has(KH)
                    || (blk.has(KR)
                        && matches!(motion, Motion::PolarLine { .. } | Motion::PolarArc(_)))
            }
            Dialect::Fagor => blk.has(KQ) || (blk.has(KR) && !blk.has(XYZ[u]) && !blk.has(XYZ[v])),
            Dialect::Rockwell => false,
        };
        let is_arc = matches!(motion, Motion::Arc(_) | Motion::PolarArc(_));
        let has_centre = blk.any(&IJK) && d != Dialect::Heidenhain;
        let has_radius = match d {
            Dialect::Sinumerik => blk.has(K_CR),
            Dialect::Heidenhain => blk.has(KR) && matches!(motion, Motion::Arc(_)),
            Dialect::Fagor => blk.has(KR) && (blk.has(XYZ[u]) || blk.has(XYZ[v])),
            _ => blk.has(KR),
        };
        let wants_motion = has_axes
            || has_polar
            || (is_arc && (has_centre || blk.has(K_TURN)) && d != Dialect::Heidenhain);
        if !wants_motion {
            return self.check_unused(blk, false);
        }
        self.check_unused(blk, is_arc)?;
        if d == Dialect::LinuxCnc {
            self.comp_check_arc(is_arc, motion_col)?;
        }

        // G53's conditions come first, as rs274 checks them.
        if let Some(col) = machine {
            if !self.absolute {
                return fail(col, "Cannot use g53 incremental");
            }
            if !matches!(motion, Motion::Rapid | Motion::Linear) {
                return fail(col, "Must use g0 or g1 with g53");
            }
            self.comp_refuse(col, "Cannot use g53 with cutter radius comp")?;
        }

        // Feed.
        let rapid = match motion {
            Motion::Rapid => true,
            Motion::PolarLine { rapid } => rapid,
            _ => false,
        };
        let feed = if rapid {
            None
        } else {
            Some(self.move_feed(blk, is_arc, motion_col)?)
        };

        let start = self.pos;
        let mut abc_end = self.abc_target(blk);
        if machine.is_some() {
            for (i, &k) in ABC.iter().enumerate() {
                if let Some(v) = blk.get(k) {
                    abc_end[i] = v;
                }
            }
        }
        let mut end = start;
        let mut new_polar: Option<(f64, f64)> = None;

        // End point.
        if machine.is_some() {
            // Machine coordinates: the named axes go there, the others stay where they
            // are on the machine (under a rotated system too).
            let mut m = self.frame_to_machine(start);
            for (i, &k) in XYZ.iter().enumerate() {
                if let Some(val) = blk.get(k) {
                    m[i] = val * self.scale();
                }
            }
            end = self.machine_to_frame(m);
        } else if has_polar && !matches!(motion, Motion::PolarArc(_)) {
            let (r, a_deg) = self.polar_end(blk, motion)?;
            let pole = self.polar_reference();
            let a = a_deg.to_radians();
            // LinuxCNC polar words always give X and Y; the others work in the active plane.
            let (pu, pv, pw) = if d == Dialect::LinuxCnc {
                (0, 1, 2)
            } else {
                (u, v, w)
            };
            end[pu] = pole[pu] + r * a.cos();
            end[pv] = pole[pv] + r * a.sin();
            end[pw] = self.linear_target(blk, XYZ[pw], pw);
            new_polar = Some((r, a_deg));
        } else {
            for (i, &k) in XYZ.iter().enumerate() {
                end[i] = self.linear_target(blk, k, i);
            }
        }

        let corner = if exact_once {
            CornerMode::ExactStop
        } else {
            self.corner
        };
        let abc = if self.abc_used {
            Some((self.abc, abc_end))
        } else {
            None
        };

        let path = match motion {
            Motion::Rapid | Motion::Linear | Motion::PolarLine { .. } => {
                // After a tool change's read-back the move starts where the machine is.
                let (start, abc_start) = match (self.crc.exit_actual, self.readback_from) {
                    (Some(p), _) => (p, self.abc),
                    (None, Some((p, abc))) => (p, abc),
                    (None, None) => (start, self.abc),
                };
                if (end - start).norm() < arc::SAME_POINT_MM && abc_end == abc_start {
                    // A zero-length line moves nothing; it is not emitted. (A polar end point
                    // a whole turn round can differ from the start by a rounding error.)
                    self.polar_last = new_polar;
                    return Ok(());
                }
                Path::Line(Line { start, end })
            }
            Motion::Cycle(_) => {
                // Canned cycles are resolved by `State::cycle`, never here.
                return fail(motion_col, "canned cycle outside its resolution");
            }
            Motion::Arc(dir) | Motion::PolarArc(dir) => {
                let ccw = match dir.or(self.last_ccw) {
                    Some(c) => c,
                    None => {
                        return fail(
                            motion_col,
                            "no direction of rotation programmed before G05/G15",
                        );
                    }
                };
                match self.arc_path(
                    blk,
                    motion,
                    start,
                    &mut end,
                    ccw,
                    has_polar,
                    has_radius,
                    abs_centre_once,
                    motion_col,
                )? {
                    Some(a) => {
                        self.last_ccw = Some(ccw);
                        Path::Arc(a)
                    }
                    None => {
                        // Rockwell: R with the end point equal to the start is a 0° arc.
                        return Ok(());
                    }
                }
            }
        };
        let finite = |p: &Vec3| p.iter().all(|x| x.is_finite());
        let finite_path = match &path {
            Path::Line(l) => finite(&l.start) && finite(&l.end),
            Path::Arc(a) => {
                finite(&a.start) && finite(&a.end) && finite(&a.center) && a.sweep_rad.is_finite()
            }
        };
        if !finite_path || !abc_end.iter().all(|x| x.is_finite()) {
            return fail(blk.first_col, "coordinate out of range");
        }
        let feed = match feed {
            Some(MoveFeed::MmMin(f)) => Some(f),
            Some(f) => Some(self.feed_rate_mm_min(f, &path, self.abc, abc_end)),
            None => None,
        };
        let mv = Move {
            line: out.line,
            rapid,
            path: self.path_to_machine(path),
            feed_mm_min: feed,
            abc_deg: abc,
            corner,
        };
        if self.crc.actual.is_some() && self.rotation_deg != 0.0 {
            // Compensation works in the frame of the program; with a rotated coordinate
            // system the frame and the machine differ, which comp does not model.
            return fail(
                motion_col,
                "cutter compensation in a rotated coordinate system (G10 L2 R) is not supported",
            );
        }
        if let Some(actual) = self.crc.actual.take() {
            self.pos = actual;
            self.comp_move(mv, motion_col, out)?;
            self.abc = abc_end;
            self.polar_last = None;
            return Ok(());
        }
        if self.crc.exit_actual.take().is_some() {
            self.crc.exit_ref = None;
        }
        out.items.push(Item::Move(mv));
        self.pos = path.end();
        if let Some(tail) = self.arc_tail.take() {
            // The radial line after LinuxCNC's whole turn (`arc_path`).
            let line = Path::Line(Line {
                start: path.end(),
                end: tail,
            });
            out.items.push(Item::Move(Move {
                line: out.line,
                rapid,
                path: self.path_to_machine(line),
                feed_mm_min: feed,
                abc_deg: abc.map(|_| (abc_end, abc_end)),
                corner,
            }));
            self.pos = tail;
        }
        self.abc = abc_end;
        if !matches!(motion, Motion::PolarArc(_)) {
            self.polar_last = new_polar;
        }
        Ok(())
    }

    /// Errors for words no G code of this block uses (LinuxCNC is strict about them).
    pub(super) fn check_unused(&self, blk: &Block, arc: bool) -> Result<(), BlockError> {
        if !arc {
            let centre_words: &[u8] = match self.dialect {
                Dialect::Heidenhain => &[],
                Dialect::Sinumerik => &[KI, KJ, KK, K_CR, K_TURN],
                Dialect::Fagor => &[KI, KJ, KK],
                // LinuxCNC M19 takes R (its angle).
                Dialect::LinuxCnc if self.m19_in_block => &[KI, KJ, KK],
                _ => &[KI, KJ, KK, KR],
            };
            if let Some(k) = blk.first_of(centre_words) {
                if self.dialect == Dialect::LinuxCnc {
                    return fail(blk.col(k), super::cycles::unused_word_message(k));
                }
                return fail(
                    blk.col(k),
                    format!("{} word with no G2 or G3 to use it", key_name(k)),
                );
            }
        }
        Ok(())
    }

    /// The point polar coordinates refer to, machine coordinates.
    pub(super) fn polar_reference(&self) -> Vec3 {
        match self.dialect {
            Dialect::LinuxCnc => self.origin,
            Dialect::Sinumerik => self.pole.unwrap_or(self.origin),
            Dialect::Heidenhain => self.cc.unwrap_or(self.origin),
            Dialect::Fagor => self.polar_origin.unwrap_or(self.origin),
            Dialect::Rockwell => self.origin,
        }
    }

    /// The axes polar coordinates work in: X and Y for LinuxCNC `@ ^`, the active plane
    /// for the other controls.
    pub(super) fn polar_axes(&self) -> (usize, usize) {
        if self.dialect == Dialect::LinuxCnc {
            (0, 1)
        } else {
            let (u, v, _) = self.plane.axes();
            (u, v)
        }
    }

    /// The current position in polar coordinates about the reference: for Heidenhain and
    /// Fagor the programmed values when the last move was polar about the same reference,
    /// else (and always for LinuxCNC, which measures the current point about the current
    /// program zero) measured from the position.
    pub(super) fn current_polar(&self) -> (f64, f64) {
        if let Some(p) = self
            .polar_last
            .filter(|_| self.dialect != Dialect::LinuxCnc)
        {
            return p;
        }
        self.measured_polar()
    }

    /// The current position's polar radius (mm) and angle (degrees, −180..180) about the
    /// reference, measured from the position alone.
    pub(super) fn measured_polar(&self) -> (f64, f64) {
        let pole = self.polar_reference();
        let (u, v) = self.polar_axes();
        let du = self.pos[u] - pole[u];
        let dv = self.pos[v] - pole[v];
        (arc::len2(du, dv), dv.atan2(du).to_degrees())
    }

    /// Polar radius (mm) and angle (degrees) of the end point.
    pub(super) fn polar_end(
        &mut self,
        blk: &Block,
        motion: Motion,
    ) -> Result<(f64, f64), BlockError> {
        let d = self.dialect;
        let (u, v, _) = self.plane.axes();
        let cart = match d {
            Dialect::LinuxCnc => blk.first_of(&[KX, KY]),
            _ => blk.first_of(&[XYZ[u], XYZ[v]]),
        };
        if let Some(k) = cart {
            return fail(
                blk.col(k),
                "mixed polar and Cartesian coordinates in the plane",
            );
        }
        let s = self.scale();
        match d {
            Dialect::LinuxCnc => {
                if !matches!(motion, Motion::Rapid | Motion::Linear) {
                    let k = blk.first_of(&[K_AT, K_CARET]).unwrap_or(K_AT);
                    return fail(
                        blk.col(k),
                        "polar coordinates (@ ^) can only be used with G0 and G1",
                    );
                }
                let (r0, a0) = self.current_polar();
                let at = blk.get(K_AT).map(|x| x * s);
                let caret = blk.get(K_CARET);
                // At program zero the current point has no angle: LinuxCNC refuses what
                // would need it, in its own words.
                let at_zero = r0 < 1e-9;
                if self.absolute {
                    if at_zero && caret.is_none() {
                        return fail(
                            blk.col(K_AT),
                            "Must specify angle in polar coordinate if at the origin",
                        );
                    }
                    Ok((at.unwrap_or(r0), caret.unwrap_or(a0)))
                } else {
                    if at_zero {
                        let (k, message) = if at.is_some() {
                            (
                                K_AT,
                                "Incremental motion with polar coordinates is indeterminate when at the origin",
                            )
                        } else {
                            (
                                K_CARET,
                                "G91 motion with polar coordinates is indeterminate when at the origin",
                            )
                        };
                        return fail(blk.col(k), message);
                    }
                    Ok((r0 + at.unwrap_or(0.0), a0 + caret.unwrap_or(0.0)))
                }
            }
            Dialect::Sinumerik => {
                let rp = match blk.get(K_RP) {
                    Some(r) => {
                        let r = r * s;
                        let r = if blk.forms[K_RP as usize] == Form::Inc {
                            self.rp_mm.unwrap_or(0.0) + r
                        } else {
                            r
                        };
                        if r < 0.0 {
                            return fail(blk.col(K_RP), "polar radius RP must not be negative");
                        }
                        r
                    }
                    None => match self.rp_mm {
                        Some(r) => r,
                        None => {
                            return fail(
                                blk.col(K_AP),
                                "polar radius RP not programmed (required after a pole or plane change)",
                            );
                        }
                    },
                };
                let ap = match blk.get(K_AP) {
                    Some(a) if blk.forms[K_AP as usize] == Form::Inc => match self.ap_deg {
                        Some(a0) => a0 + a,
                        None => {
                            return fail(blk.col(K_AP), "AP=IC() needs a previous polar angle AP");
                        }
                    },
                    Some(a) => a,
                    None => match self.ap_deg {
                        Some(a) => a,
                        None => {
                            return fail(
                                blk.col(K_RP),
                                "polar angle AP not programmed (required after a pole or plane change)",
                            );
                        }
                    },
                };
                if !(-360.0..=360.0).contains(&blk.get(K_AP).unwrap_or(0.0)) {
                    return fail(
                        blk.col(K_AP),
                        "polar angle AP out of range (-360..360 degrees)",
                    );
                }
                self.rp_mm = Some(rp);
                self.ap_deg = Some(ap);
                Ok((rp, ap))
            }
            Dialect::Heidenhain | Dialect::Fagor => {
                let (rk, ak) = if d == Dialect::Heidenhain {
                    (KR, KH)
                } else {
                    (KR, KQ)
                };
                if d == Dialect::Heidenhain
                    && !matches!(motion, Motion::PolarLine { .. } | Motion::PolarArc(_))
                {
                    let k = blk.first_of(&[KH, KR]).unwrap_or(KH);
                    return fail(
                        blk.col(k),
                        "polar coordinates need G10, G11, G12, G13 or G15",
                    );
                }
                if self.dialect == Dialect::Heidenhain && self.cc.is_none() {
                    return fail(blk.first_col, "pole (I, J) not defined");
                }
                let (r0, a0) = self.current_polar();
                let r = match blk.get(rk) {
                    Some(r) if self.word_absolute(blk, rk) => r * s,
                    Some(r) => r0 + r * s,
                    None => r0,
                };
                if r < 0.0 {
                    return fail(blk.col(rk), "polar radius must not be negative");
                }
                let a = match blk.get(ak) {
                    Some(a) => {
                        let limit =
                            if matches!(motion, Motion::PolarArc(_)) && d == Dialect::Heidenhain {
                                5400.0
                            } else if d == Dialect::Heidenhain {
                                360.0
                            } else {
                                f64::INFINITY
                            };
                        if a.abs() > limit {
                            return fail(
                                blk.col(ak),
                                format!(
                                    "polar angle {} out of range (-{limit}..+{limit} degrees)",
                                    key_name(ak)
                                ),
                            );
                        }
                        if self.word_absolute(blk, ak) {
                            a
                        } else {
                            a0 + a
                        }
                    }
                    None => a0,
                };
                Ok((r, a))
            }
            Dialect::Rockwell => Ok(self.current_polar()),
        }
    }

    #[allow(clippy::too_many_arguments)]
    pub(super) fn arc_path(
        &mut self,
        blk: &Block,
        motion: Motion,
        start: Vec3,
        end: &mut Vec3,
        ccw: bool,
        polar: bool,
        has_radius: bool,
        abs_centre_once: bool,
        motion_col: u32,
    ) -> Result<Option<kerf_geom::Arc>, BlockError> {
        let d = self.dialect;
        let plane = self.plane;
        let (u, v, w) = plane.axes();
        let s = self.scale();
        let tol = self.arc_tolerance();

        // Turns.
        let extra_turns: u32 = match d {
            Dialect::LinuxCnc => match blk.get(KP) {
                Some(p) => {
                    if p.fract() != 0.0 || !(1.0..=1e6).contains(&p) {
                        return fail(
                            blk.col(KP),
                            "P word with G2 or G3 must be a positive integer",
                        );
                    }
                    p as u32 - 1
                }
                None => 0,
            },
            Dialect::Sinumerik => match blk.get(K_TURN) {
                Some(t) => {
                    if t.fract() != 0.0 || !(0.0..=999.0).contains(&t) {
                        return fail(blk.col(K_TURN), "TURN must be an integer from 0 to 999");
                    }
                    t as u32
                }
                None => 0,
            },
            _ => 0,
        };

        // Heidenhain polar circles: centre = pole, angle H, optional helix along the normal.
        if let Motion::PolarArc(_) = motion {
            let Some(cc) = self.cc else {
                return fail(motion_col, "pole (I, J) not defined");
            };
            if let Some(k) = blk.first_of(&[XYZ[u], XYZ[v], KR]) {
                return fail(
                    blk.col(k),
                    format!(
                        "{} not allowed in a polar circle (G12/G13/G15): the radius is the distance to the pole",
                        key_name(k)
                    ),
                );
            }
            let (r0, a0) = self.current_polar();
            if r0 < arc::SAME_POINT_MM {
                return fail(motion_col, "zero-radius arc: the start point is the pole");
            }
            let Some(h) = blk.get(KH) else {
                return fail(motion_col, "polar angle H missing");
            };
            if h.abs() > 5400.0 {
                return fail(
                    blk.col(KH),
                    "polar angle H out of range (-5400..+5400 degrees)",
                );
            }
            let (sweep_deg, a_end) = if self.word_absolute(blk, KH) {
                // Absolute H is the angular position of the end point (seed 004), a point:
                // H and H ± 360° name the same one. The arc runs from the start point in
                // the programmed direction to that point, less than one turn, or one whole
                // turn when it is the start point. The start's angle is measured from its
                // position, never taken from how it was programmed (after `H-360` or
                // `H+0` or a Cartesian move to the same point, `G13 H+5` sweeps 5°).
                let (_, a_start) = self.measured_polar();
                let mut ahead = (h - a_start).rem_euclid(360.0);
                if !(POLAR_SAME_ANGLE_DEG..=360.0 - POLAR_SAME_ANGLE_DEG).contains(&ahead) {
                    ahead = 0.0;
                }
                let sweep = match (ccw, ahead == 0.0) {
                    (true, true) => 360.0,
                    (true, false) => ahead,
                    (false, true) => -360.0,
                    (false, false) => ahead - 360.0,
                };
                (sweep, h)
            } else {
                if h == 0.0 || (h > 0.0) != ccw {
                    return fail(
                        blk.col(KH),
                        "incremental polar angle and direction of rotation disagree",
                    );
                }
                (h, a0 + h)
            };
            if sweep_deg % 360.0 == 0.0 {
                // Whole turns end exactly where they started, not one rounding away.
                end[u] = start[u];
                end[v] = start[v];
            } else {
                let a = a_end.to_radians();
                end[u] = cc[u] + r0 * a.cos();
                end[v] = cc[v] + r0 * a.sin();
            }
            end[w] = self.linear_target(blk, XYZ[w], w);
            let arc = arc::make_arc(start, *end, (cc[u], cc[v]), plane, sweep_deg.to_radians());
            self.polar_last = Some((r0, a_end));
            return Ok(Some(arc));
        }

        // Out-of-plane centre words.
        if d != Dialect::Heidenhain
            && let Some(k) = blk.first_of(&[IJK[w]])
        {
            let message = if d == Dialect::LinuxCnc {
                format!(
                    "{} word given for arc in {} plane",
                    key_name(k),
                    plane.name()
                )
            } else {
                format!("{} word in {} plane", key_name(k), plane.name())
            };
            return fail(blk.col(k), message);
        }
        let has_centre = blk.has(IJK[u]) || blk.has(IJK[v]);

        // Radius format.
        let use_radius = match d {
            Dialect::LinuxCnc => {
                if has_radius && has_centre {
                    return fail(blk.col(KR), "mixed radius and centre format");
                }
                has_radius
            }
            Dialect::Sinumerik => {
                if has_radius && has_centre {
                    return fail(blk.col(K_CR), "mixed radius and centre format");
                }
                if has_radius && polar {
                    return fail(
                        blk.col(K_CR),
                        "CR= cannot be combined with polar coordinates",
                    );
                }
                if has_radius && blk.has(K_TURN) {
                    return fail(blk.col(K_TURN), "TURN cannot be combined with CR=");
                }
                has_radius
            }
            // Rockwell 9/Series: R and I/J/K in one block, R wins.
            Dialect::Rockwell => has_radius,
            Dialect::Heidenhain | Dialect::Fagor => {
                if has_radius && has_centre && d == Dialect::Fagor {
                    return fail(blk.col(KR), "mixed radius and centre format");
                }
                has_radius
            }
        };
        if use_radius {
            let rk = if d == Dialect::Sinumerik { K_CR } else { KR };
            let r = blk.vals[rk as usize] * s;
            if d == Dialect::Rockwell && arc::same_in_plane(&start, end, plane) {
                if (end[w] - start[w]).abs() > 0.0 {
                    return fail(blk.col(rk), "a radius arc needs an end point in the plane");
                }
                return Ok(None);
            }
            let slack = if d == Dialect::LinuxCnc {
                0.00127
            } else {
                self.settings.arc_tolerance_mm
            };
            return arc::arc_from_radius(start, *end, r, plane, ccw, extra_turns, slack)
                .map(Some)
                .map_err(|e| self.arc_error(e, blk.col(rk)));
        }

        // Centre.
        let centre = match d {
            Dialect::LinuxCnc | Dialect::Rockwell | Dialect::Sinumerik => {
                if !has_centre && !polar {
                    let message = match d {
                        Dialect::LinuxCnc => "R, I, J, and K words all missing for arc",
                        Dialect::Sinumerik => "circle centre (I, J, K) or CR= missing",
                        _ => "I, J, K or R missing for arc",
                    };
                    return fail(motion_col, message);
                }
                if polar {
                    if has_centre {
                        let k = blk.first_of(&IJK).unwrap_or(KI);
                        return fail(
                            blk.col(k),
                            "a polar circle turns about the pole: I, J, K not allowed",
                        );
                    }
                    let p = self.pole.unwrap_or(self.origin);
                    (p[u], p[v])
                } else {
                    let mut c = [0.0; 2];
                    for (slot, &i) in [u, v].iter().enumerate() {
                        let k = IJK[i];
                        let val = blk.get(k).unwrap_or(0.0) * s;
                        let absolute = match blk.forms[k as usize] {
                            Form::Abs => true,
                            Form::Inc => false,
                            Form::Plain => d == Dialect::LinuxCnc && self.arc_absolute,
                        };
                        c[slot] = if absolute && blk.has(k) {
                            val + self.origin[i]
                        } else if absolute {
                            // LinuxCNC G90.1 needs both centre words of the plane.
                            return fail(
                                motion_col,
                                format!("{} word missing in absolute center arc", key_name(k)),
                            );
                        } else {
                            start[i] + val
                        };
                    }
                    (c[0], c[1])
                }
            }
            Dialect::Heidenhain => match self.cc {
                Some(cc) => (cc[u], cc[v]),
                None => return fail(motion_col, "circle centre (I, J) not defined"),
            },
            Dialect::Fagor => {
                if has_centre {
                    let mut c = [0.0; 2];
                    for (slot, &i) in [u, v].iter().enumerate() {
                        let val = blk.get(IJK[i]).unwrap_or(0.0) * s;
                        c[slot] = if abs_centre_once {
                            self.origin[i] + val
                        } else {
                            start[i] + val
                        };
                    }
                    (c[0], c[1])
                } else {
                    let o = self.polar_origin.unwrap_or(self.origin);
                    (o[u], o[v])
                }
            }
        };

        // Heidenhain: an end point within 0.016 mm of the start is a full circle.
        if d == Dialect::Heidenhain {
            let (du, dv) = (end[u] - start[u], end[v] - start[v]);
            if arc::len2(du, dv) <= 0.016 {
                end[u] = start[u];
                end[v] = start[v];
            }
        }

        // Fagor G91 Q360 (a multiple of 360° incremental about the polar origin): whole circles.
        if d == Dialect::Fagor
            && polar
            && !has_centre
            && let (Some(q), false) = (blk.get(KQ), self.word_absolute(blk, KQ))
        {
            let turns = (q / 360.0).round();
            if q != 0.0 && (q - turns * 360.0).abs() < 1e-9 {
                let sweep = turns.abs() * TAU * if ccw { 1.0 } else { -1.0 };
                let arc = arc::make_arc(start, *end, centre, plane, sweep);
                let r = arc::len2(start[u] - centre.0, start[v] - centre.1);
                if r < arc::SAME_POINT_MM {
                    return fail(motion_col, "zero-radius arc");
                }
                let mut a = arc;
                a.end[u] = start[u];
                a.end[v] = start[v];
                *end = a.end;
                return Ok(Some(a));
            }
        }

        let col = if has_centre {
            blk.first_of(&IJK).map_or(motion_col, |k| blk.col(k))
        } else {
            motion_col
        };
        let arc = arc::arc_from_center(start, *end, centre, plane, ccw, extra_turns, tol)
            .map_err(|e| self.arc_error(e, col))?;
        if d == Dialect::LinuxCnc && arc::end_on_start_ray(&start, end, centre, plane) {
            // LinuxCNC turns a whole circle about the programmed centre, spiralling to the
            // end radius. Kerf's arcs are exact circles: the whole turn at the start radius
            // (the helix reaching the end's height), then the radial line to the end, which
            // is as long as the radii differ (within the arc tolerance checked above).
            if self.crc.actual.is_some() {
                return fail(
                    col,
                    "an arc whose end lies on the ray from its centre through its start (a whole turn that changes radius) is not supported with cutter compensation",
                );
            }
            if self.feed_mode == super::FeedMode::InverseTime {
                return fail(
                    col,
                    "an arc whose end lies on the ray from its centre through its start (a whole turn that changes radius) is not supported in inverse time (G93)",
                );
            }
            let mut turn_end = start;
            turn_end[w] = end[w];
            let whole = arc::arc_from_center(start, turn_end, centre, plane, ccw, extra_turns, tol)
                .map_err(|e| self.arc_error(e, col))?;
            self.arc_tail = Some(*end);
            *end = whole.end;
            return Ok(Some(whole));
        }
        Ok(Some(arc))
    }
}
