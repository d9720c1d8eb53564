//! The arc of a motion block: its tolerance and errors per dialect, and the arc path from
//! centre, radius or polar words, with LinuxCNC's whole turns.

use std::f64::consts::TAU;

use kerf_geom::Vec3;

use super::{Block, BlockError, MM_PER_INCH, State, fail};
use crate::Dialect;
use crate::arc::{self, ArcError, Tolerance};
use crate::codes::*;
use crate::lex::{Form, K_CR, K_TURN};

/// Two polar angles closer than this (degrees) name the same point: the angle of a point
/// measured from its coordinates carries rounding errors of about 1e-14°.
const POLAR_SAME_ANGLE_DEG: f64 = 1e-9;

impl State {
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
        let extra_turns = self.arc_turns(blk)?;

        // Heidenhain polar circles: centre = pole, angle H, optional helix along the normal.
        if let Motion::PolarArc(_) = motion {
            return self
                .polar_circle(blk, start, end, ccw, motion_col)
                .map(Some);
        }

        // Out-of-plane centre words.
        self.check_out_of_plane_centre(blk)?;
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
        let centre = self.arc_centre(blk, start, polar, has_centre, abs_centre_once, motion_col)?;

        // Heidenhain: an end point within 0.016 mm of the start is a full circle.
        if d == Dialect::Heidenhain {
            let (du, dv) = (end[u] - start[u], end[v] - start[v]);
            if arc::len2(du, dv) <= 0.016 {
                end[u] = start[u];
                end[v] = start[v];
            }
        }

        // Fagor G91 Q360 (a multiple of 360° incremental about the polar origin): whole circles.
        if let Some(a) = self.fagor_whole_circles(
            blk,
            start,
            end,
            centre,
            ccw,
            polar && !has_centre,
            motion_col,
        )? {
            return Ok(Some(a));
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

    /// The whole turns an arc makes beyond its sweep: LinuxCNC P (the number of turns),
    /// Sinumerik TURN.
    fn arc_turns(&self, blk: &Block) -> Result<u32, BlockError> {
        Ok(match self.dialect {
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
        })
    }

    /// Heidenhain polar circles (G12/G13/G15): centre = pole, angle H, optional helix along
    /// the normal. Sets the end point.
    fn polar_circle(
        &mut self,
        blk: &Block,
        start: Vec3,
        end: &mut Vec3,
        ccw: bool,
        motion_col: u32,
    ) -> Result<kerf_geom::Arc, BlockError> {
        let plane = self.plane;
        let (u, v, w) = plane.axes();
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
        Ok(arc)
    }

    /// The centre of an arc in the plane (frame coordinates): from I, J, K, the pole or
    /// polar origin, or the Heidenhain circle centre.
    pub(super) fn arc_centre(
        &self,
        blk: &Block,
        start: Vec3,
        polar: bool,
        has_centre: bool,
        abs_centre_once: bool,
        motion_col: u32,
    ) -> Result<(f64, f64), BlockError> {
        let d = self.dialect;
        let (u, v, _) = self.plane.axes();
        let s = self.scale();
        Ok(match d {
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
        })
    }

    /// Fagor: `G91 Q` a non-zero multiple of 360° about the polar origin makes whole
    /// circles ending at the start; `None` otherwise.
    #[allow(clippy::too_many_arguments)]
    fn fagor_whole_circles(
        &self,
        blk: &Block,
        start: Vec3,
        end: &mut Vec3,
        centre: (f64, f64),
        ccw: bool,
        polar_about_origin: bool,
        motion_col: u32,
    ) -> Result<Option<kerf_geom::Arc>, BlockError> {
        let plane = self.plane;
        let (u, v, _) = plane.axes();
        if self.dialect == Dialect::Fagor
            && polar_about_origin
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
        Ok(None)
    }

    /// A centre word along the plane's normal (K in G17): an error, except in Heidenhain.
    fn check_out_of_plane_centre(&self, blk: &Block) -> Result<(), BlockError> {
        let d = self.dialect;
        let plane = self.plane;
        let (_, _, w) = plane.axes();
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
        Ok(())
    }
}
