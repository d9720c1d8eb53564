//! Offsets, reference positions and tool data kept in LinuxCNC's numbered parameters:
//! G54–G59.3 with the XY rotation (G10 L2/L20), G52/G92/G92.1/G92.2/G92.3, G28/G28.1,
//! G30/G30.1, the tool table (G10 L1/L10/L11), T/M6/M61 and G43/G43.1/G43.2/G49.
//!
//! The parameters are the truth (as in LinuxCNC): the work offsets live in #5221…#5390,
//! the G52/G92 offset in #5211–#5219 with its flag #5210, the active system in #5220, the
//! stored positions in #5161…/#5181…, the applied tool offsets in #5401–#5409. The state
//! keeps one cached transform from them, rebuilt by [`State::update_origin`]:
//!
//! machine = G5x + R(program + G92) + tool, with R the active system's XY rotation about
//! its origin (LinuxCNC's canon: G92 and G52 apply before the rotation, the G5x offset and
//! the tool offset after it).
//!
//! `State.pos` is the current point in the *frame*: machine coordinates before the
//! rotation, `frame = G5x + tool + program + G92`. Without a rotation the frame is the
//! machine. Moves are resolved in the frame and turned into machine coordinates as a rigid
//! rotation of the whole path about the centre `G5x + tool` (XY), so lines and arcs (in any
//! plane) stay exact.

use kerf_geom::PerAxis;
use kerf_geom::{Path, Vec3};

use super::params::{
    COORD_SYSTEM, G28_HOME, G30_HOME, G92_ENABLED, G92_OFFSET, TOOL_NUMBER, TOOL_OFFSET, coord_base,
};
use super::{Block, BlockError, Out, State, fail};
use crate::codes::*;
use crate::{Dialect, Tool};

/// The axis words in parameter order: X Y Z A B C.
const AXES: [u8; 6] = [KX, KY, KZ, KA, KB, KC];

/// What a G43-family code does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum ToolLength {
    /// G43 (H or the loaded tool), also Rockwell G43 H.
    Apply,
    /// G43.1: the offsets from the axis words.
    Dynamic,
    /// G43.2 H: add the offsets of tool H.
    Add,
    /// G49.
    Cancel,
}

impl State {
    /// Fills the parameter table at program start: work offsets, stored positions and
    /// the active system from the settings, then the restored parameters.
    pub(super) fn init_params(&mut self) {
        for (n, offs) in self.settings.work_offsets_mm.iter().enumerate() {
            for (i, v) in offs.iter().enumerate() {
                self.params.set(coord_base(n + 1) + i, *v);
            }
        }
        for i in 0..6 {
            self.params
                .set(G28_HOME + i, self.settings.g28_home_mm_deg[i]);
            self.params
                .set(G30_HOME + i, self.settings.g30_home_mm_deg[i]);
        }
        let system = self.coord_system.map_or(0.0, |i| i as f64 + 1.0);
        self.params.set(COORD_SYSTEM, system);
        for &(n, v) in &self.settings.parameters {
            self.params.set(n as usize, v);
        }
        if self.dialect == Dialect::LinuxCnc {
            // LinuxCNC starts in the coordinate system its parameter file names.
            let n = self.params.at(COORD_SYSTEM);
            if n.fract() == 0.0 && (1.0..=9.0).contains(&n) {
                self.coord_system = Some(n as usize - 1);
            } else {
                self.params.set(COORD_SYSTEM, 1.0);
            }
        }
    }

    /// The offsets X Y Z A B C and the rotation (degrees) of coordinate system `index`
    /// (0 = G54).
    fn work_offset(&self, index: usize) -> (PerAxis<f64>, f64) {
        let base = coord_base(index + 1);
        let mut o = [0.0; 6];
        for (i, v) in o.iter_mut().enumerate() {
            *v = self.params.at(base + i);
        }
        (o, self.params.at(base + 9))
    }

    /// The G52/G92 offset in effect (zero while #5210 is 0).
    fn g92_offset(&self) -> PerAxis<f64> {
        let mut o = [0.0; 6];
        if self.params.at(G92_ENABLED) != 0.0 {
            for (i, v) in o.iter_mut().enumerate() {
                *v = self.params.at(G92_OFFSET + i);
            }
        }
        o
    }

    fn set_g92_offset(&mut self, o: PerAxis<f64>) {
        for (i, v) in o.iter().enumerate() {
            self.params.set(G92_OFFSET + i, *v);
        }
        self.params.set(G92_ENABLED, 1.0);
    }

    /// Recomputes program zero and the rotation after a work offset, G52/G92, rotation or
    /// tool offset change. The current point stays where it is on the machine. Polar values
    /// are relative to the polar reference: when it moves in its plane, the programmed
    /// polar values of the current point no longer describe it and are forgotten (the next
    /// polar word measures the point about the new reference).
    pub(super) fn update_origin(&mut self) {
        let before = self.polar_reference();
        let machine = self.frame_to_machine(self.pos);
        let (work, rotation) = match self.coord_system {
            Some(i) => self.work_offset(i),
            None => ([0.0; 6], 0.0),
        };
        let g92 = self.g92_offset();
        let tool = self.tool_offset;
        for i in 0..3 {
            self.origin[i] = work[i] + g92[i] + tool[i];
            self.origin_abc[i] = work[i + 3] + g92[i + 3] + tool[i + 3];
        }
        self.rotation_deg = if self.dialect == Dialect::LinuxCnc {
            rotation
        } else {
            0.0
        };
        self.rotation_center = [work[0] + tool[0], work[1] + tool[1]];
        self.pos = self.machine_to_frame(machine);
        let after = self.polar_reference();
        let (u, v) = self.polar_axes();
        if before[u] != after[u] || before[v] != after[v] {
            self.polar_last = None;
        }
    }

    fn rotate_xy(&self, p: Vec3, angle_deg: f64) -> Vec3 {
        let (s, c) = angle_deg.to_radians().sin_cos();
        let [cx, cy] = self.rotation_center;
        let (x, y) = (p[0] - cx, p[1] - cy);
        Vec3::new(cx + c * x - s * y, cy + s * x + c * y, p[2])
    }

    /// Machine coordinates of a frame point.
    pub(super) fn frame_to_machine(&self, f: Vec3) -> Vec3 {
        if self.rotation_deg == 0.0 {
            f
        } else {
            self.rotate_xy(f, self.rotation_deg)
        }
    }

    /// Frame coordinates of a machine point.
    pub(super) fn machine_to_frame(&self, m: Vec3) -> Vec3 {
        if self.rotation_deg == 0.0 {
            m
        } else {
            self.rotate_xy(m, -self.rotation_deg)
        }
    }

    /// A path resolved in the frame, in machine coordinates: the rigid XY rotation of the
    /// active coordinate system (G10 L2 R), applied to every point, the centre and the
    /// axis of an arc.
    pub(super) fn path_to_machine(&self, path: Path) -> Path {
        if self.rotation_deg == 0.0 {
            return path;
        }
        match path {
            Path::Line(mut l) => {
                l.start = self.frame_to_machine(l.start);
                l.end = self.frame_to_machine(l.end);
                Path::Line(l)
            }
            Path::Arc(mut a) => {
                a.start = self.frame_to_machine(a.start);
                a.end = self.frame_to_machine(a.end);
                a.center = self.frame_to_machine(a.center);
                let (s, c) = self.rotation_deg.to_radians().sin_cos();
                let (x, y) = (a.axis[0], a.axis[1]);
                a.axis = Vec3::new(c * x - s * y, s * x + c * y, a.axis[2]);
                Path::Arc(a)
            }
        }
    }

    /// The current point in program coordinates of the active system, mm and degrees.
    pub(super) fn program_point(&self) -> PerAxis<f64> {
        let mut p = [0.0; 6];
        for i in 0..3 {
            p[i] = self.pos[i] - self.origin[i];
            p[i + 3] = self.abc[i] - self.origin_abc[i];
        }
        p
    }

    /// The value of axis word `i` (X Y Z A B C) in mm or degrees.
    fn axis_value(&self, blk: &Block, i: usize) -> Option<f64> {
        let v = blk.get(AXES[i])?;
        Some(if i < 3 { v * self.scale() } else { v })
    }

    /// G92 (the current point gets the given coordinates), G92.1 (clear, parameters
    /// zeroed), G92.2 (suspend, parameters kept), G92.3 (apply the parameters), and G52
    /// (the offset given directly): LinuxCNC's semantics on #5210–#5219.
    pub(super) fn exec_g92(&mut self, blk: &Block, g: G, col: u32) -> Result<(), BlockError> {
        match g {
            G::G92Set | G::LocalOffset => {
                if !blk.any(&AXES) {
                    let message = if self.dialect == Dialect::LinuxCnc {
                        "All axes missing with g52 or g92"
                    } else {
                        "all axes missing with G92"
                    };
                    return fail(col, message);
                }
                let mut g92 = self.g92_offset();
                let prog = self.program_point();
                for (i, o) in g92.iter_mut().enumerate() {
                    if let Some(v) = self.axis_value(blk, i) {
                        *o = if g == G::LocalOffset {
                            v
                        } else {
                            // The offset that makes the current point read `v`.
                            prog[i] + *o - v
                        };
                    }
                }
                self.set_g92_offset(g92);
            }
            G::G92Reset => {
                for i in 0..9 {
                    self.params.set(G92_OFFSET + i, 0.0);
                }
                self.params.set(G92_ENABLED, 0.0);
            }
            G::G92Suspend => {
                self.params.set(G92_ENABLED, 0.0);
            }
            _ => {
                self.params.set(G92_ENABLED, 1.0);
            }
        }
        self.update_origin();
        Ok(())
    }

    /// G10 L1/L10/L11 (tool table) and G10 L2/L20 (coordinate systems).
    pub(super) fn exec_g10(&mut self, blk: &Block, col: u32) -> Result<(), BlockError> {
        if blk.get(KL) == Some(0.0) {
            if let Some(n) = self.tool_loaded.filter(|&n| n != 0) {
                return fail(col, format!("G10 L0 not allowed with loaded tool <{n}>"));
            }
            // G10 L0 reloads the tool table (rs274: RELOAD_TOOLDATA, the block's other
            // words unread). Kerf's table is the configured one with the program's G10 L1,
            // L10 and L11 changes, which LinuxCNC writes to its file and so reloads: nothing
            // changes.
            return Ok(());
        }
        let l = blk
            .get(KL)
            .filter(|l| [1.0, 2.0, 10.0, 11.0, 20.0].contains(l));
        let Some(l) = l else {
            return fail(
                blk.get(KL).map_or(col, |_| blk.col(KL)),
                "Line with G10 does not have L0, L1, L10, L11, L2, or L20",
            );
        };
        if l == 2.0 || l == 20.0 {
            self.set_coordinate_system(blk, l == 20.0)
        } else {
            self.set_tool_entry(blk, l as u8)
        }
    }

    fn set_coordinate_system(&mut self, blk: &Block, l20: bool) -> Result<(), BlockError> {
        let lname = if l20 { "L20" } else { "L2" };
        let p = blk.get(KP).map(f64::round);
        let p = match p {
            Some(p) if (0.0..=9.0).contains(&p) => p as usize,
            _ => {
                let c = if blk.has(KP) {
                    blk.col(KP)
                } else {
                    blk.first_col
                };
                return fail(c, format!("P value out of range (0-9) with G10 {lname}"));
            }
        };
        if let Some(k) = blk.first_of(&[KI, KJ]) {
            return fail(
                blk.col(k),
                format!("I J words not allowed with G10 {lname}"),
            );
        }
        if l20 && blk.has(KR) {
            return fail(blk.col(KR), "R not allowed in G10 L20");
        }
        let index = if p == 0 {
            self.coord_system.unwrap_or(0)
        } else {
            p - 1
        };
        let base = coord_base(index + 1);
        let (mut offs, mut rot) = self.work_offset(index);
        if l20 {
            // The offset that makes the current point read the given coordinates in that
            // system (with the G92 and tool offsets in effect, the system's own rotation),
            // the other coordinates of the point staying what they read there.
            let machine = self.frame_to_machine(self.pos);
            let g92 = self.g92_offset();
            let tool = self.tool_offset;
            let (s, c) = rot.to_radians().sin_cos();
            let (dx, dy) = (
                machine[0] - offs[0] - tool[0],
                machine[1] - offs[1] - tool[1],
            );
            // Program point in the target system (rotation undone, G92 removed).
            let mut prog = [
                c * dx + s * dy - g92[0],
                -s * dx + c * dy - g92[1],
                machine[2] - offs[2] - tool[2] - g92[2],
                self.abc[0] - offs[3] - tool[3] - g92[3],
                self.abc[1] - offs[4] - tool[4] - g92[4],
                self.abc[2] - offs[5] - tool[5] - g92[5],
            ];
            let mut xy_given = false;
            for (i, pv) in prog.iter_mut().enumerate() {
                if let Some(v) = self.axis_value(blk, i) {
                    *pv = v;
                    xy_given |= i < 2;
                    if i >= 2 {
                        offs[i] = if i == 2 { machine[2] } else { self.abc[i - 3] }
                            - tool[i]
                            - g92[i]
                            - v;
                    }
                }
            }
            if xy_given {
                let (px, py) = (prog[0] + g92[0], prog[1] + g92[1]);
                let (rx, ry) = (c * px - s * py, s * px + c * py);
                if blk.has(KX) {
                    offs[0] = machine[0] - tool[0] - rx;
                }
                if blk.has(KY) {
                    offs[1] = machine[1] - tool[1] - ry;
                }
            }
        } else {
            for (i, o) in offs.iter_mut().enumerate() {
                if let Some(v) = self.axis_value(blk, i) {
                    *o = v;
                }
            }
            if let Some(r) = blk.get(KR) {
                rot = r;
            }
        }
        for (i, o) in offs.iter().enumerate() {
            self.params.set(base + i, *o);
        }
        self.params.set(base + 9, rot);
        if !offs.iter().chain([&rot]).all(|v| v.is_finite()) {
            return fail(blk.first_col, "coordinate out of range");
        }
        self.update_origin();
        Ok(())
    }

    /// G10 L1 (values), L10 (from the current point with the offsets in effect), L11
    /// (from the current point as if in G59.3 without G52/G92).
    fn set_tool_entry(&mut self, blk: &Block, l: u8) -> Result<(), BlockError> {
        let number = blk
            .get(KP)
            .map(f64::round)
            .filter(|&p| p >= 1.0 && p <= f64::from(u32::MAX));
        let Some(number) = number else {
            let c = if blk.has(KP) {
                blk.col(KP)
            } else {
                blk.first_col
            };
            return fail(c, format!("P value out of range with G10 L{l}"));
        };
        let number = number as u32;
        let Some(index) = self.settings.tools.iter().position(|t| t.number == number) else {
            return fail(
                blk.col(KP),
                format!("Requested tool {number} not found in the tool table"),
            );
        };
        let mut tool = self.settings.tools[index];
        let mut offs = tool.offsets_mm_deg();
        let machine = self.frame_to_machine(self.pos);
        let current = [
            machine[0],
            machine[1],
            machine[2],
            self.abc[0],
            self.abc[1],
            self.abc[2],
        ];
        let (work, g92) = match l {
            10 => (
                self.coord_system
                    .map_or([0.0; 6], |i| self.work_offset(i).0),
                self.g92_offset(),
            ),
            11 => (self.work_offset(8).0, [0.0; 6]),
            _ => ([0.0; 6], [0.0; 6]),
        };
        for (i, o) in offs.iter_mut().enumerate() {
            if let Some(v) = self.axis_value(blk, i) {
                *o = if l == 1 {
                    v
                } else {
                    // The offset that makes the current point read `v`.
                    current[i] - work[i] - g92[i] - v
                };
            }
        }
        tool.offset_xy_mm = [offs[0], offs[1]];
        tool.length_mm = offs[2];
        tool.offset_abc_deg = [offs[3], offs[4], offs[5]];
        if let Some(r) = blk.get(KR) {
            tool.radius_mm = r * self.scale();
        }
        if let Some(i) = blk.get(KI) {
            tool.front_angle_deg = i;
        }
        if let Some(j) = blk.get(KJ) {
            tool.back_angle_deg = j;
        }
        if let Some(q) = blk.get(KQ) {
            if q.fract() != 0.0 || !(0.0..=9.0).contains(&q) {
                return fail(
                    blk.col(KQ),
                    "Q word with G10 L1 must be an orientation 0 to 9",
                );
            }
            tool.orientation = q as u8;
        }
        if !offs.iter().chain([&tool.radius_mm]).all(|v| v.is_finite()) {
            return fail(blk.first_col, "coordinate out of range");
        }
        self.settings.tools[index] = tool;
        Ok(())
    }

    /// G28.1 / G30.1: the current machine position into #5161… / #5181….
    pub(super) fn store_home(&mut self, g30: bool) {
        let base = if g30 { G30_HOME } else { G28_HOME };
        let m = self.frame_to_machine(self.pos);
        for i in 0..3 {
            self.params.set(base + i, m[i]);
            self.params.set(base + 3 + i, self.abc[i]);
        }
    }

    /// G28 / G30: with axis words, a rapid to the point they give (program coordinates,
    /// G90/G91 as usual), then a rapid of those axes only to the stored position; without
    /// axis words, a rapid of every axis to the stored position. The stored position is
    /// in machine coordinates; under a rotated coordinate system the named axes take the
    /// stored point's program coordinates (as LinuxCNC computes it).
    pub(super) fn exec_home(
        &mut self,
        blk: &Block,
        g30: bool,
        col: u32,
        out: &mut Out<'_>,
    ) -> Result<(), BlockError> {
        if self.comp != Comp::Off {
            return fail(col, "Cannot use g28 or g30 with cutter radius comp");
        }
        let base = if g30 { G30_HOME } else { G28_HOME };
        let mut home_m = Vec3::zeros();
        let mut home_abc = [0.0; 3];
        for i in 0..3 {
            home_m[i] = self.params.at(base + i);
            home_abc[i] = self.params.at(base + 3 + i);
        }
        let home_f = self.machine_to_frame(home_m);
        let all = !blk.any(&AXES);
        // The intermediate point.
        let mut mid = self.pos;
        for (i, &k) in XYZ.iter().enumerate() {
            mid[i] = self.linear_target(blk, k, i);
        }
        let mid_abc = self.abc_target(blk);
        if blk.any(&ABC) {
            self.abc_used = true;
        }
        self.rapid_to(mid, mid_abc, blk, out)?;
        let mut end = self.pos;
        let mut end_abc = self.abc;
        for i in 0..3 {
            if all || blk.has(XYZ[i]) {
                end[i] = home_f[i];
            }
            if all || blk.has(ABC[i]) {
                end_abc[i] = home_abc[i];
            }
        }
        if end_abc != self.abc {
            self.abc_used = true;
        }
        self.rapid_to(end, end_abc, blk, out)
    }

    /// T (LinuxCNC: the tool must be in the table; T0 is "no tool").
    pub(super) fn check_tool_exists(&self, number: u32, col: u32) -> Result<(), BlockError> {
        if self.dialect != Dialect::LinuxCnc || number == 0 || self.tool(Some(number)).is_some() {
            return Ok(());
        }
        fail(
            col,
            format!("Requested tool {number} not found in the tool table"),
        )
    }

    /// M6 / M61: the tool in the spindle; #5400 and its diameter and lathe data
    /// #5410–#5413. `data` says whether its table entry becomes the one G43 without H
    /// applies (M6; M61 changes the number only, as rs274 does).
    pub(super) fn load_tool(&mut self, number: Option<u32>, data: bool) {
        let n = number.unwrap_or(0);
        let entry = self.tool(Some(n)).cloned().unwrap_or_default();
        self.params.set(TOOL_NUMBER, f64::from(n));
        self.params.set(TOOL_OFFSET + 9, 2.0 * entry.radius_mm);
        self.params.set(TOOL_OFFSET + 10, entry.front_angle_deg);
        self.params.set(TOOL_OFFSET + 11, entry.back_angle_deg);
        self.params
            .set(TOOL_OFFSET + 12, f64::from(entry.orientation));
        if data {
            self.tool_loaded = number;
        }
    }

    /// M61 Q: the current tool number, without a tool change.
    pub(super) fn exec_m61(&mut self, blk: &Block, col: u32) -> Result<(), BlockError> {
        let q = blk.get(KQ).filter(|&q| q >= 0.0);
        let Some(q) = q else {
            let c = if blk.has(KQ) { blk.col(KQ) } else { col };
            return fail(
                c,
                "Need non-negative Q-word to specify tool number with M61",
            );
        };
        let Some(n) = super::tool_number(q.round()) else {
            return fail(
                blk.col(KQ),
                "Need non-negative Q-word to specify tool number with M61",
            );
        };
        self.check_tool_exists(n, blk.col(KQ))?;
        self.load_tool(Some(n), false);
        Ok(())
    }

    /// G43 H / G43 / G43.1 axes / G43.2 H / G49 (LinuxCNC, every offset of the entry), and
    /// Rockwell G43 H / G49 (length only). Returns whether the block's axis words were
    /// used by G43.1.
    pub(super) fn exec_tool_length(
        &mut self,
        blk: &Block,
        kind: ToolLength,
        col: u32,
        motion_in_block: bool,
    ) -> Result<bool, BlockError> {
        let lcnc = self.dialect == Dialect::LinuxCnc;
        let entry = |s: &State, n: u32, c: u32| -> Result<PerAxis<f64>, BlockError> {
            if lcnc && n == 0 {
                // H0: the tool in the spindle (none: zero), on a non-random changer.
                return Ok(s.tool(s.tool_loaded).map_or([0.0; 6], Tool::offsets_mm_deg));
            }
            match s.tool(Some(n)) {
                Some(t) if lcnc => Ok(t.offsets_mm_deg()),
                Some(t) => Ok([0.0, 0.0, t.length_mm, 0.0, 0.0, 0.0]),
                None if lcnc => fail(c, format!("Requested tool {n} not found in the tool table")),
                None => Ok([0.0; 6]),
            }
        };
        let h = match blk.get(KH) {
            Some(h) if lcnc && h.fract() != 0.0 => {
                return fail(blk.col(KH), "Non integer value for integer");
            }
            Some(h) if lcnc && h < 0.0 => {
                return fail(
                    blk.col(KH),
                    format!("Requested tool {h} not found in the tool table"),
                );
            }
            Some(h) => Some(super::tool_number(h).ok_or_else(|| BlockError {
                col: blk.col(KH),
                message: "H word must be a non-negative integer".into(),
            })?),
            None => None,
        };
        let mut used_axes = false;
        let new = match kind {
            ToolLength::Apply => match h {
                Some(n) => entry(self, n, blk.col(KH))?,
                None => match self.tool_loaded {
                    Some(n) => entry(self, n, col)?,
                    None => [0.0; 6],
                },
            },
            ToolLength::Dynamic => {
                if blk.has(KH) {
                    return fail(blk.col(KH), "H word with no G43 or G76 to use it");
                }
                let mut o = self.tool_offset;
                for (i, v) in o.iter_mut().enumerate() {
                    if let Some(x) = self.axis_value(blk, i) {
                        *v = x;
                    }
                }
                used_axes = !motion_in_block;
                o
            }
            ToolLength::Add => {
                let Some(n) = h else {
                    if blk.any(&AXES) {
                        // LinuxCNC 2.9's interpreter takes no axis words with G43.2.
                        return fail(col, "Requested tool -1 not found in the tool table");
                    }
                    return fail(col, "G43.2: No axes specified and H word missing");
                };
                if let Some(k) = blk.first_of(&AXES) {
                    return fail(blk.col(k), "G43.2: Can not have both H and axis words");
                }
                let add = entry(self, n, blk.col(KH))?;
                let mut o = self.tool_offset;
                for (v, a) in o.iter_mut().zip(add) {
                    *v += a;
                }
                o
            }
            ToolLength::Cancel => [0.0; 6],
        };
        if !new.iter().all(|v| v.is_finite()) {
            return fail(col, "coordinate out of range");
        }
        self.set_tool_offsets(new);
        Ok(used_axes)
    }

    /// Puts `offsets` (X, Y, Z mm, A, B, C degrees) in effect as the tool offsets, in the
    /// state and in #5401–#5406.
    pub(super) fn set_tool_offsets(&mut self, offsets: PerAxis<f64>) {
        self.tool_offset = offsets;
        for (i, v) in offsets.iter().enumerate() {
            self.params.set(TOOL_OFFSET + i, *v);
        }
        self.update_origin();
    }
}

impl State {
    /// A rapid from the current point to `end` (frame) and `abc` (G28/G30), not emitted
    /// when it moves nothing.
    fn rapid_to(
        &mut self,
        end: Vec3,
        abc: [f64; 3],
        blk: &Block,
        out: &mut Out<'_>,
    ) -> Result<(), BlockError> {
        let start = self.pos;
        if (end - start).norm() < crate::arc::SAME_POINT_MM && abc == self.abc {
            return Ok(());
        }
        if !end.iter().chain(abc.iter()).all(|v| v.is_finite()) {
            return fail(blk.first_col, "coordinate out of range");
        }
        let path = self.path_to_machine(Path::Line(kerf_geom::Line { start, end }));
        out.items.push(crate::Item::Move(kerf_geom::Move {
            line: out.line,
            rapid: true,
            path,
            feed_mm_min: None,
            abc_deg: self.abc_used.then_some((self.abc, abc)),
            corner: self.corner,
        }));
        self.pos = end;
        self.abc = abc;
        self.polar_last = None;
        Ok(())
    }
}
