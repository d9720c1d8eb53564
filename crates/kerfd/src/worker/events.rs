//! What the program's non-motion events mean to the motion.

use super::*;

/// What a non-motion event of the program means to the motion: a dwell (`G4`) is an exact
/// stop and a rest; a program stop (M0, M1), an end (M2, M30), a tool change (M6), a
/// spindle (M3, M4, M5, S) or coolant (M7, M8, M9) change is an exact stop, because the
/// control waits for the motion to finish before it acts on it (as LinuxCNC does); a tool
/// selection (T) does not stop the motion. A pallet-change pause (M60) is a program stop,
/// and a user M code (M100–M199) runs its program after the motion before it, as LinuxCNC
/// does; messages (MSG, DEBUG, PRINT), LinuxCNC's log calls (LOG, passed on) and the
/// override controls (M48–M53) do not stop the motion. The
/// simulation does not wait at a program stop (it stands for an operator who presses
/// cycle start at once) and runs M1 like M0.
pub fn input_of_event(e: &kerf_geom::Event) -> Option<Input> {
    use kerf_geom::EventCode as C;
    match e.code {
        C::G4 => Some(Input::Dwell(e.value.unwrap_or(0.0))),
        // The override controls (M48–M53) change what the operator's overrides do from
        // this point of the path on: LinuxCNC queues them with the motion, no stop.
        C::T | C::Msg | C::Debug | C::Print | C::Log => None,
        C::M48 | C::M49 | C::M50 | C::M51 | C::M52 | C::M53 => None,
        C::M60 | C::User(_) => Some(Input::Stop),
        C::M0
        | C::M1
        | C::M2
        | C::M30
        | C::M3
        | C::M4
        | C::M5
        | C::M6
        | C::M7
        | C::M8
        | C::M9
        | C::M19
        | C::S => Some(Input::Stop),
    }
}
