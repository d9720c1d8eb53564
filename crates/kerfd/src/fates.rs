//! What became of each program: the daemon's memory of the last
//! [`PROGRAMS_REMEMBERED`] programs whose BEGIN arrived, accepted or refused, for
//! `REQUEST_PROGRAM` (a client reads the fate of its own program by id, also after other
//! programs began) and for refusing a BEGIN that repeats a known id.
//!
//! The planning thread records what it decides (BEGIN accepted or refused, END received)
//! and the control thread what the real-time cycle reports (finished, aborted, refused,
//! stopped by the safety layer). Neither is the real-time thread: the table sits behind a
//! mutex and allocates freely.

use std::collections::VecDeque;

use kerf_proto::{
    PROGRAM_FATE_ABORTED, PROGRAM_FATE_FINISHED, PROGRAM_FATE_RECEIVING, PROGRAM_FATE_REFUSED,
    PROGRAM_FATE_RUNNING, PROGRAM_FATE_UNKNOWN, PROGRAMS_REMEMBERED,
};

/// The fate of one program: a `PROGRAM_FATE_*` code and, for a refused or aborted
/// program, why.
#[derive(Clone, Debug, PartialEq)]
pub struct Fate {
    /// `PROGRAM_FATE_*`.
    pub code: u32,
    /// Why it was refused or aborted; empty otherwise.
    pub reason: String,
}

impl Fate {
    /// `true` once nothing can change it any more.
    pub(crate) fn is_final(&self) -> bool {
        matches!(
            self.code,
            PROGRAM_FATE_FINISHED | PROGRAM_FATE_ABORTED | PROGRAM_FATE_REFUSED
        )
    }
}

/// The last [`PROGRAMS_REMEMBERED`] programs, oldest first.
#[derive(Debug, Default)]
pub struct Fates {
    programs: VecDeque<(u64, Fate)>,
}

impl Fates {
    /// An empty memory.
    pub fn new() -> Fates {
        Fates::default()
    }

    /// `true` when a program of this id is remembered.
    pub fn knows(&self, program_id: u64) -> bool {
        self.programs.iter().any(|(id, _)| *id == program_id)
    }

    /// The fate of program `program_id` (`PROGRAM_FATE_UNKNOWN` when not remembered).
    pub fn get(&self, program_id: u64) -> Fate {
        self.programs
            .iter()
            .rev()
            .find(|(id, _)| *id == program_id)
            .map_or(
                Fate {
                    code: PROGRAM_FATE_UNKNOWN,
                    reason: String::new(),
                },
                |(_, f)| f.clone(),
            )
    }

    /// The programs whose BEGIN was accepted and whose fate is not final yet, oldest
    /// first.
    pub fn unfinished(&self) -> Vec<u64> {
        self.programs
            .iter()
            .filter(|(_, f)| !f.is_final() && f.code != PROGRAM_FATE_UNKNOWN)
            .map(|(id, _)| *id)
            .collect()
    }

    /// A new program whose BEGIN was accepted (receiving), or refused (with the reason).
    /// An id already remembered keeps its first fate: a BEGIN that repeats it is refused
    /// without touching the program it names.
    pub fn begin(&mut self, program_id: u64, refused: Option<String>) {
        if program_id == 0 || self.knows(program_id) {
            return;
        }
        if self.programs.len() == PROGRAMS_REMEMBERED {
            self.programs.pop_front();
        }
        let fate = match refused {
            None => Fate {
                code: PROGRAM_FATE_RECEIVING,
                reason: String::new(),
            },
            Some(reason) => Fate {
                code: PROGRAM_FATE_REFUSED,
                reason,
            },
        };
        self.programs.push_back((program_id, fate));
    }

    /// The program was received to its END (unless its fate is already final).
    pub fn received(&mut self, program_id: u64) {
        self.update(program_id, PROGRAM_FATE_RUNNING, String::new());
    }

    /// The program's final fate. Returns `true` if this changed it (the first time it
    /// became final).
    pub fn end(&mut self, program_id: u64, code: u32, reason: String) -> bool {
        self.update(program_id, code, reason)
    }

    fn update(&mut self, program_id: u64, code: u32, reason: String) -> bool {
        match self
            .programs
            .iter_mut()
            .rev()
            .find(|(id, _)| *id == program_id)
        {
            Some((_, f)) if !f.is_final() => {
                *f = Fate { code, reason };
                true
            }
            _ => false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_final_fate_never_changes_and_a_repeated_begin_keeps_the_first() {
        let mut f = Fates::new();
        f.begin(7, None);
        assert_eq!(f.get(7).code, PROGRAM_FATE_RECEIVING);
        f.received(7);
        assert_eq!(f.get(7).code, PROGRAM_FATE_RUNNING);
        assert!(f.end(7, PROGRAM_FATE_ABORTED, "aborted".into()));
        assert!(!f.end(7, PROGRAM_FATE_FINISHED, String::new()));
        f.received(7);
        assert_eq!(f.get(7).code, PROGRAM_FATE_ABORTED);
        f.begin(7, Some("again".into()));
        assert_eq!(f.get(7).reason, "aborted");
        assert_eq!(f.get(8).code, PROGRAM_FATE_UNKNOWN);
    }

    #[test]
    fn only_the_last_programs_are_remembered() {
        let mut f = Fates::new();
        for id in 1..=(PROGRAMS_REMEMBERED as u64 + 10) {
            f.begin(id, None);
        }
        assert!(!f.knows(10));
        assert!(f.knows(11));
        assert!(f.knows(PROGRAMS_REMEMBERED as u64 + 10));
    }
}
