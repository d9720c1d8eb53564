//! A line of subdevices as the frame passes through it (ETG.1000.4 §5): each datagram is
//! handled by every subdevice in turn. Addressing: auto-increment (APRD/APWR/APRW/ARMW:
//! each subdevice increments the position field, the one that sees 0 acts), configured
//! address (FPRD/FPWR/FPRW/FRMW: station address 0x0010), broadcast (BRD: the read data of
//! all are ORed; BWR/BRW) and logical (LRD/LWR/LRW through each subdevice's FMMUs).
//! Working counter per subdevice: +1 for a successful read, +1 for a write, and for the
//! read-write commands +1 read, +2 write (3 for both).

use crate::esc::{Ctx, Esc, REG_FMMU0};
use crate::frame::{self, Command, Datagram, FrameError};

/// The emulated line.
#[derive(Debug)]
pub struct Network {
    escs: Vec<Esc>,
}

/// One FMMU's registers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Fmmu {
    logical_start: u32,
    len: u16,
    physical_start: u16,
    read: bool,
    write: bool,
}

fn fmmus(esc: &mut Esc, ctx: Ctx) -> Vec<Fmmu> {
    let mut out = Vec::new();
    for index in 0..8u16 {
        let mut raw = [0u8; 16];
        esc.read(REG_FMMU0 + 16 * index, &mut raw, ctx);
        if raw[12] & 1 == 0 {
            continue;
        }
        out.push(Fmmu {
            logical_start: u32::from_le_bytes([raw[0], raw[1], raw[2], raw[3]]),
            len: u16::from_le_bytes([raw[4], raw[5]]),
            physical_start: u16::from_le_bytes([raw[8], raw[9]]),
            read: raw[11] & 1 != 0,
            write: raw[11] & 2 != 0,
        });
    }
    out
}

/// The overlap of a datagram's logical range with an FMMU's: (offset in the datagram,
/// physical address, length).
fn overlap(fmmu: &Fmmu, logical: u32, len: usize) -> Option<(usize, u16, usize)> {
    let d_start = u64::from(logical);
    let d_end = d_start + len as u64;
    let f_start = u64::from(fmmu.logical_start);
    let f_end = f_start + u64::from(fmmu.len);
    let start = d_start.max(f_start);
    let end = d_end.min(f_end);
    (start < end).then(|| {
        let physical = u64::from(fmmu.physical_start) + (start - f_start);
        (
            (start - d_start) as usize,
            physical as u16,
            (end - start) as usize,
        )
    })
}

impl Network {
    /// A line of these subdevices, in order.
    pub fn new(escs: Vec<Esc>) -> Network {
        Network { escs }
    }

    /// The subdevices.
    pub fn escs(&self) -> &[Esc] {
        &self.escs
    }

    /// The subdevices, mutably.
    pub fn escs_mut(&mut self) -> &mut [Esc] {
        &mut self.escs
    }

    /// Passes an Ethernet frame through the line at time `now_ns`, changing it in place
    /// into the frame that comes back.
    pub fn process(&mut self, frame: &mut [u8], now_ns: u64) -> Result<(), FrameError> {
        frame::for_each_datagram(frame, |datagram| self.datagram(datagram, now_ns))
    }

    /// One loop turn for every subdevice (watchdogs).
    pub fn tick(&mut self, now_ns: u64) {
        for esc in &mut self.escs {
            esc.tick(now_ns);
        }
    }

    fn datagram(&mut self, d: &mut Datagram<'_>, now_ns: u64) {
        let count = self.escs.len() as u16;
        for (position, esc) in self.escs.iter_mut().enumerate() {
            let ctx = Ctx {
                now_ns,
                position: position as u16,
                count,
            };
            match d.command {
                Command::Nop => {}
                Command::Aprd | Command::Apwr | Command::Aprw | Command::Armw => {
                    let addressed = d.adp == 0;
                    d.adp = d.adp.wrapping_add(1);
                    physical(esc, d, addressed, ctx);
                }
                Command::Fprd | Command::Fpwr | Command::Fprw | Command::Frmw => {
                    let addressed = esc.station_address() == d.adp;
                    physical(esc, d, addressed, ctx);
                }
                Command::Brd | Command::Bwr | Command::Brw => broadcast(esc, d, ctx),
                Command::Lrd | Command::Lwr | Command::Lrw => logical(esc, d, ctx),
            }
        }
    }
}

fn physical(esc: &mut Esc, d: &mut Datagram<'_>, addressed: bool, ctx: Ctx) {
    match d.command {
        Command::Aprd | Command::Fprd if addressed => {
            esc.read(d.ado, d.data, ctx);
            d.wkc = d.wkc.wrapping_add(1);
        }
        Command::Apwr | Command::Fpwr if addressed => {
            esc.write(d.ado, d.data, ctx);
            d.wkc = d.wkc.wrapping_add(1);
        }
        Command::Aprw | Command::Fprw if addressed => {
            let incoming = d.data.to_vec();
            esc.read(d.ado, d.data, ctx);
            esc.write(d.ado, &incoming, ctx);
            d.wkc = d.wkc.wrapping_add(3);
        }
        Command::Armw | Command::Frmw => {
            if addressed {
                esc.read(d.ado, d.data, ctx);
            } else {
                esc.write(d.ado, d.data, ctx);
            }
            d.wkc = d.wkc.wrapping_add(1);
        }
        _ => {}
    }
}

fn broadcast(esc: &mut Esc, d: &mut Datagram<'_>, ctx: Ctx) {
    let mut read = vec![0u8; d.data.len()];
    match d.command {
        Command::Brd => {
            esc.read(d.ado, &mut read, ctx);
            d.data.iter_mut().zip(&read).for_each(|(a, b)| *a |= b);
            d.wkc = d.wkc.wrapping_add(1);
        }
        Command::Bwr => {
            esc.write(d.ado, d.data, ctx);
            d.wkc = d.wkc.wrapping_add(1);
        }
        _ => {
            esc.read(d.ado, &mut read, ctx);
            esc.write(d.ado, d.data, ctx);
            d.data.iter_mut().zip(&read).for_each(|(a, b)| *a |= b);
            d.wkc = d.wkc.wrapping_add(3);
        }
    }
}

fn logical(esc: &mut Esc, d: &mut Datagram<'_>, ctx: Ctx) {
    if esc.al().state() < crate::al::AlState::SafeOp {
        return;
    }
    let logical = d.logical_address();
    let mut did_read = false;
    let mut did_write = false;
    let fmmus = fmmus(esc, ctx);
    if matches!(d.command, Command::Lwr | Command::Lrw) {
        for fmmu in fmmus.iter().filter(|f| f.write) {
            if let Some((offset, physical, len)) = overlap(fmmu, logical, d.data.len()) {
                esc.write(physical, &d.data[offset..offset + len], ctx);
                did_write = true;
            }
        }
    }
    if matches!(d.command, Command::Lrd | Command::Lrw) {
        for fmmu in fmmus.iter().filter(|f| f.read) {
            if let Some((offset, physical, len)) = overlap(fmmu, logical, d.data.len()) {
                esc.read(physical, &mut d.data[offset..offset + len], ctx);
                did_read = true;
            }
        }
    }
    let increment = match d.command {
        Command::Lrw => u16::from(did_read) + 2 * u16::from(did_write),
        _ => u16::from(did_read || did_write),
    };
    d.wkc = d.wkc.wrapping_add(increment);
}
