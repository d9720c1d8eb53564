//! The machine settings the interpreter needs and the entries of the tool table.

use kerf_geom::PerAxis;
/// One entry of the tool table.
///
/// LinuxCNC applies every offset of the entry with G43 (X, Y, Z, A, B, C); the other
/// controls use the length only.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Tool {
    /// Tool number (T word).
    pub number: u32,
    /// Tool length offset, mm: the Z offset of the entry.
    pub length_mm: f64,
    /// Tool radius, mm (LinuxCNC cutter compensation; the other dialects refuse G41/G42
    /// when it is non-zero).
    pub radius_mm: f64,
    /// X and Y offsets of the entry, mm (LinuxCNC applies them with G43; lathes mostly).
    pub offset_xy_mm: [f64; 2],
    /// A, B and C offsets of the entry, degrees (LinuxCNC applies them with G43).
    pub offset_abc_deg: [f64; 3],
    /// The pocket the tool sits in (LinuxCNC tool table `P`; informational).
    pub pocket: u32,
    /// Lathe front angle, degrees (LinuxCNC `I`, parameter #5411).
    pub front_angle_deg: f64,
    /// Lathe back angle, degrees (LinuxCNC `J`, parameter #5412).
    pub back_angle_deg: f64,
    /// Lathe tool orientation 0–9 (LinuxCNC `Q`, parameter #5413).
    pub orientation: u8,
}

impl Tool {
    /// The offsets of the entry as LinuxCNC applies them: X, Y, Z mm, A, B, C degrees.
    pub fn offsets_mm_deg(&self) -> PerAxis<f64> {
        let [x, y] = self.offset_xy_mm;
        let [a, b, c] = self.offset_abc_deg;
        [x, y, self.length_mm, a, b, c]
    }
}

/// Machine settings the interpreter needs.
#[derive(Clone, Debug)]
pub struct Settings {
    /// LinuxCNC G54, G55, G56, G57, G58, G59, G59.1, G59.2, G59.3 offsets in mm (zero by default).
    pub work_offsets_mm: [[f64; 3]; 9],
    /// The tool table.
    pub tools: Vec<Tool>,
    /// Absolute arc end-point tolerance for Sinumerik/Heidenhain/Fagor, mm (default 0.02828).
    pub arc_tolerance_mm: f64,
    /// Relative arc end-point tolerance (fraction of the start radius) for
    /// Sinumerik/Heidenhain/Fagor (default 0.001).
    pub arc_tolerance_rel: f64,
    /// Where the machine is when the program starts: X, Y, Z machine mm, A, B, C degrees
    /// (the origin by default; `kerf run` gives the daemon's position).
    pub start_mm_deg: PerAxis<f64>,
    /// LinuxCNC: directories searched, in order, for the file `NAME.ngc` of a subroutine
    /// `o<NAME> call` that the program does not define (`[gcode] subroutine_path`).
    pub subroutine_path: Vec<std::path::PathBuf>,
    /// LinuxCNC: the program's own file, when it is read from one. A `call` of a sub that
    /// is defined later in the program (after M2, say) finds it there, as LinuxCNC does by
    /// seeking forward; the program's directory is searched for `NAME.ngc` files before
    /// [`Settings::subroutine_path`]. `None` (standard input): such a call is an error.
    pub program_file: Option<std::path::PathBuf>,
    /// LinuxCNC: the most iterations of one `while`/`do`/`repeat` loop, and the deepest
    /// subroutine nesting times this, before the program is refused as endless
    /// (`[gcode] max_loop_iterations`).
    pub max_loop_iterations: u64,
    /// LinuxCNC: the G28 and G30 stored positions at program start (parameters
    /// #5161–#5166 and #5181–#5186), machine mm and degrees.
    pub g28_home_mm_deg: PerAxis<f64>,
    /// See [`Settings::g28_home_mm_deg`].
    pub g30_home_mm_deg: PerAxis<f64>,
    /// LinuxCNC: numbered parameters restored at program start, after the values above
    /// (the persistent parameters #5161–#5390 of a parameter file, as LinuxCNC restores
    /// its `.var` file). Values in mm and degrees, Kerf's machine units. A number outside
    /// #1–#5602 is ignored.
    pub parameters: Vec<(u32, f64)>,
    /// The block delete switch (`[gcode] block_delete`): on, a block that starts with `/`
    /// is skipped; off (the default), the `/` is ignored and the block runs, as LinuxCNC
    /// runs it with its switch off, which is how rs274 and LinuxCNC start.
    pub block_delete: bool,
    /// LinuxCNC: the inputs an `M66` reads when the program reads `#5399` and no
    /// [`crate::InputWait`] was given ([`crate::Interpreter::set_input_wait`]): the offline
    /// answer of `kerf plan` and `kerf sim`. Default: every input off, every analog input 0.
    pub simulated_inputs: crate::SimulatedInputs,
    /// The tool in the machine's spindle when the program starts (`kerf run` asks the
    /// daemon): the current tool until the program's first change (`#5400`, `G43`
    /// without `H`). `None`: none (as rs274 starts).
    pub tool_in_spindle: Option<u32>,
    /// MDI (`kerf mdi`): the input is lines typed one at a time, not a program file.
    /// LinuxCNC's rule that a file ends with M2, M30 or `%` does not apply; the end of the
    /// reader's input is a pause, not the program's end (the [`crate::Interpreter`]
    /// returns `None`, and reads on at the next call once the reader has more); an error
    /// ends its line only (the next call reads the next line); cutter radius compensation
    /// (G41/G42, whose moves wait for the next one) is refused. Off by default.
    pub mdi: bool,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            work_offsets_mm: [[0.0; 3]; 9],
            tools: Vec::new(),
            arc_tolerance_mm: 0.02828,
            arc_tolerance_rel: 0.001,
            start_mm_deg: [0.0; 6],
            subroutine_path: Vec::new(),
            program_file: None,
            max_loop_iterations: 1_000_000,
            g28_home_mm_deg: [0.0; 6],
            g30_home_mm_deg: [0.0; 6],
            parameters: Vec::new(),
            block_delete: false,
            simulated_inputs: crate::SimulatedInputs::default(),
            tool_in_spindle: None,
            mdi: false,
        }
    }
}
