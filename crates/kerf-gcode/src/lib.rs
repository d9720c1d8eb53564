//! G-code front end for Kerf: lexing, dialects, modal state and exact move resolution.
//!
//! [`Interpreter`] reads a program written for one of five controls ([`Dialect`]) and
//! yields, in program order, resolved [`Move`]s (absolute machine millimetres, exact
//! lines, arcs and helices) and non-motion [`Event`]s. The first bad block ends the
//! stream with a [`Diagnostic`] naming line, column and the problem in the words of the
//! control's manual.
//!
//! ```
//! use kerf_gcode::{Dialect, Interpreter, Item, Path, Settings};
//!
//! let program = "G21 G90 F600\nG1 X10\nG3 X0 Y10 I-10 J0\nM30\n";
//! let items: Vec<Item> = Interpreter::new(program.as_bytes(), Dialect::LinuxCnc, Settings::default())
//!     .collect::<Result<_, _>>()
//!     .expect("a valid program");
//! let Item::Move(quarter) = items[1] else { panic!("a move") };
//! let Path::Arc(arc) = quarter.path else { panic!("an arc") };
//! assert_eq!(arc.center, kerf_gcode::Vec3::zeros());
//! assert!((arc.sweep_rad - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
//! assert_eq!(quarter.feed_mm_min, Some(600.0));
//! ```
//!
//! # Design
//!
//! - **Streaming, constant memory.** One source line is read at a time into a reused
//!   buffer (lines longer than [`MAX_LINE_BYTES`] are an error); each line is lexed into a
//!   reused word buffer, resolved against the modal state, and its items are queued in a
//!   small reused buffer. Nothing grows with the program. On the hot path nothing is
//!   allocated: error messages are only formatted when an error happens.
//! - **Bytes, not chars.** The lexer works on bytes with case-insensitive letters and
//!   converts numbers itself (exact for up to 15 significant digits; longer numbers are
//!   converted through a general path). Comments may hold any UTF-8; invalid UTF-8, NUL
//!   bytes and unexpected characters are errors, never panics.
//! - **One resolution engine, dialect tables.** Each dialect maps its G codes onto shared
//!   actions (plane, units, distance mode, motion, poles…); the geometry is computed once
//!   in plane coordinates (u, v) with u × v = the plane normal, so G17, G18 and G19 share
//!   one code path and `sweep_rad` is always signed about the normal by the right-hand rule.
//! - **Blocks are atomic.** A block's items are only released when the whole block has
//!   been resolved; after an error, nothing more is produced.
//!
//! Code map: `lex` (bytes to words, per-dialect syntax), `codes` (word keys, G/M code
//! tables and modal groups of each dialect), `interp` (modal state, block execution,
//! events), `interp::geometry` (end points, poles, polar coordinates, arcs of one motion
//! block), `interp::modal` (LinuxCNC feed modes, G64 P Q, M70–M73 and their subroutine
//! hooks, user M codes, spindle and coolant state), `interp::cycles` (LinuxCNC canned
//! cycles), `arc` (exact arc construction and the end-point tolerance rules).
//!
//! # Common rules (all dialects)
//!
//! - Output is millimetres in absolute machine coordinates; the first move starts at the
//!   machine origin `[0, 0, 0]` and every move starts where the previous one ended.
//!   Rotary axes A/B/C are degrees, never unit-converted; `abc_deg` is `None` until an
//!   A/B/C word appears, then `Some((start, end))` on every later move, lines and arcs.
//! - Missing axis words keep the current position. A zero-length line (end = start and no
//!   rotary motion) is not emitted: the control would not move.
//! - Feed F is modal and kept physically (converted to mm/min when read). A feed move with
//!   no F ever programmed, or F0, is an error. Rapids carry `feed_mm_min: None`.
//! - Events run in the control's order inside a block: S, T, M6, M3/M4/M5, M7/M8/M9
//!   before the motion, M0/M1/M2/M30 after it (Heidenhain: M5 and M9 also after the
//!   motion, as on the TNC; LinuxCNC: its own order, below). After M2/M30 the rest of the
//!   program is not read. Other M codes are an "unknown M code" error. An `S` event
//!   carries the rpm, a `T` event the tool number. M0, M1 (optional stop) and LinuxCNC M60
//!   (pallet change) are program pauses; Kerf does not skip M1 (its optional-stop switch
//!   is on).
//! - **A block is executed completely or refused.** A word or code that the block would
//!   need but Kerf cannot act on is an error naming it, never dropped: words no code of
//!   the block uses, tool offset words Kerf does not apply (D, H), axis words of a block
//!   whose axes belong to a non-motion code together with a motion code, and the extra
//!   words of Heidenhain G99/G30 and Fagor G30 blocks (each dialect below). Sinumerik,
//!   Heidenhain and Fagor apply the length of a called tool; Kerf does not, so a T word
//!   calling a tool with a non-zero length in the tool table is the error "tool length
//!   compensation is not supported (tool N has a non-zero length)".
//! - A dwell is the event `G4` with its time in seconds, after the block's spindle and
//!   coolant events and before its motion (LinuxCNC's order of execution); the motion
//!   before it comes to an exact stop and waits. A G4 without a time word (accepted
//!   outside LinuxCNC) is a dwell of zero: still an exact stop. The dwell word: LinuxCNC
//!   `G4 P` (seconds, required: "Dwell time P word missing with G4"), Rockwell `G04 X` or
//!   `P` (both taken as seconds: the 9/Series unit of P is not confirmed, and reading a
//!   Fanuc-style millisecond P as seconds errs on the side of waiting longer), Sinumerik
//!   `G4 F` (seconds) or `G4 S` (spindle revolutions at the last programmed S, an error
//!   without one), Heidenhain `G04 F` (seconds), Fagor `G04 K` (seconds); one of them per
//!   block. A negative value is an error at the word (LinuxCNC: "Negative P word used"),
//!   and so is one above 1,000,000 (11.6 days in
//!   seconds: a mistake, not a dwell). On Sinumerik and Heidenhain the F (and S) of a
//!   dwell block is the dwell only: the feed and spindle speed programmed before stay.
//!   LinuxCNC runs a motion of the same block after the dwell (`G4 P1 G1 X10`); the other
//!   controls want the dwell in a block of its own ("G4 must be programmed in a separate
//!   block"), so an axis, centre or polar word there is an error, never dropped.
//! - Block delete `/` at the start of a block: with the block delete switch on
//!   ([`Settings::block_delete`]) the block is skipped (it is not even checked); off, the
//!   default, the `/` is ignored and the block runs. Off is how LinuxCNC starts (rs274's
//!   `-b` turns it on; AXIS has a toggle) and how the other controls' panels leave it
//!   until the operator asks for skipping. In LinuxCNC the `/` must be the
//!   first character of the line, spaces aside: after a comment, an N word or any word it
//!   is an error, as in rs274 ("Bad character '/' used").
//! - Cutter compensation G41/G42: LinuxCNC compensates (its section below). The other
//!   dialects accept it only while the active tool's radius is zero (tool table in
//!   [`Settings`]; the tool is the last T, or the Rockwell D word); with a non-zero radius
//!   it is the error "cutter compensation not supported", never a silently wrong path. G40
//!   cancels it.
//! - Work offsets: one table, [`Settings::work_offsets_mm`], serves LinuxCNC
//!   G54–G59.3, Rockwell and Fagor G54–G59 (G54 active by default) and Sinumerik G54–G57
//!   (G500, no offset, by default). Heidenhain has none. It initialises LinuxCNC's
//!   numbered parameters #5221… (the interpreter reads the offsets from there, in every
//!   dialect), which the program can change (LinuxCNC G10 L2/L20).
//! - Arc end points: a centre-format arc whose end radius differs from its start radius
//!   within the tolerance is made exact by moving the centre onto the perpendicular
//!   bisector of the chord, to the point closest to the programmed centre (LinuxCNC would
//!   spiral instead; the difference is within the tolerance). Beyond the tolerance it is an
//!   error. LinuxCNC uses its own rule (below); the other controls reject when
//!   |r_end − r_start| > max(`arc_tolerance_mm`, r_start × `arc_tolerance_rel`) (the
//!   Sinumerik MD21000/MD21010 rule; defaults 0.02828 mm and 0.001). A radius-format arc
//!   whose |R| is short of half the chord by at most the slack (LinuxCNC 0.00127 mm,
//!   others `arc_tolerance_mm`) is taken as a semicircle. LinuxCNC: when the end lies on
//!   the ray from the programmed centre through the start (its angle about the centre is
//!   the start's, within 0.0001 mm beside the ray) at another radius, LinuxCNC turns a whole
//!   circle spiralling to the end radius; Kerf turns the whole circle (and its P turns) at
//!   the start radius about the programmed centre, then feeds along the radius to the end
//!   (a line as long as the radii differ, within the arc tolerance), in the same block. With
//!   cutter compensation or in G93 that is an error.
//! - A full circle is a centre-format arc whose end equals its start (end words omitted or
//!   repeated): `|sweep_rad| = 2π`, plus 2π per extra turn. Radius format cannot make one.
//! - Helices: an axis word along the plane normal moves linearly with the angle; the
//!   centre lies in the plane of the start point.
//! - Not supported yet, each a clear error naming the construct: parameters and
//!   expressions outside LinuxCNC (Sinumerik R parameters, `=` expressions and other
//!   keywords; Fagor `P` parameters, `#` and `$` instructions), canned cycles (outside
//!   LinuxCNC, which has them: see its section), inverse-time (G93) and per-revolution
//!   (G95) feed outside LinuxCNC, U/V/W axes.
//!
//! # LinuxCNC / Tormach (`linuxcnc`, alias `tormach`)
//!
//! - `( )` and `;` comments; spaces are allowed anywhere, even inside numbers (`X 1 0.5`
//!   is X10.5). A `%` line opens the program and the next `%` line ends it. A program
//!   ends with M2/M30 or its closing `%`: at the end of the file without them it is
//!   rs274's error "File ended with no percent sign or program end" ("File ended with no
//!   percent sign" after an opening `%`) at the last line, after the moves before it (not
//!   a move cutter compensation holds back); a `%` without an opening one is "Bad
//!   character '%' used". Subroutine files are read for their subs and need no end.
//! - G20/G21 (default mm), G90/G91, G90.1/G91.1 (I J K absolute / incremental, default
//!   incremental; under G90.1 both centre words of the plane are required: "J word missing
//!   in absolute center arc"), G17/G18/G19, G80 cancels the motion mode (with a motion
//!   code in the same block, `G80 G0 X5`, the motion runs, as in rs274), G97/G98/G99
//!   accepted. G17.1/G18.1/G19.1 (UVW planes) are "not supported". There is no motion mode at start: axis words before G0/G1/G2/G3 are the
//!   error "cannot use axis values without a G code that uses them".
//! - **Order of execution** (the manual's list): feed mode G93/G94/G95, F, S, T,
//!   M62–M68, M6, M3/M4/M5, M70–M73, M7/M8/M9, M100–M199, G4, then plane, units, cutter compensation,
//!   G43/G49, G54–G59.3, G61/G64, G90/G91, G92, the motion, and M0/M1/M2/M30/M60. So F is
//!   read in the unit in force before the block's G20/G21 (`G20 G1 X1 F40` is 40 mm/min,
//!   `G21 G1 X1 F2` under G20 is 2 in/min), and M70 saves the state before the block's G
//!   codes. M7 and M8 in one block is an error, as in rs274.
//! - **Path control**: G61 and G61.1 are exact stop (LinuxCNC's G61 is exact path, which
//!   need not stop where the path is tangent; Kerf stops at every join). G64 blends:
//!   `P` the path tolerance, `Q` the naive-CAM tolerance (`P` when Q is absent, as in
//!   LinuxCNC), both in program units, carried in [`CornerMode::Blend`]; the planner uses
//!   P and does not use Q yet. G64 without P blends within the configured default
//!   tolerance (LinuxCNC: as fast as possible). A negative P or Q is an error.
//! - **Feed modes**: G93, G94 and G95 each set the feed rate to zero, as in LinuxCNC: a
//!   feed move needs a new F. G94: F in units per minute. G93 (inverse time): every feed
//!   move needs its own F ("F word missing with inverse time G1 move" / "... arc move"),
//!   the move takes 1/F minutes: `feed_mm_min` = length × F, where the length is the XYZ
//!   path length (helices included), or for a rotary-only move the A/B/C distance in
//!   degrees (then degrees/min); at least 0.1 program units per minute (LinuxCNC's
//!   floor, which also makes `F0` move). G95 (per revolution): `feed_mm_min` = F (mm, or
//!   inches at the time F was read, per revolution) × the last programmed S. Kerf has no
//!   spindle feedback: it assumes the spindle turns at the commanded speed, whether M3/M4
//!   or M5 is in force; with no S or S0 it is the error "Cannot feed with zero spindle
//!   speed in feed per rev mode".
//! - **Modal state M70–M73**: M70 saves, M72 restores ("Cannot restore context from
//!   invalid stack frame - missing M70/M73?" with nothing saved), M71 invalidates, at the
//!   current call level (the program, or one subroutine call). M73 saves, and the end of
//!   the subroutine (endsub or return) restores; in the main program it saves like M70
//!   and the program's end restores nothing. Saved: units, plane, cutter compensation,
//!   distance and arc distance modes, feed mode and feed, coordinate system, G43/G49,
//!   G61/G64 with P and Q, S, the spindle (M3/M4/M5) and coolant (M7/M8); not the motion
//!   mode. A restore sets the units first, then the rest, as rs274 does, and emits S,
//!   M3/M4/M5 for what changes; coolant as rs274 restores it (saved off: M9 when anything
//!   is on; saved on: M7/M8 for what is off; nothing is turned off otherwise); G43 is
//!   applied anew with the tool in the spindle; a restore that changes the feed mode
//!   leaves the feed at zero (rs274 does). M70–M73 belong to the spindle group (`M3 M70`
//!   is refused, as in rs274); M6 stops the spindle.
//! - **M19** orients the spindle: an [`EventCode::M19`] event with `value` = R (degrees,
//!   0–360, default 0), `p` = P (direction 0, 1, 2; default 0) and `q` = Q (the wait,
//!   seconds), checked as rs274 checks them; M19 is in the spindle group (M3/M4/M5).
//!   (rs274's canon prints no ORIENT_SPINDLE for an M19 that repeats the last angle and
//!   direction; Kerf hands every M19 on.)
//! - **Overrides** M48/M49 (feed and spindle override enable/disable) and M50/M51/M52/M53
//!   (feed override, spindle override, adaptive feed, feed stop; `value` 1, or 0 for `P0`)
//!   are events ([`EventCode::M48`]…) in their own modal group, after the coolant and
//!   before the user M codes; `kerf sim` does not stop at them.
//! - **Machine I/O** (`interp::io`), one code per block (LinuxCNC's modal group 5), after T
//!   and before M6, each an event: M62/M63 digital output P on/off with the start of the
//!   next move, M64/M65 at once (`value` = P); M67/M68 analog output E set to Q with the
//!   next move / at once (`value` = E, `q` = Q); M66 waits on digital input P
//!   ([`EventCode::M66`]) or analog input E ([`EventCode::M66Analog`]), `value` = the
//!   input, `p` = the wait mode L (0 immediate, the default; 1 rise, 2 fall, 3 high, 4
//!   low; analog inputs only 0), `q` = the timeout Q in seconds (`None` without Q, 0 for
//!   a Q at or below zero, as rs274 passes it). rs274's checks in its words: "No valid P
//!   word with M62", "Need to have either a valid P or a valid E word with M66", "Invalid
//!   to select both a digital and an analog input with M66", "Zero timeout with wait type
//!   != immediate return" (L1–L4 need Q > 0), "Can't select analog input with wait type !=
//!   immediate return", "Invalid analog index with M67", and each code's "Cannot … with
//!   cutter radius compensation on". Kerf is stricter where rs274 passes on a number no
//!   machine has: an input or output number is a whole number from 0 to
//!   [`MAX_IO_NUMBER`] (63, LinuxCNC's limit of 64 each; rs274 rounds P and E and takes a
//!   negative output number), which inputs and outputs exist is the machine
//!   configuration's business; L is at most 4; M67/M68 need their Q ("Q word missing with
//!   M67: the value to set"; rs274 sets -1).
//! - **`#5399`**, the result of the last M66 (the input's state 1/0 or an analog value,
//!   -1 after a timeout). LinuxCNC stops reading ahead at an M66 until the motion has
//!   drained and the wait is over. Kerf yields the M66 event and reads on; only a line that
//!   reads `#5399` (in an expression, an O-word condition, a DEBUG/PRINT text; not
//!   `EXISTS`) while the M66 is outstanding waits: it asks the [`InputWait`] given by
//!   [`Interpreter::set_input_wait`] once, and `#5399` keeps the answer until the next M66
//!   or an assignment to it. Its error stops the program at that line ("#5399 after the
//!   M66 of line N: …"). Without one, [`Settings::simulated_inputs`] answer (inputs that
//!   never change: see [`SimulatedInputs`]), so `kerf plan` and `kerf sim` run offline.
//!   (rs274 itself answers with `#5399`'s previous value.)
//! - **Refused**: M98/M99 (Fanuc-style subprograms of LinuxCNC 2.9): "not supported, use
//!   o-word subroutines".
//! - **G10 L0** reloads the tool table: Kerf's is the configured one with the program's
//!   G10 L1/L10/L11 changes, so nothing changes; its other words are not read (rs274
//!   neither). With a tool loaded it is rs274's error `G10 L0 not allowed with loaded
//!   tool <N>`.
//! - **User M codes** M100–M199: an [`EventCode::User`] event with `value` = P and `q` =
//!   Q, after the coolant and before the dwell; one per block. LinuxCNC runs the program
//!   file `M1nn` and refuses the code when there is none ("Unknown m code used"); Kerf
//!   runs no user programs and hands the code on as an event (`kerf sim` stops the
//!   motion at it).
//! - Offsets live in LinuxCNC's numbered parameters, in mm (Kerf's machine unit) and
//!   degrees whatever G20/G21 says: G54–G59.3 in #5221–#5390 (X Y Z A B C at +0..+5, the
//!   XY rotation R at +9, 20 apart; initialised from [`Settings::work_offsets_mm`]), the
//!   active system in #5220, the shared G52/G92 offset in #5211–#5219 with #5210 = 1
//!   while it applies, the G28/G30 positions in #5161–#5166/#5181–#5186 (from
//!   [`Settings::g28_home_mm_deg`]/[`Settings::g30_home_mm_deg`]), the tool offsets in
//!   effect in #5401–#5409, the tool in the spindle #5400 and its diameter #5410.
//!   [`Settings::parameters`] restores a parameter file at start (a restored #5220 selects
//!   the system); [`Interpreter::persistent_parameters`] gives the end values.
//!   machine = G5x + R(program + G52/G92) + tool offset, R the active system's rotation.
//! - G54–G59.3 select a system; M2/M30 select G54 again. G10 L2 P0–P9 (0 = active) sets a
//!   system's offsets and its rotation R (degrees CCW about its origin: every later line
//!   and arc, in any plane, is rotated rigidly, as LinuxCNC's canon does); G10 L20 sets the
//!   offsets that make the current point read the given coordinates (R refused). G92
//!   makes the current point read the given coordinates (axes not named keep the offset in
//!   effect); G52 sets the offset itself; G92.1 clears it and its parameters; G92.2 turns
//!   it off keeping the parameters; G92.3 turns the parameters on. G91 does not affect
//!   them. A code that uses axis words (G10, G28, G30, G52, G92) with G0–G3 in the same
//!   block is "Cannot use two g codes that both use axis values".
//! - G53 (with G0 or G1, G90, no cutter compensation): the named axes go to the given
//!   machine coordinates, the others stay where they are on the machine.
//! - G28/G30: with axis words a rapid to the point they give (program coordinates, G90 or
//!   G91), then a rapid of those axes only to the stored position (machine coordinates;
//!   under a rotation the named axes take the stored point's program coordinates, as rs274
//!   computes); without axis words a rapid of every axis to it. A rapid that moves nothing
//!   is not emitted (rs274 prints one). G28.1/G30.1 store the current machine position.
//!   Refused under cutter compensation.
//! - Tools ([`Settings::tools`], [`Tool`]): T selects (a tool missing from the table is
//!   "Requested tool N not found in the tool table"; T0 is no tool), M6 loads, M61 Q sets
//!   the tool number without a change (as rs274 does, G43 without H keeps using the entry
//!   of the last M6). G43 H (or the M6 tool; H0 = the tool in the spindle) applies every
//!   offset of the entry (X Y Z A B C), G43.1 replaces the offsets of the axes it names
//!   (its axis words move nothing unless G0–G3 is in the block), G43.2 H adds an entry's
//!   offsets (axis words refused, as LinuxCNC 2.9's rs274 does), G49 cancels. An offset
//!   moves nothing by itself. G10 L1 P sets an entry (axis words, R radius, I J Q lathe
//!   data), L10 from the current point with the offsets in effect, L11 as if in G59.3
//!   without G52/G92; they do not re-apply it (G43 does).
//! - After a block with M6 the current point is read back as rs274 reads it: the program
//!   point of the last move, in which tool offsets changed since that move are not
//!   counted. `T1 M6 G43 H1` then `G0 X1` moves Z by the tool length (rs274 prints the old
//!   program Z); G43 in a later block does not. The next move starts where the machine
//!   is; an arc as that move, when the point changed, is an error. (A real LinuxCNC reads
//!   back the machine position; rs274 is the reference of this dialect.)
//! - Arcs: centre format with I J K (a word for the axis normal to the plane is the error
//!   "K word given for arc in XY plane" and its G18/G19 twins) or radius format R (R < 0 =
//!   more than 180°); both is "mixed radius and centre format"; neither is "R, I, J, and K
//!   words all missing for arc". P = number of turns (P1 = default). Centre format is
//!   rejected when |r_start − r_end| > 100·t, or when it exceeds t and the relative error
//!   exceeds 0.1 %, with t = 0.02828 mm (0.002828 in under G20). Radius format with end =
//!   start is "current point same as end point of arc".
//! - Polar `@` (distance) `^` (angle, degrees, CCW from +X) about the current XY program
//!   zero, G0/G1 only; a missing one keeps the current point's value, measured about the
//!   current zero (as LinuxCNC computes it from the current position: after G92, G92.1,
//!   G92.2, G92.3 or a G5x moved the zero, the point's distance and angle about the new
//!   one; a tool offset along Z only leaves them). Under G91 both are added to the current
//!   point's polar coordinates measured the same way. At program zero the point has no
//!   angle: `@` alone, and either word under G91, are LinuxCNC's errors ("Must specify
//!   angle in polar coordinate if at the origin", "... is indeterminate when at the
//!   origin"). Mixing them with X/Y is an error.
//! - Feed errors use LinuxCNC's words: "Cannot do G1 with zero feed rate", "Cannot make arc
//!   with zero feed rate". F is kept physically across G20/G21 changes.
//! - Words no G code of the block uses are errors, as in LinuxCNC: I/J/K/R without an arc
//!   (also with G92, or G87), P without G2/G3/G4/G10/G64, a dwelling cycle, M62–M66 or a
//!   user M code, Q without G10/G64/M61, G73, G83, M66–M68 or a user M code, E without
//!   M66–M68, H without G43 (also with G49), D without G41/G42/G41.1/G42.1 in the block, L
//!   without G10, a canned cycle, G41.1/G42.1 or M66. A motion code with a code that
//!   takes the axis words (G10, G28, G30, G52, G92) is "Cannot use two g codes that both
//!   use axis values". U, V and W are not supported.
//! - Canned cycles G73, G81, G82, G83, G85, G86, G87, G88, G89 (`interp::cycles`) give the
//!   moves rs274 (LinuxCNC 2.9) gives, in G17, G18 and G19 (the drilling axis is the plane's
//!   normal: Z, Y, X), with G98 (back to the initial level) or G99 (to R; rs274's default),
//!   L repeats and G91 (R from the initial level, the bottom from R, the hole position added
//!   before each repeat). R, the bottom, P, Q and G87's I J K are kept for the following
//!   blocks of the same cycle; a block with axis words continues the cycle, one without
//!   them does nothing (its R, L, P, Q, I, J, K are then unused words); G0–G3 and G80 end
//!   the series (G80 with axis words is "Cannot use axis values with g80"). Polar words
//!   place the hole in G17, as in rs274. Cycle moves are exact stops. Dwells (the P of G82, G86, G88,
//!   G89) are `G4` events; G86 and G88 stop the spindle (`M5`) and restart it (`M3`/`M4`,
//!   the direction it had), G88 stops the program (`M0`) for a manual retract, which Kerf
//!   then makes as a rapid to the clearance level (rs274 leaves that gap: Kerf's moves are
//!   continuous); G87 orients the spindle (`M19` events). G73/G83 back off 0.010 in
//!   (0.254 mm). Errors are rs274's ("R less than z in cycle in xy plane", "Q word missing
//!   with g83", "Negative or zero q value used", "Cannot use canned cycles with cutter
//!   compensation on", "Cannot do zero repeats of cycle", ...). Kerf refuses a negative P
//!   (rs274 dwells a negative time) and a block of more than 100,000 moves and events
//!   (its L repeats and pecks). G33, G33.1, G74, G76 and G84 are "... is not supported:
//!   needs spindle synchronisation". Table: `docs/linuxcnc/cycles.md`.
//! - Cutter radius compensation as LinuxCNC's interpreter computes it (`interp::comp`,
//!   docs/linuxcnc/comp.md): G41/G42 take the radius of tool D from the tool table, or of
//!   the tool loaded by M6 without D (none loaded: radius 0, no effect); G41.1/G42.1 take the
//!   diameter D in program units (L, the lathe orientation, only 0 or 9, in G18); a negative
//!   radius swaps the side. Compensation works in G17 and G18 (else "Cutter radius
//!   compensation allowed only in XY, XZ planes"). The first move after G41/G42 ends one
//!   radius from its programmed end, on the normal of its direction (an arc: on the arc's
//!   normal, its centre moved so that it still starts at the tool); later moves end on the
//!   normal of the programmed path at their end; an outside corner gets an arc about the
//!   programmed corner (a straight traverse for G0) and an inside one shortens the previous
//!   move to the intersection, with LinuxCNC's 0.05 rad corner tolerance. The last move is
//!   held until the next one shows its corner; spindle, coolant and dwell events of
//!   the blocks in between stay behind it, as LinuxCNC queues them. G40, M0, M1, M60, M2 and
//!   M30 release it (checked for gouging as LinuxCNC checks it), as does the end of the file;
//!   a closing `%` drops it, as LinuxCNC does. After G40 the programmed point is the
//!   current point for the next move's words (that move starts at the tool, and may not be
//!   an arc). While compensation is on, its errors are LinuxCNC's: G41/G42 again, a plane,
//!   coordinate system, G92, G43/G49 or tool change, G53, gouging at inside corners, a tool
//!   radius not less than an arc's with the tool inside it. Compensated arcs are exact
//!   (LinuxCNC's may start up to 0.05 rad off their circle; Kerf moves the centre onto the
//!   chord's bisector), and an arc LinuxCNC would turn into a spiral is refused.
//!
//! ## The LinuxCNC language (`ngc` module)
//!
//! A line holding `#`, `[`, an O-word or a message comment goes through the language
//! layer; other lines keep the plain fast path. Checked against LinuxCNC's `rs274`
//! (`tests/data/ngc/lang`, docs/linuxcnc/language.md).
//!
//! - The line is read as LinuxCNC reads it: spaces and tabs removed and letters folded
//!   outside comments, so `#<Depth Of Cut>` is `#<depthofcut>`. Every value of a line is
//!   read before any of its assignments takes effect (`#1=5 G1 X#1` moves to the old #1),
//!   and the assignments take effect in order (`#3=1 #3=2` leaves 2), before the block runs.
//! - Numbered parameters #1–#5601 (reading or setting another one: "Parameter number out of
//!   range"; a fraction: "Non integer value for integer"); unset ones read 0. `##n` and
//!   `#[expr]` are indirect. #5420–#5425 (#5426–#5428 read 0: no U V W) are the current
//!   position in program coordinates and units, #5400 the tool in the spindle.
//! - Named parameters: `#<name>` is local to the subroutine call level (reading one never
//!   set: "Named parameter `#<name>` not defined"), `#<_name>` global. The predefined ones
//!   (`#<_x>`, `#<_abs_x>`, `#<_metric>`, `#<_motion_mode>`, `#<_value>`, … the manual's
//!   list) are read-only ("Cannot assign to read-only parameter").
//! - Expressions `[..]` anywhere a number stands, G and M numbers included. Precedence,
//!   highest first: `**`; `* / MOD`; `+ -`; `EQ NE GT GE LT LE`; `AND OR XOR`, all left to
//!   right. EQ/NE compare within 0.0001. `MOD` is non-negative. Unary `-`/`+` bind tighter
//!   than `**` (`-2**0.5` is an error, as in rs274). Functions ABS ACOS ASIN COS EXP FIX
//!   FUP ROUND LN SIN SQRT TAN (degrees), `ATAN[y]/[x]`, `EXISTS[#<name>]`; their errors
//!   use rs274's words ("Attempt to divide by zero", "Negative argument to sqrt", …).
//!   Brackets and parameter references nest at most 64 deep.
//! - Comments: `(MSG,text)` is a [`EventCode::Msg`] event with the text after the comma as
//!   written; `(DEBUG,text)` and `(PRINT,text)` are [`EventCode::Debug`] and
//!   [`EventCode::Print`] events with each `#n`, `##n`, `#<name>` replaced by its value with
//!   six decimals (`######` when it cannot be read), as rs274 prints them. The keyword may
//!   follow spaces and is case-insensitive. `(LOGOPEN,file)`, `(LOGAPPEND,file)`,
//!   `(LOG,text)` and `(LOGCLOSE)` are [`EventCode::Log`] events whose text is the call:
//!   `LOGOPEN,file` and `LOGAPPEND,file` with the name as written, `LOG,text` substituted
//!   as DEBUG is, `LOGCLOSE` (only the exact comment `(LOGCLOSE)`, as rs274 reads it).
//!   Kerf opens and writes no file: it hands the calls on as events.
//! - O-words, numbered (`o100`) or named (`o<name>`): `sub`/`endsub [v]`/`return [v]`,
//!   `call [a1] [a2] …` (arguments in #1…#30, 0 in the rest as rs274 does, all restored after the call; named
//!   locals are fresh per call; `#<_value>` and `#<_value_returned>` after it), `if`/
//!   `elseif`/`else`/`endif`, `while`/`endwhile`, `do`/`while`, `repeat [n]`/`endrepeat`,
//!   `break`, `continue`. A sub not defined before its call is looked for further down
//!   the program's file ([`Settings::program_file`], as LinuxCNC seeks forward; reaching
//!   its definition later is LinuxCNC's "found in illegal location"), then as `NAME.ngc`
//!   in the program's directory and on [`Settings::subroutine_path`]. Subroutines nest nine deep ("Too many subroutine
//!   levels"); a loop that runs [`Settings::max_loop_iterations`] times is an error.
//! - Memory: the text of a sub, or of a top-level structure up to its end line, is kept
//!   while it runs (at most 1,000,000 lines each); loops run from that text and never
//!   unroll. Items of a subroutine carry the line numbers of the text they come from (of
//!   the subroutine file for a file's sub); an error there names the file
//!   ([`Diagnostic::file`]) and the calling lines ([`Diagnostic::called_from`]).
//!
//! # Rockwell 9/Series mill (`rockwell`, Fanuc style)
//!
//! - `;` ENDS a block (several blocks may share a line); `( )` are comments; a leading
//!   `O1234` program number is skipped; `%` lines as in LinuxCNC.
//! - G20/G21 inch/mm (Fanuc style; the seed does not confirm it), G90/G91, G17/G18/G19,
//!   G61 exact stop mode, G64 cutting mode, G09 exact stop for one block, G54–G59,
//!   G43 H (the length of tool H from the tool table) / G49. The
//!   motion mode at start is G01 (Fanuc power-up default).
//! - Words no code of the block uses are errors: P outside a G04 dwell, Q (cycles are not
//!   supported), H without G43 (also with G49), D without G41/G42 in the block (D names
//!   the tool whose radius the compensation check uses).
//! - Arcs: I J K always incremental from the start point; R± radius; when R and I/J/K are
//!   both given, R wins. R with the end point equal to the start is a 0° arc: no motion and
//!   no error. I J K with the end omitted or equal to the start is a full circle. No turns
//!   word.
//!
//! # Sinumerik 840D (`sinumerik`)
//!
//! - `;` comments; `%_N_NAME_MPF` lines are skipped. Words are `X10` or `X=10`;
//!   `X=AC(..)`/`X=IC(..)` force absolute/incremental for one value; `CR=`, `TURN=`,
//!   `RP=`, `AP=` are recognised; parentheses outside `AC()`/`IC()` are expressions and
//!   not supported. The motion mode at start is G0.
//! - G70/G71 switch the geometry (positions, I J K, CR, RP) between inch and mm while F
//!   stays in the basic unit, mm/min; G700/G710 switch F too (G700: inch/min).
//! - Arcs: I J K incremental from the start regardless of G90/G91, `I=AC(..)` absolute;
//!   `CR=±` radius (a full circle with CR= is an error); `TURN=n` (0..999) adds n full
//!   circles; I J K without an end point is a full circle.
//! - Poles: G110 (relative to the last programmed position), G111 (absolute in the
//!   workpiece system), G112 (relative to the last pole), given by the plane's axis words
//!   or by RP/AP; none of them is affected by G90/G91. Without a pole, the workpiece zero
//!   is the pole. `RP=` (mm) and `AP=` (degrees from the plane's abscissa, CCW positive,
//!   ±360°; `AP=IC(..)` relative to the last AP) give polar end points for G0/G1 and for
//!   G2/G3 circles about the pole (checked with the arc tolerance). RP and AP are modal and
//!   forgotten when the pole or the plane changes; a polar move that lacks one of them
//!   then is an error.
//! - G60 exact stop, G64 continuous path, G9 exact stop for one block. D (tool edge) selects
//!   the tool's offsets, which Kerf does not apply: D0 is accepted, D1 and up only while
//!   the active tool has zero length and radius in the tool table (else an error). H
//!   (auxiliary function) words are an error: Kerf has no machine logic to hand them to.
//!
//! # Heidenhain TNC ISO (`heidenhain`)
//!
//! - `*` ends a block; `;` starts a comment. `%NAME G71 *` (or G70) opens the program and
//!   sets mm (inch); the next `%NAME ... *` line ends it. G70/G71 are also accepted in
//!   blocks. G30/G31 (blank form) blocks are skipped. G99 T L R defines a tool (length L,
//!   radius R); a T word elsewhere is a tool call. There is no motion mode at start.
//! - G90/G91 may switch per word inside a block (`G02 G91 X+5 G90 Y-5`): words after a
//!   G90/G91 take that mode, earlier words the modal one; the last one stays modal.
//! - `I J` (K in G18/G19) set the modal circle centre **and pole** (absolute, or under G91
//!   relative to the last programmed position), also inside a motion block, where they
//!   apply before the motion. G29 makes the last programmed position the centre/pole.
//! - G02/G03 arcs turn about that centre (an end point within 0.016 mm of the start makes
//!   a full circle); with R± they are radius arcs (R− more than 180°; a full circle needs
//!   two half circles). G05 is an arc in the last programmed direction.
//! - Polar lines G10 (rapid) / G11 (feed): R = polar radius, H = polar angle (−360..+360,
//!   CCW from the plane's abscissa), about the pole; both modal; under G91 they are added
//!   to the previous polar values. Polar circles G12 (CW) / G13 (CCW) / G15 (last
//!   direction) about the pole with the radius of the start point. Absolute H (up to
//!   ±5400°) is the angular position of the end point, as seed 004 puts it: H and H ± 360°
//!   name the same point. Choice (the manual does not say how an absolute H turns more than
//!   once): the arc runs from the start point in the programmed direction to that point,
//!   less than one turn, or one whole turn when it is the start point (`G13 H+720` from 0°
//!   is one full circle, `G13 H+365` from 0° is 5°); the start point's angle is measured
//!   from its position, so it does not matter whether it was reached with `H-360`, `H+0` or
//!   a Cartesian move. Several turns are programmed with G91: G91 H is the swept angle
//!   itself (H+720 is two turns) and its sign must match the direction. An axis word along
//!   the normal makes a helix.
//! - G41/G42 with a zero tool radius keep the programmed path. An R word in a G00/G01
//!   block is an error (R belongs to G02/G03, G10/G11 and G99), and so is an L word
//!   outside G99. A G99 block holds no axis, centre or H words; its M codes run. A G30/G31
//!   blank form block holds no M codes and no F, S or T words.
//!
//! # Fagor 8070 (`fagor`)
//!
//! - `;` and `( )` comments; `%name` header lines are skipped; N up to 4294967295. The
//!   motion mode at start is G00. G70 inch / G71 mm (not confirmed by the seed). G05 and
//!   G50 blend, G07 square corner (exact stop).
//! - Arcs: `X Y I J` with I J K incremental from the start point and not affected by
//!   G90/G91 (G06 in the block: I J absolute, for that block only); `X Y R±` radius (a full
//!   circle with R is an error); with neither I/J nor R the centre is the polar origin.
//! - Polar end points: `R` (radius) and `Q` (angle, degrees, CCW from the plane's
//!   abscissa) about the polar origin, in G00/G01/G02/G03. In G02/G03 an `R` together with
//!   X/Y in the plane is the arc radius, otherwise `R`/`Q` are polar. A missing R or Q
//!   keeps the value of the last point; under G91 they are added to it. When the polar
//!   origin moves (G30, a plane change, or G54–G59 while it is part zero) that value is the
//!   point's radius or angle measured about the new origin. `G91 Q360` (any
//!   non-zero multiple of 360°) about the polar origin is a whole circle (or several);
//!   `G90 Q360` is the point at 360°.
//! - The polar origin is part zero until `G30 I.. J..` (K in G18/G19) sets it at those
//!   absolute part coordinates; `G30` alone makes the current point the polar origin. A
//!   plane change resets it to part zero. Axis, R and Q words in a G30 block are errors.
//! - D (tool offset) as in Sinumerik: D0 accepted, D1 and up only while the active tool
//!   has zero length and radius.
#![deny(missing_docs)]
#![forbid(unsafe_code)]

mod arc;
mod codes;
mod interp;
mod lex;
mod ngc;

pub use codes::{CodeInfo, code_reference, word_addresses};
pub use kerf_geom::{Arc, CornerMode, Event, EventCode, Item, Line, Move, Path, Vec3};

mod diagnostic;
mod dialect;
mod inputs;
mod interpreter;
mod settings;

pub use diagnostic::Diagnostic;
pub use dialect::Dialect;
pub use inputs::{InputWait, MAX_IO_NUMBER, SimulatedInputs};
pub use interpreter::{Interpreter, MAX_LINE_BYTES};
pub use settings::{Settings, Tool};

#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_mdi;
#[cfg(test)]
mod tests_plain;
