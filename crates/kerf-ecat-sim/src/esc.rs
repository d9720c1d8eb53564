//! The register map and memory of one EtherCAT subdevice controller (ESC), as the
//! MainDevice sees it through physical reads and writes: 64 KiB of address space whose
//! registers 0x0000–0x0FFF behave as ETG.1000.4 says and whose process RAM from 0x1000
//! holds the mailboxes and process data. The behaviour behind it (mailbox protocols,
//! process data) is the [`Application`].
//!
//! Registers with behaviour: information 0x0000–0x0008 (read-only), station address
//! 0x0010 and alias 0x0012, DL status 0x0110, AL control 0x0120 / status 0x0130 / code
//! 0x0134, watchdogs 0x0400 / 0x0410 / 0x0420 and status 0x0440, SII access 0x0500–0x050F,
//! FMMUs 0x0600+, SyncManagers 0x0800+ (status byte: mailbox full), DC 0x0900–0x09FF
//! (receive times, system time 0x0910, offset 0x0920, delay 0x0928, system time
//! difference 0x092C read-only: see [`crate::dc::difference_register`]).

use crate::al::{self, Al, AlState};
use crate::dc::{self, DcClock};
use crate::sii::{SiiSpec, SmUsage};

/// Register: AL control.
pub const REG_AL_CONTROL: u16 = 0x0120;
/// Register: AL status.
pub const REG_AL_STATUS: u16 = 0x0130;
/// Register: AL status code.
pub const REG_AL_STATUS_CODE: u16 = 0x0134;
/// Register: SII control/status.
pub const REG_SII_CONTROL: u16 = 0x0502;
/// Register: SII data.
pub const REG_SII_DATA: u16 = 0x0508;
/// Register: first FMMU.
pub const REG_FMMU0: u16 = 0x0600;
/// Register: first SyncManager.
pub const REG_SM0: u16 = 0x0800;
/// Register: DC receive time port 0 (a write latches all ports).
pub const REG_DC_PORT0: u16 = 0x0900;
/// Register: DC system time.
pub const REG_DC_SYSTEM_TIME: u16 = 0x0910;
/// Register: DC receive time of port 0, 64 bits.
pub const REG_DC_RECEIVE_TIME: u16 = 0x0918;
/// Register: DC system time offset.
pub const REG_DC_OFFSET: u16 = 0x0920;
/// Register: DC system time delay.
pub const REG_DC_DELAY: u16 = 0x0928;
/// Register: DC system time difference.
pub const REG_DC_DIFFERENCE: u16 = 0x092C;
/// Register: watchdog status (process data).
pub const REG_WD_STATUS: u16 = 0x0440;

const MEMORY_LEN: usize = 0x1_0000;

/// Where a subdevice is on the line and what time it is, for one access.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Ctx {
    /// The loop's time, ns.
    pub now_ns: u64,
    /// The subdevice's position on the line (0 first).
    pub position: u16,
    /// How many subdevices the line has.
    pub count: u16,
}

/// One SyncManager's registers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SmRegisters {
    /// Physical start address.
    pub start: u16,
    /// Length, bytes.
    pub len: u16,
    /// Control byte.
    pub control: u8,
    /// Enabled (activate register bit 0).
    pub enabled: bool,
}

/// What the application behind an ESC shows, for the emulator's `state` command.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AppSnapshot {
    /// A CiA 402 drive.
    Drive(crate::drive::DriveSnapshot),
    /// A digital I/O subdevice.
    Io(crate::io::IoSnapshot),
}

/// What a subdevice does behind its ESC.
pub trait Application: Send {
    /// The EEPROM contents (and the SyncManager layout it declares).
    fn sii(&self) -> &SiiSpec;
    /// The process data sizes the application expects now: (output bytes, input bytes).
    fn process_data_len(&self) -> (u16, u16);
    /// A complete mailbox request written by the MainDevice; returns the response.
    fn mailbox(&mut self, request: &[u8], state: AlState) -> Option<Vec<u8>>;
    /// The outputs were written (a complete output buffer); `apply` is false outside OP
    /// (SAFE-OP: the application keeps its outputs safe).
    fn outputs(&mut self, data: &[u8], apply: bool, now_ns: u64);
    /// Fill the inputs the MainDevice is about to read.
    fn inputs(&mut self, data: &mut [u8]);
    /// A state change took place.
    fn transition(&mut self, from: AlState, to: AlState);
    /// The process-data watchdog expired: no output write for the watchdog time. The
    /// application makes its outputs safe by itself (a drive does its quick stop).
    fn watchdog_expired(&mut self, _now_ns: u64) {}
    /// Called once per loop turn with the time (a drive stopping by itself goes on).
    fn tick(&mut self, _now_ns: u64) {}
    /// Test hook: trip a fault with this error code; false where the application has
    /// no such notion.
    fn inject_fault(&mut self, _error_code: u16) -> bool {
        false
    }
    /// Test hook: jam the motor (`true`) or free it; false where the application has no
    /// motor.
    fn set_stalled(&mut self, _stalled: bool) -> bool {
        false
    }
    /// What it shows now.
    fn snapshot(&self) -> AppSnapshot;
}

/// One subdevice: registers, EEPROM, AL state, clock and its application.
pub struct Esc {
    memory: Vec<u8>,
    eeprom: Vec<u16>,
    al: Al,
    clock: DcClock,
    mailbox_pending: bool,
    last_output_ns: Option<u64>,
    watchdog_trips: u32,
    refusal: Option<(AlState, u16)>,
    /// An error of its own, to take effect at the next tick (see [`Esc::fail_out_of_op`]).
    pending_failure: Option<u16>,
    app: Box<dyn Application>,
}

impl core::fmt::Debug for Esc {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Esc")
            .field("al", &self.al)
            .field("clock", &self.clock)
            .finish_non_exhaustive()
    }
}

fn overlaps(a_start: usize, a_len: usize, b_start: usize, b_len: usize) -> bool {
    a_start < b_start + b_len && b_start < a_start + a_len
}

impl Esc {
    /// A subdevice in INIT with this distributed clock.
    pub fn new(app: Box<dyn Application>, clock: DcClock) -> Esc {
        let eeprom = crate::sii::build_image(app.sii());
        let mut esc = Esc {
            memory: vec![0; MEMORY_LEN],
            eeprom,
            al: Al::default(),
            clock,
            mailbox_pending: false,
            last_output_ns: None,
            watchdog_trips: 0,
            refusal: None,
            pending_failure: None,
            app,
        };
        let info: [u8; 10] = [
            0x11, // type
            0x01, // revision
            0x01, 0x00, // build
            8,    // FMMUs
            8,    // SyncManagers
            60,   // RAM, KiB
            0x0F, // ports 0 and 1: MII; 2 and 3 not implemented
            0x0C, 0x00, // features: DC, 64-bit DC
        ];
        esc.memory[..info.len()].copy_from_slice(&info);
        esc.memory[usize::from(REG_SII_CONTROL)] = 0xC0; // 8-byte reads, 2-byte addresses
        esc.set_u16(0x0400, 0x09C2); // watchdog divider: 100 µs
        esc.set_u16(0x0410, 1000);
        esc.set_u16(0x0420, 1000);
        esc
    }

    /// The AL state machine.
    pub fn al(&self) -> &Al {
        &self.al
    }

    /// The configured station address (0x0010).
    pub fn station_address(&self) -> u16 {
        self.u16_at(0x0010)
    }

    /// The application.
    pub fn app(&self) -> &dyn Application {
        self.app.as_ref()
    }

    /// The application, mutably.
    pub fn app_mut(&mut self) -> &mut dyn Application {
        self.app.as_mut()
    }

    fn u16_at(&self, at: u16) -> u16 {
        let at = usize::from(at);
        u16::from_le_bytes([self.memory[at], self.memory[at + 1]])
    }

    fn u32_at(&self, at: u16) -> u32 {
        let at = usize::from(at);
        u32::from_le_bytes(self.memory[at..at + 4].try_into().unwrap_or([0; 4]))
    }

    fn u64_at(&self, at: u16) -> u64 {
        let at = usize::from(at);
        u64::from_le_bytes(self.memory[at..at + 8].try_into().unwrap_or([0; 8]))
    }

    fn set_u16(&mut self, at: u16, value: u16) {
        let at = usize::from(at);
        self.memory[at..at + 2].copy_from_slice(&value.to_le_bytes());
    }

    fn set_u64(&mut self, at: u16, value: u64) {
        let at = usize::from(at);
        self.memory[at..at + 8].copy_from_slice(&value.to_le_bytes());
    }

    /// SyncManager `index`'s registers.
    pub fn sm(&self, index: u16) -> SmRegisters {
        let base = REG_SM0 + 8 * index;
        SmRegisters {
            start: self.u16_at(base),
            len: self.u16_at(base + 2),
            control: self.memory[usize::from(base + 4)],
            enabled: self.memory[usize::from(base + 6)] & 1 != 0,
        }
    }

    fn sm_of(&self, usage: SmUsage) -> Option<(u16, SmRegisters)> {
        let index = self
            .app
            .sii()
            .sync_managers
            .iter()
            .position(|sm| sm.usage == usage)?;
        Some((index as u16, self.sm(index as u16)))
    }

    /// The registers whose value is computed when read.
    fn refresh(&mut self, start: usize, len: usize, ctx: Ctx) {
        let last = ctx.position + 1 >= ctx.count;
        // DL status: PDI operational, watchdog ok, link and signal on port 0 (and port 1
        // unless last), loop closed on the closed ports.
        let mut dl: u16 = 0x0001 | 0x0002 | 0x0010 | 0x0200 | 0x1000 | 0x4000;
        dl |= if last { 0x0400 } else { 0x0020 | 0x0800 };
        self.set_u16(0x0110, dl);
        self.set_u16(REG_AL_STATUS, self.al.status_word());
        self.set_u16(REG_AL_STATUS_CODE, self.al.code());
        if overlaps(start, len, usize::from(REG_DC_SYSTEM_TIME), 8) {
            let offset = self.u64_at(REG_DC_OFFSET);
            self.set_u64(REG_DC_SYSTEM_TIME, self.clock.system_ns(ctx.now_ns, offset));
        }
        for index in 0..8u16 {
            let sm = self.sm(index);
            let is_mailbox_in = sm.control & 0x03 == 0x02 && (sm.control >> 2) & 0x03 == 0;
            let full = is_mailbox_in && self.mailbox_pending;
            self.memory[usize::from(REG_SM0 + 8 * index + 5)] = if full { 0x08 } else { 0 };
        }
        if let Some((_, sm)) = self.sm_of(SmUsage::Inputs)
            && sm.enabled
            && sm.len > 0
            && overlaps(start, len, usize::from(sm.start), usize::from(sm.len))
            && self.al.state() >= AlState::SafeOp
        {
            let range = usize::from(sm.start)..usize::from(sm.start) + usize::from(sm.len);
            self.app.inputs(&mut self.memory[range]);
        }
    }

    /// A physical read of `out.len()` bytes at `address`.
    pub fn read(&mut self, address: u16, out: &mut [u8], ctx: Ctx) {
        let start = usize::from(address);
        self.refresh(start, out.len(), ctx);
        for (i, byte) in out.iter_mut().enumerate() {
            *byte = self.memory[(start + i) % MEMORY_LEN];
        }
        if let Some((_, sm)) = self.sm_of(SmUsage::MailboxIn) {
            let last = usize::from(sm.start) + usize::from(sm.len).max(1) - 1;
            if sm.enabled && (start..start + out.len()).contains(&last) {
                self.mailbox_pending = false;
            }
        }
    }

    fn writable(at: usize) -> bool {
        let read_only_register = matches!(
            at,
            0x0000..=0x000F
                | 0x0110..=0x0111
                | 0x0130..=0x0135
                | 0x0440..=0x0441
                | 0x0900..=0x090F
                | 0x0918..=0x091F
                | 0x092C..=0x092F
        );
        // SyncManager status (byte 5) and PDI control (byte 7) belong to the ESC.
        let sm_status = (0x0800..0x0880).contains(&at) && matches!(at % 8, 5 | 7);
        !read_only_register && !sm_status
    }

    /// A physical write of `data` at `address`.
    pub fn write(&mut self, address: u16, data: &[u8], ctx: Ctx) {
        let start = usize::from(address);
        for (i, byte) in data.iter().enumerate() {
            let at = (start + i) % MEMORY_LEN;
            if Self::writable(at) {
                self.memory[at] = *byte;
            }
        }
        let touches = |reg: u16, len: usize| overlaps(start, data.len(), usize::from(reg), len);
        if touches(REG_AL_CONTROL, 2) {
            self.al_request(self.u16_at(REG_AL_CONTROL), ctx.now_ns);
        }
        if touches(REG_SII_CONTROL, 2) {
            self.sii_command();
        }
        if touches(REG_DC_PORT0, 4) {
            self.latch_receive_times(ctx);
        }
        let covers = |reg: u16, len: usize| {
            start <= usize::from(reg) && usize::from(reg) + len <= start + data.len()
        };
        // A write of the reference's system time (FRMW / BWR to 0x0910): 64 bits, or the
        // lower 32; the difference it shows is kept in 0x092C.
        let offset = self.u64_at(REG_DC_OFFSET);
        let delay = self.u32_at(REG_DC_DELAY);
        let difference = if covers(REG_DC_SYSTEM_TIME, 8) {
            let received = self.u64_at(REG_DC_SYSTEM_TIME);
            Some(self.clock.steer(ctx.now_ns, offset, delay, received))
        } else if covers(REG_DC_SYSTEM_TIME, 4) {
            let received = self.u32_at(REG_DC_SYSTEM_TIME);
            Some(self.clock.steer_32(ctx.now_ns, offset, delay, received))
        } else {
            None
        };
        if let Some(difference) = difference {
            let word = dc::difference_register(difference);
            self.memory[usize::from(REG_DC_DIFFERENCE)..usize::from(REG_DC_DIFFERENCE) + 4]
                .copy_from_slice(&word.to_le_bytes());
        }
        self.after_sm_write(start, data.len(), ctx);
    }

    fn after_sm_write(&mut self, start: usize, len: usize, ctx: Ctx) {
        if let Some((_, sm)) = self.sm_of(SmUsage::MailboxOut) {
            let last = usize::from(sm.start) + usize::from(sm.len).max(1) - 1;
            if sm.enabled && sm.len > 0 && (start..start + len).contains(&last) {
                let range = usize::from(sm.start)..=last;
                let request = self.memory[range].to_vec();
                if let Some(response) = self.app.mailbox(&request, self.al.state()) {
                    self.put_mailbox_response(&response);
                }
            }
        }
        if let Some((_, sm)) = self.sm_of(SmUsage::Outputs)
            && sm.enabled
            && sm.len > 0
        {
            let last = usize::from(sm.start) + usize::from(sm.len) - 1;
            if (start..start + len).contains(&last) && self.al.state() >= AlState::SafeOp {
                let range = usize::from(sm.start)..=last;
                let apply = self.al.state() == AlState::Op;
                let data = self.memory[range].to_vec();
                self.app.outputs(&data, apply, ctx.now_ns);
                self.last_output_ns = Some(ctx.now_ns);
            }
        }
    }

    fn put_mailbox_response(&mut self, response: &[u8]) {
        let Some((_, sm)) = self.sm_of(SmUsage::MailboxIn) else {
            return;
        };
        let start = usize::from(sm.start);
        let len = usize::from(sm.len);
        let area = &mut self.memory[start..start + len];
        area.fill(0);
        let n = response.len().min(len);
        area[..n].copy_from_slice(&response[..n]);
        self.mailbox_pending = true;
    }

    fn sii_command(&mut self) {
        let at = usize::from(REG_SII_CONTROL);
        let command = self.memory[at + 1];
        let word = usize::from(self.u16_at(0x0504));
        if command & 0x01 != 0 {
            for i in 0..4 {
                let value = self.eeprom.get(word + i).copied().unwrap_or(0xFFFF);
                self.set_u16(REG_SII_DATA + 2 * i as u16, value);
            }
        } else if command & 0x02 != 0 {
            let value = self.u16_at(REG_SII_DATA);
            if let Some(slot) = self.eeprom.get_mut(word) {
                *slot = value;
            }
        }
        // Done at once: clear the command and busy bits, keep no error.
        self.memory[at + 1] = 0;
    }

    fn latch_receive_times(&mut self, ctx: Ctx) {
        let local = self.clock.local_ns(ctx.now_ns);
        let (port0, port1) = dc::receive_times(local, ctx.position, ctx.count);
        let base = usize::from(REG_DC_PORT0);
        self.memory[base..base + 16].fill(0);
        self.memory[base..base + 4].copy_from_slice(&(port0 as u32).to_le_bytes());
        if let Some(port1) = port1 {
            self.memory[base + 4..base + 8].copy_from_slice(&(port1 as u32).to_le_bytes());
        }
        self.set_u64(REG_DC_RECEIVE_TIME, port0);
    }

    /// Test hook: refuse every request to enter `state` with AL status `code` (e.g.
    /// SAFE-OP with 0x001D, as a drive whose configuration does not suit it): the
    /// subdevice stays where it is, with the error indicator and that code.
    pub fn refuse(&mut self, state: AlState, code: u16) {
        self.refusal = Some((state, code));
    }

    fn check_transition(&self, from: AlState, to: AlState) -> Result<(), u16> {
        if let Some((state, code)) = self.refusal
            && state == to
        {
            return Err(code);
        }
        let sii = self.app.sii();
        let needs_mailbox = to != AlState::Init && sii.mailbox.is_some();
        if from == AlState::Init && needs_mailbox {
            for (usage, expected_len) in [
                (SmUsage::MailboxOut, sii.mailbox.map(|m| m.1)),
                (SmUsage::MailboxIn, sii.mailbox.map(|m| m.3)),
            ] {
                let declared = sii.sync_managers.iter().find(|s| s.usage == usage);
                let actual = self.sm_of(usage).map(|(_, sm)| sm);
                let good = match (declared, actual, expected_len) {
                    (Some(d), Some(a), Some(len)) => {
                        a.enabled && a.start == d.start && a.len == len && a.control == d.control
                    }
                    _ => false,
                };
                if !good {
                    return Err(al::CODE_INVALID_MAILBOX_CONFIG);
                }
            }
        }
        if from == AlState::PreOp && to == AlState::SafeOp {
            let (out_len, in_len) = self.app.process_data_len();
            for (usage, len, code) in [
                (SmUsage::Outputs, out_len, al::CODE_INVALID_OUTPUT_CONFIG),
                (SmUsage::Inputs, in_len, al::CODE_INVALID_INPUT_CONFIG),
            ] {
                if len == 0 {
                    continue;
                }
                let declared = sii.sync_managers.iter().find(|s| s.usage == usage);
                let actual = self.sm_of(usage).map(|(_, sm)| sm);
                let good = match (declared, actual) {
                    (Some(d), Some(a)) => a.enabled && a.start == d.start && a.len == len,
                    _ => false,
                };
                if !good {
                    return Err(code);
                }
            }
        }
        Ok(())
    }

    fn al_request(&mut self, control: u16, now_ns: u64) {
        let mut al = self.al;
        let done = al.request(control, |from, to| self.check_transition(from, to));
        self.al = al;
        if let Some((from, to)) = done {
            if to < AlState::PreOp || from == AlState::Init {
                self.mailbox_pending = false;
            }
            if to == AlState::Op {
                // The watchdog starts anew: back in OP after it expired, the time since
                // the last output write is not held against the subdevice again.
                self.last_output_ns = Some(now_ns);
                self.memory[usize::from(REG_WD_STATUS)] = 1;
            }
            self.app.transition(from, to);
        }
    }

    /// The SyncManager watchdog time: divider (0x0400, units of 40 ns, plus 2) times the
    /// SM watchdog (0x0420); `None` when 0x0420 is 0 or the output SyncManager does not
    /// enable its watchdog (control bit 6).
    pub fn watchdog_ns(&self) -> Option<u64> {
        let (_, sm) = self.sm_of(SmUsage::Outputs)?;
        let count = u64::from(self.u16_at(0x0420));
        if sm.control & 0x40 == 0 || count == 0 {
            return None;
        }
        Some((u64::from(self.u16_at(0x0400)) + 2) * 40 * count)
    }

    /// One loop turn: the process-data watchdog (in OP, no output write for the watchdog
    /// time since the last one or since entering OP drops the subdevice to SAFE-OP with
    /// the error indicator and AL status code 0x001B, and tells the application), then
    /// the application's own tick. The MainDevice brings it back with an acknowledge
    /// (see [`Al::request`]) and a request for OP.
    pub fn tick(&mut self, now_ns: u64) {
        if let Some(code) = self.pending_failure.take()
            && self.al.state() == AlState::Op
        {
            // An error of its own: out of OP with the code, and, as after the watchdog,
            // the drive stops itself (its outputs are no longer taken).
            self.al.drop_to(AlState::SafeOp, code);
            self.app.watchdog_expired(now_ns);
        }
        let expired = match (self.al.state(), self.last_output_ns, self.watchdog_ns()) {
            (AlState::Op, Some(last), Some(limit)) => now_ns.saturating_sub(last) > limit,
            _ => false,
        };
        if expired {
            self.watchdog_trips = self.watchdog_trips.saturating_add(1);
            self.al.drop_to(AlState::SafeOp, al::CODE_SM_WATCHDOG);
            self.app.watchdog_expired(now_ns);
            self.memory[usize::from(REG_WD_STATUS)] = 0;
        }
        self.app.tick(now_ns);
    }

    /// How many times the process-data watchdog has expired.
    /// An error of the subdevice's own while in OP (a drive's internal error that takes
    /// its EtherCAT state machine down): at the next tick it drops to SAFE-OP with the
    /// error flag and AL status `code`, and its application stops as after the watchdog.
    /// Nothing happens out of OP.
    pub fn fail_out_of_op(&mut self, code: u16) {
        self.pending_failure = Some(code);
    }

    /// Process-data watchdog expiries so far.
    pub fn watchdog_trips(&self) -> u32 {
        self.watchdog_trips
    }

    /// The time of the last output write, or of entering SAFE-OP (where the watchdog
    /// starts counting).
    pub fn last_output_ns(&self) -> Option<u64> {
        self.last_output_ns
    }
}
