//! The application-layer (AL) state machine of one subdevice (ETG.1000.6 §6.4): the
//! states INIT, PRE-OP, BOOT, SAFE-OP and OP, the request in AL control (0x0120), the
//! answer in AL status (0x0130, bit 4 the error indicator) and AL status code (0x0134).

/// AL status code 0x0000: no error.
pub const CODE_NONE: u16 = 0x0000;
/// AL status code 0x0011: invalid requested state change.
pub const CODE_INVALID_STATE_CHANGE: u16 = 0x0011;
/// AL status code 0x0012: unknown requested state.
pub const CODE_UNKNOWN_STATE: u16 = 0x0012;
/// AL status code 0x0016: invalid mailbox configuration.
pub const CODE_INVALID_MAILBOX_CONFIG: u16 = 0x0016;
/// AL status code 0x001B: SyncManager watchdog.
pub const CODE_SM_WATCHDOG: u16 = 0x001B;
/// AL status code 0x001D: invalid output configuration.
pub const CODE_INVALID_OUTPUT_CONFIG: u16 = 0x001D;
/// AL status code 0x001E: invalid input configuration.
pub const CODE_INVALID_INPUT_CONFIG: u16 = 0x001E;

/// An AL state.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum AlState {
    /// INIT (1).
    Init = 1,
    /// PRE-OP (2).
    PreOp = 2,
    /// BOOT (3).
    Boot = 3,
    /// SAFE-OP (4).
    SafeOp = 4,
    /// OP (8).
    Op = 8,
}

impl AlState {
    /// Decodes the 4 state bits of AL control or status.
    pub fn from_bits(bits: u8) -> Option<AlState> {
        match bits & 0x0F {
            1 => Some(AlState::Init),
            2 => Some(AlState::PreOp),
            3 => Some(AlState::Boot),
            4 => Some(AlState::SafeOp),
            8 => Some(AlState::Op),
            _ => None,
        }
    }
}

/// True when ETG.1000.6's state machine allows `from` → `to` (or they are equal).
pub fn is_allowed(from: AlState, to: AlState) -> bool {
    use AlState::*;
    from == to
        || to == Init
        || matches!(
            (from, to),
            (Init, PreOp)
                | (Init, Boot)
                | (PreOp, SafeOp)
                | (SafeOp, Op)
                | (SafeOp, PreOp)
                | (Op, SafeOp)
                | (Op, PreOp)
        )
}

/// The state machine of one subdevice.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Al {
    state: AlState,
    error: bool,
    code: u16,
}

impl Default for Al {
    fn default() -> Self {
        Al {
            state: AlState::Init,
            error: false,
            code: CODE_NONE,
        }
    }
}

impl Al {
    /// The current state.
    pub fn state(&self) -> AlState {
        self.state
    }

    /// The error indicator.
    pub fn error(&self) -> bool {
        self.error
    }

    /// The AL status code.
    pub fn code(&self) -> u16 {
        self.code
    }

    /// The AL status register's value (0x0130): state bits and the error indicator.
    pub fn status_word(&self) -> u16 {
        self.state as u16 | if self.error { 0x10 } else { 0 }
    }

    /// A request written to AL control. `check` is the application's verdict on entering a
    /// state from the current one (`Err(code)` refuses it). Returns the transition that
    /// happened, if any.
    ///
    /// While the error indicator is set, a request without the acknowledge bit (bit 4,
    /// 0x10) is ignored: the subdevice stays in its state with the indicator and its
    /// code. With the acknowledge bit, the indicator and the code are cleared and the
    /// state bits of the same write are then acted on as any request: 0x14 in SAFE-OP
    /// (acknowledge, stay) then 0x08 returns to OP, and so does 0x18 at once (acknowledge
    /// and OP in one write). This follows ETG.1000.6's AL control as read here (the
    /// acknowledge flag travels with a state request, and nothing makes the request wait
    /// for a second write), not checked against a real ESC; masters mostly send the
    /// acknowledge with the current state first, which works the same.
    pub fn request(
        &mut self,
        control: u16,
        check: impl FnOnce(AlState, AlState) -> Result<(), u16>,
    ) -> Option<(AlState, AlState)> {
        let acknowledge = control & 0x10 != 0;
        if self.error {
            if !acknowledge {
                return None;
            }
            self.error = false;
            self.code = CODE_NONE;
        }
        let Some(to) = AlState::from_bits(control as u8) else {
            self.fail(CODE_UNKNOWN_STATE);
            return None;
        };
        if to == self.state {
            return None;
        }
        if !is_allowed(self.state, to) {
            self.fail(CODE_INVALID_STATE_CHANGE);
            return None;
        }
        match check(self.state, to) {
            Ok(()) => {
                let from = self.state;
                self.state = to;
                Some((from, to))
            }
            Err(code) => {
                self.fail(code);
                None
            }
        }
    }

    /// The subdevice falls back to `state` with an error (e.g. the SM watchdog: SAFE-OP,
    /// 0x001B).
    pub fn drop_to(&mut self, state: AlState, code: u16) {
        if state < self.state {
            self.state = state;
        }
        self.fail(code);
    }

    fn fail(&mut self, code: u16) {
        self.error = true;
        self.code = code;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ok(_: AlState, _: AlState) -> Result<(), u16> {
        Ok(())
    }

    #[test]
    fn init_to_op_directly_is_an_invalid_state_change() {
        let mut al = Al::default();
        assert_eq!(al.request(0x08, ok), None);
        assert_eq!(
            (al.state(), al.error(), al.code()),
            (AlState::Init, true, 0x0011)
        );
        assert_eq!(al.status_word(), 0x11);
        // Ignored without acknowledge, accepted with it.
        assert_eq!(al.request(0x02, ok), None);
        assert_eq!(al.request(0x12, ok), Some((AlState::Init, AlState::PreOp)));
        assert_eq!((al.status_word(), al.code()), (0x02, 0));
    }

    #[test]
    fn the_application_can_refuse_with_its_code() {
        let mut al = Al::default();
        al.request(0x02, ok);
        al.request(0x04, |_, _| Err(CODE_INVALID_OUTPUT_CONFIG));
        assert_eq!((al.status_word(), al.code()), (0x12, 0x001D));
        assert_eq!(al.request(0x11, ok), Some((AlState::PreOp, AlState::Init)));
    }

    #[test]
    fn unknown_state_bits_are_refused() {
        let mut al = Al::default();
        al.request(0x05, ok);
        assert_eq!(al.code(), 0x0012);
    }

    fn in_safe_op_after_the_watchdog() -> Al {
        let mut al = Al::default();
        al.request(0x02, ok);
        al.request(0x04, ok);
        al.request(0x08, ok);
        al.drop_to(AlState::SafeOp, CODE_SM_WATCHDOG);
        al
    }

    #[test]
    fn an_acknowledge_clears_the_error_and_op_follows_in_the_same_or_the_next_write() {
        // Without the acknowledge bit the request for OP is ignored.
        let mut al = in_safe_op_after_the_watchdog();
        assert_eq!(al.request(0x08, ok), None);
        assert_eq!((al.status_word(), al.code()), (0x14, 0x001B));
        // Acknowledge in SAFE-OP (0x14): SAFE-OP without error, code 0; then OP.
        assert_eq!(al.request(0x14, ok), None);
        assert_eq!((al.status_word(), al.code()), (0x04, 0x0000));
        assert_eq!(al.request(0x08, ok), Some((AlState::SafeOp, AlState::Op)));
        assert_eq!((al.status_word(), al.code()), (0x08, 0x0000));
        // Acknowledge and OP in one write (0x18).
        let mut al = in_safe_op_after_the_watchdog();
        assert_eq!(al.request(0x18, ok), Some((AlState::SafeOp, AlState::Op)));
        assert_eq!((al.status_word(), al.code()), (0x08, 0x0000));
        // Acknowledge and a lower state (0x12): PRE-OP.
        let mut al = in_safe_op_after_the_watchdog();
        assert_eq!(
            al.request(0x12, ok),
            Some((AlState::SafeOp, AlState::PreOp))
        );
        assert_eq!((al.status_word(), al.code()), (0x02, 0x0000));
        // An acknowledge whose request is refused sets the indicator again, with the
        // refusal's code.
        let mut al = in_safe_op_after_the_watchdog();
        assert_eq!(al.request(0x18, |_, _| Err(0x0035)), None);
        assert_eq!((al.status_word(), al.code()), (0x14, 0x0035));
    }

    #[test]
    fn the_watchdog_drops_op_to_safe_op_with_its_code() {
        let mut al = Al::default();
        al.request(0x02, ok);
        al.request(0x04, ok);
        al.request(0x08, ok);
        al.drop_to(AlState::SafeOp, CODE_SM_WATCHDOG);
        assert_eq!((al.status_word(), al.code()), (0x14, 0x001B));
    }
}
