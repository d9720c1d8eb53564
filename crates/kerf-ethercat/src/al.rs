//! The EtherCAT state machine of a subdevice (ETG.1000.6 AL): its states and status codes
//! in words, the status read, and the control register's acknowledge.

use std::time::Duration;

use ethercrab::{MainDevice, RegisterAddress};

use crate::pump::Pump;

/// The AL control register (ETG.1000.4): the state requested, bit 4 acknowledges an error.
pub(crate) const AL_CONTROL_REGISTER: u16 = 0x0120;
/// AL control's error acknowledge bit.
pub(crate) const AL_ACKNOWLEDGE: u16 = 0x0010;
/// The AL state SAFE-OP (the low four bits of the AL status).
pub const SAFE_OP: u8 = 4;
/// The AL state OP.
pub const OP: u8 = 8;
/// The AL status's error flag (bit 4).
pub const ERROR_FLAG: u8 = 0x10;
/// The AL status's state bits.
pub const STATE_BITS: u8 = 0x0F;

/// An AL state (the low four bits of the AL status) by its name: "SAFE-OP".
pub fn state_name(al_status: u8) -> &'static str {
    match al_status & STATE_BITS {
        1 => "INIT",
        2 => "PRE-OP",
        3 => "BOOT",
        SAFE_OP => "SAFE-OP",
        OP => "OP",
        _ => "an unknown state",
    }
}

/// The state of a subdevice in words, "+ error" when its error flag is set.
pub fn state_text(al_status: u8) -> String {
    let state = state_name(al_status);
    if al_status & ERROR_FLAG != 0 {
        format!("{state} + error")
    } else {
        state.to_owned()
    }
}

/// An AL status code (register 0x0134) in words, as ETG.1000.6 names it:
/// "0x001B (sync manager watchdog)".
pub fn al_code_text(code: u16) -> String {
    use ethercrab::EtherCrabWireRead;
    match ethercrab::AlStatusCode::unpack_from_slice(&code.to_le_bytes()) {
        Ok(ethercrab::AlStatusCode::Unknown(_)) | Err(_) => format!("{code:#06x}"),
        Ok(c) => format!("{code:#06x} ({})", words_of(&c)),
    }
}

/// ethercrab's name of a code, in lower case words ("SyncManagerWatchdog" becomes "sync
/// manager watchdog").
fn words_of(code: &ethercrab::AlStatusCode) -> String {
    let name = format!("{code:?}");
    let mut words = String::new();
    for (i, c) in name.chars().enumerate() {
        if c.is_ascii_uppercase() && i > 0 {
            words.push(' ');
        }
        words.push(c.to_ascii_lowercase());
    }
    words
}

/// The AL status (state and error flag) and the AL status code of the subdevice at the
/// configured station `address`, read outside any group; `None` without an answer.
/// `tries` attempts of both reads, each bounded by `timeout`: right after a refused
/// transition the first may find the answer to the transition's last frame (dropped in
/// flight at its timeout) in its place.
pub(crate) fn read_status(
    maindevice: &MainDevice<'static>,
    pump: &mut Pump,
    address: u16,
    timeout: Duration,
    tries: u32,
) -> Option<(u8, u16)> {
    (0..tries).find_map(|_| {
        pump.block_on(
            async {
                let state = ethercrab::Command::fprd(address, RegisterAddress::AlStatus.into())
                    .receive::<u8>(maindevice)
                    .await?;
                let code = ethercrab::Command::fprd(address, RegisterAddress::AlStatusCode.into())
                    .receive::<u16>(maindevice)
                    .await?;
                Ok::<_, ethercrab::error::Error>((state, code))
            },
            timeout,
        )
        .ok()?
        .ok()
    })
}
