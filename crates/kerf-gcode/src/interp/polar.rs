//! Poles and polar coordinates: the Sinumerik pole, the Fagor polar origin, the
//! Heidenhain circle centre and pole, and the polar end point of a move about them.

use kerf_geom::Vec3;

use super::{Block, BlockError, State, fail};
use crate::Dialect;
use crate::arc;
use crate::codes::*;
use crate::lex::{Form, K_AP, K_AT, K_CARET, K_RP};

impl State {
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
            Dialect::LinuxCnc => self.polar_end_linuxcnc(blk, motion, s),
            Dialect::Sinumerik => self.polar_end_sinumerik(blk, s),
            Dialect::Heidenhain | Dialect::Fagor => self.polar_end_tnc_fagor(blk, motion, s),
            Dialect::Rockwell => Ok(self.current_polar()),
        }
    }

    /// LinuxCNC `@` (radius) and `^` (angle) about program zero, in G0 and G1.
    fn polar_end_linuxcnc(
        &self,
        blk: &Block,
        motion: Motion,
        s: f64,
    ) -> Result<(f64, f64), BlockError> {
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

    /// Sinumerik RP and AP about the pole, kept as the modal polar values.
    fn polar_end_sinumerik(&mut self, blk: &Block, s: f64) -> Result<(f64, f64), BlockError> {
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

    /// Heidenhain R and H about the pole (CC), Fagor R and Q about the polar origin.
    fn polar_end_tnc_fagor(
        &self,
        blk: &Block,
        motion: Motion,
        s: f64,
    ) -> Result<(f64, f64), BlockError> {
        let d = self.dialect;
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
                let limit = if matches!(motion, Motion::PolarArc(_)) && d == Dialect::Heidenhain {
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
}
