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

    /// Trips a fault with `error_code` in the subdevice at `position`; false where there
    /// is none or it has no faults (an I/O subdevice).
    pub fn inject_fault(&mut self, position: usize, error_code: u16) -> bool {
        self.escs
            .get_mut(position)
            .is_some_and(|esc| esc.app_mut().inject_fault(error_code))
    }

    /// Jams (`stalled`) or frees the motor of the drive at `position`; false where there
    /// is none or it has no motor (an I/O subdevice).
    pub fn set_stalled(&mut self, position: usize, stalled: bool) -> bool {
        self.escs
            .get_mut(position)
            .is_some_and(|esc| esc.app_mut().set_stalled(stalled))
    }

    /// The subdevice at `position` leaves OP by an error of its own with AL status `code`
    /// ([`crate::esc::Esc::fail_out_of_op`]); false where there is none.
    pub fn fail_out_of_op(&mut self, position: usize, code: u16) -> bool {
        self.escs
            .get_mut(position)
            .map(|esc| esc.fail_out_of_op(code))
            .is_some()
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::{build_frame, parse_datagrams};
    use crate::{NetworkSpec, build};

    fn line(drives: u16, io: u16) -> Network {
        build(&NetworkSpec {
            drives,
            io,
            ..NetworkSpec::default()
        })
        .0
    }

    fn run(
        network: &mut Network,
        datagrams: &[frame::DatagramSpec<'_>],
    ) -> Vec<frame::ParsedDatagram> {
        let mut frame = build_frame(datagrams);
        network.process(&mut frame, 1_000_000).unwrap();
        parse_datagrams(&frame).unwrap()
    }

    #[test]
    fn brd_of_the_type_register_counts_every_subdevice() {
        let mut network = line(3, 1);
        let out = run(&mut network, &[(Command::Brd, 0, 0, 0x0000, &[0], 0)]);
        // Each subdevice ORs its type byte (0x11) and adds 1.
        assert_eq!(out[0].3, vec![0x11]);
        assert_eq!(out[0].4, 4);
        assert_eq!(out[0].1, 0, "broadcast leaves the address alone");
    }

    #[test]
    fn auto_increment_addresses_the_subdevice_at_that_position() {
        let mut network = line(3, 0);
        // APWR to position 2 (ADP = −2): station address 0x1002.
        let out = run(
            &mut network,
            &[(
                Command::Apwr,
                0,
                0u16.wrapping_sub(2),
                0x0010,
                &[0x02, 0x10],
                0,
            )],
        );
        assert_eq!(out[0].4, 1);
        assert_eq!(out[0].1, 1, "three increments of −2 give 1");
        let addresses: Vec<u16> = network.escs().iter().map(|e| e.station_address()).collect();
        assert_eq!(addresses, vec![0, 0, 0x1002]);
        // FPRD of the AL status at 0x1002 answers INIT (1), WKC 1; an absent address 0.
        let out = run(
            &mut network,
            &[
                (Command::Fprd, 1, 0x1002, 0x0130, &[0, 0], 0),
                (Command::Fprd, 2, 0x1003, 0x0130, &[0, 0], 0),
            ],
        );
        assert_eq!((out[0].3.clone(), out[0].4), (vec![1, 0], 1));
        assert_eq!(out[1].4, 0);
    }

    #[test]
    fn read_write_commands_count_three_and_return_the_old_value() {
        let mut network = line(2, 0);
        run(
            &mut network,
            &[(Command::Apwr, 0, 0, 0x0010, &[0x01, 0x10], 0)],
        );
        let out = run(
            &mut network,
            &[(Command::Fprw, 0, 0x1001, 0x0012, &[0x34, 0x12], 0)],
        );
        assert_eq!((out[0].3.clone(), out[0].4), (vec![0, 0], 3));
        let out = run(
            &mut network,
            &[(Command::Fprd, 0, 0x1001, 0x0012, &[0, 0], 0)],
        );
        assert_eq!(out[0].3, vec![0x34, 0x12]);
    }

    #[test]
    fn frmw_reads_at_the_addressed_one_and_writes_the_others() {
        let mut network = line(3, 0);
        for (position, address) in [(0u16, 0x1000u16), (1, 0x1001), (2, 0x1002)] {
            let data = address.to_le_bytes();
            run(
                &mut network,
                &[(
                    Command::Apwr,
                    0,
                    0u16.wrapping_sub(position),
                    0x0010,
                    &data,
                    0,
                )],
            );
        }
        // The first subdevice's alias is read and written to the others.
        run(
            &mut network,
            &[(Command::Fpwr, 0, 0x1000, 0x0012, &[0xCD, 0xAB], 0)],
        );
        let out = run(
            &mut network,
            &[(Command::Frmw, 0, 0x1000, 0x0012, &[0, 0], 0)],
        );
        assert_eq!((out[0].3.clone(), out[0].4), (vec![0xCD, 0xAB], 3));
        let out = run(&mut network, &[(Command::Brd, 0, 0, 0x0012, &[0, 0], 0)]);
        assert_eq!(out[0].3, vec![0xCD, 0xAB]);
    }

    #[test]
    fn an_al_request_past_pre_op_is_refused_with_0x0011_and_init_to_pre_op_needs_the_mailbox() {
        let mut network = line(1, 0);
        run(&mut network, &[(Command::Bwr, 0, 0, 0x0120, &[0x08, 0], 0)]);
        let out = run(&mut network, &[(Command::Brd, 0, 0, 0x0130, &[0; 6], 0)]);
        assert_eq!(out[0].3, vec![0x11, 0, 0, 0, 0x11, 0x00]);
        // Acknowledge and ask for PRE-OP without mailbox SyncManagers: 0x0016.
        run(&mut network, &[(Command::Bwr, 0, 0, 0x0120, &[0x12, 0], 0)]);
        let out = run(&mut network, &[(Command::Brd, 0, 0, 0x0130, &[0; 6], 0)]);
        assert_eq!(out[0].3, vec![0x11, 0, 0, 0, 0x16, 0x00]);
        // Configure SM0/SM1 as the EEPROM says (0x1000/128 control 0x26, 0x1080/128 0x22).
        let sm = [
            0x00, 0x10, 128, 0, 0x26, 0, 1, 0, 0x80, 0x10, 128, 0, 0x22, 0, 1, 0,
        ];
        run(&mut network, &[(Command::Bwr, 0, 0, 0x0800, &sm, 0)]);
        run(&mut network, &[(Command::Bwr, 0, 0, 0x0120, &[0x12, 0], 0)]);
        let out = run(&mut network, &[(Command::Brd, 0, 0, 0x0130, &[0; 6], 0)]);
        assert_eq!(out[0].3, vec![0x02, 0, 0, 0, 0, 0]);
    }

    #[test]
    fn sii_reads_return_eight_bytes_of_the_identity() {
        let mut network = line(1, 0);
        // Read request for word 0x0008 (ETG.1000.4 SII control: read bit in byte 1).
        run(
            &mut network,
            &[(
                Command::Apwr,
                0,
                0,
                0x0502,
                &[0x00, 0x01, 0x08, 0x00, 0, 0],
                0,
            )],
        );
        let out = run(&mut network, &[(Command::Aprd, 0, 0, 0x0502, &[0; 14], 0)]);
        assert_eq!(out[0].3[1] & 0x80, 0, "not busy");
        // Vendor 0x00004B52, product 0x00000402.
        assert_eq!(&out[0].3[6..14], &[0x52, 0x4B, 0, 0, 0x02, 0x04, 0, 0]);
    }

    #[test]
    fn logical_commands_reach_only_subdevices_in_safe_op_or_op() {
        let mut network = line(0, 2);
        // Configure each I/O: SM0 outputs 0x0F00/1, SM1 inputs 0x1000/1; FMMU0 writes
        // logical 0x10+n to SM0, FMMU1 reads logical 0x20+n from SM1.
        for n in 0..2u16 {
            let adp = 0u16.wrapping_sub(n);
            let sm = [
                0x00, 0x0F, 1, 0, 0x44, 0, 1, 0, 0x00, 0x10, 1, 0, 0x00, 0, 1, 0,
            ];
            let lo = 0x10 + n as u8;
            let li = 0x20 + n as u8;
            let fmmu = [
                lo, 0, 0, 0, 1, 0, 0, 7, 0x00, 0x0F, 0, 2, 1, 0, 0, 0, //
                li, 0, 0, 0, 1, 0, 0, 7, 0x00, 0x10, 0, 1, 1, 0, 0, 0,
            ];
            run(
                &mut network,
                &[
                    (Command::Apwr, 0, adp, 0x0800, &sm, 0),
                    (Command::Apwr, 0, adp, 0x0600, &fmmu, 0),
                ],
            );
        }
        let out = run(&mut network, &[(Command::Lrw, 0, 0x10, 0, &[0; 32], 0)]);
        assert_eq!(
            out[0].4, 0,
            "PRE-OP is not reached yet: INIT answers no logical command"
        );
        for control in [0x02u8, 0x04, 0x08] {
            run(
                &mut network,
                &[(Command::Bwr, 0, 0, 0x0120, &[control, 0], 0)],
            );
        }
        let out = run(&mut network, &[(Command::Brd, 0, 0, 0x0130, &[0; 2], 0)]);
        assert_eq!(out[0].3, vec![0x08, 0]);
        let out = run(&mut network, &[(Command::Lrw, 0, 0x10, 0, &[0; 32], 0)]);
        assert_eq!(out[0].4, 6, "2 subdevices × (1 read + 2 write)");
        let out = run(&mut network, &[(Command::Lwr, 0, 0x10, 0, &[0; 2], 0)]);
        assert_eq!(out[0].4, 2);
        let out = run(&mut network, &[(Command::Lrd, 0, 0x30, 0, &[0; 2], 0)]);
        assert_eq!(out[0].4, 0, "nothing mapped there");
    }

    fn run_at(
        network: &mut Network,
        now_ns: u64,
        datagrams: &[frame::DatagramSpec<'_>],
    ) -> Vec<frame::ParsedDatagram> {
        let mut frame = build_frame(datagrams);
        network.process(&mut frame, now_ns).unwrap();
        parse_datagrams(&frame).unwrap()
    }

    #[test]
    fn the_watchdog_drops_op_to_safe_op_100_ms_after_the_last_output_write() {
        let mut network = line(1, 0);
        // SM0/SM1 mailboxes, SM2 outputs 0x1100/6 control 0x64 (watchdog on), SM3 inputs
        // 0x1180/20; FMMU0 writes logical 0..6 to 0x1100.
        let sm = [
            0x00, 0x10, 128, 0, 0x26, 0, 1, 0, 0x80, 0x10, 128, 0, 0x22, 0, 1, 0, //
            0x00, 0x11, 6, 0, 0x64, 0, 1, 0, 0x80, 0x11, 20, 0, 0x20, 0, 1, 0,
        ];
        let fmmu = [0, 0, 0, 0, 6, 0, 0, 7, 0x00, 0x11, 0, 2, 1, 0, 0, 0];
        run_at(
            &mut network,
            0,
            &[
                (Command::Bwr, 0, 0, 0x0800, &sm, 0),
                (Command::Bwr, 0, 0, 0x0600, &fmmu, 0),
            ],
        );
        for control in [0x02u8, 0x04, 0x08] {
            run_at(
                &mut network,
                0,
                &[(Command::Bwr, 0, 0, 0x0120, &[control, 0], 0)],
            );
        }
        let out = run_at(&mut network, 0, &[(Command::Brd, 0, 0, 0x0130, &[0; 2], 0)]);
        assert_eq!(out[0].3, vec![0x08, 0]);
        let write_ns = 1_000_000;
        let out = run_at(
            &mut network,
            write_ns,
            &[(Command::Lwr, 0, 0, 0, &[0; 6], 0)],
        );
        assert_eq!(out[0].4, 1);
        // ESC defaults: divider 0x09C2 → (2498 + 2) · 40 ns = 100 µs; 0x0420 = 1000 → 100 ms.
        network.tick(write_ns + 100_000_000);
        assert_eq!(network.escs()[0].al().status_word(), 0x08);
        network.tick(write_ns + 100_000_001);
        assert_eq!(network.escs()[0].al().status_word(), 0x14);
        assert_eq!(network.escs()[0].al().code(), 0x001B);
        assert_eq!(network.escs()[0].watchdog_trips(), 1);
        // Acknowledged (0x14) and asked for OP (0x08), 1 s later, with no output written
        // since: back in OP, and the watchdog counts from there.
        let back_ns = write_ns + 1_000_000_000;
        for control in [0x14u8, 0x08] {
            run_at(
                &mut network,
                back_ns,
                &[(Command::Bwr, 0, 0, 0x0120, &[control, 0], 0)],
            );
        }
        let out = run_at(
            &mut network,
            back_ns,
            &[(Command::Brd, 0, 0, 0x0130, &[0; 6], 0)],
        );
        assert_eq!(out[0].3, vec![0x08, 0, 0, 0, 0, 0]);
        network.tick(back_ns + 100_000_000);
        assert_eq!(network.escs()[0].al().status_word(), 0x08);
        network.tick(back_ns + 100_000_001);
        assert_eq!(network.escs()[0].al().status_word(), 0x14);
        assert_eq!(network.escs()[0].watchdog_trips(), 2);
        // Acknowledge and OP in one write.
        run_at(
            &mut network,
            back_ns + 200_000_000,
            &[(Command::Bwr, 0, 0, 0x0120, &[0x18, 0], 0)],
        );
        assert_eq!(network.escs()[0].al().status_word(), 0x08);
        assert_eq!(network.escs()[0].al().code(), 0);
    }

    #[test]
    fn the_system_time_gains_the_oscillator_drift_on_the_host_time() {
        let (mut network, _) = build(&NetworkSpec {
            drives: 2,
            dc_drift_ppm: 50.0,
            ..NetworkSpec::default()
        });
        let read = |network: &mut Network, now_ns: u64, position: u16| {
            let out = run_at(
                network,
                now_ns,
                &[(
                    Command::Aprd,
                    0,
                    0u16.wrapping_sub(position),
                    0x0910,
                    &[0; 8],
                    0,
                )],
            );
            u64::from_le_bytes(out[0].3.clone().try_into().unwrap())
        };
        // Over 2 s of host time every clock advances 2 s + 100 µs.
        for position in [0, 1] {
            let t0 = read(&mut network, 1_000_000_000, position);
            let t1 = read(&mut network, 3_000_000_000, position);
            assert_eq!(t1 - t0, 2_000_100_000, "subdevice {position}");
        }
    }

    #[test]
    fn a_written_system_time_shows_its_difference_in_0x092c() {
        let mut network = line(2, 0);
        let at_1 = 0u16.wrapping_sub(1);
        let now_ns = 1_000_000;
        // Subdevice 1's local clock starts 1 ms ahead: 2 ms at now. Delay 500 ns.
        run_at(
            &mut network,
            now_ns,
            &[(Command::Apwr, 0, at_1, 0x0928, &500u32.to_le_bytes(), 0)],
        );
        let difference = |network: &mut Network| {
            let out = run_at(
                network,
                now_ns,
                &[(Command::Aprd, 0, at_1, 0x092C, &[0; 4], 0)],
            );
            u32::from_le_bytes(out[0].3.clone().try_into().unwrap())
        };
        assert_eq!(difference(&mut network), 0, "nothing received yet");
        // Received 2 ms + 1.3 µs, + 0.5 µs delay: 1.8 µs ahead of the own copy, which is
        // smaller (bit 31). The loop corrects 1 µs of it.
        let received = 2_001_300u64.to_le_bytes();
        run_at(
            &mut network,
            now_ns,
            &[(Command::Apwr, 0, at_1, 0x0910, &received, 0)],
        );
        assert_eq!(difference(&mut network), 0x8000_0000 | 1_800);
        // Now the own copy is 2.001 ms; received 2 ms + 0.5 µs delay is 500 ns behind.
        let received = 2_000_000u64.to_le_bytes();
        run_at(
            &mut network,
            now_ns,
            &[(Command::Apwr, 0, at_1, 0x0910, &received, 0)],
        );
        assert_eq!(difference(&mut network), 500);
        // A 32-bit write compares the lower half: own 2.0005 ms, received 2.0005 ms + 0.5
        // µs delay → 500 ns ahead.
        let received = 2_000_500u32.to_le_bytes();
        run_at(
            &mut network,
            now_ns,
            &[(Command::Apwr, 0, at_1, 0x0910, &received, 0)],
        );
        assert_eq!(difference(&mut network), 0x8000_0000 | 500);
        // The register is the ESC's: a write from the MainDevice does not change it.
        run_at(
            &mut network,
            now_ns,
            &[(Command::Apwr, 0, at_1, 0x092C, &[0; 4], 0)],
        );
        assert_eq!(difference(&mut network), 0x8000_0000 | 500);
        // Subdevice 0 received nothing.
        let out = run_at(
            &mut network,
            now_ns,
            &[(Command::Aprd, 0, 0, 0x092C, &[0; 4], 0)],
        );
        assert_eq!(out[0].3, vec![0; 4]);
    }

    #[test]
    fn a_refused_safe_op_stays_in_pre_op_with_the_error_and_its_code() {
        let (mut network, _) = build(&NetworkSpec {
            io: 2,
            refuse_safe_op: vec![crate::SafeOpRefusal {
                position: 1,
                al_status_code: 0x0035,
            }],
            ..NetworkSpec::default()
        });
        // Subdevice 0's SyncManagers set as its EEPROM says; subdevice 1's too, but it
        // refuses.
        let sm = [
            0x00, 0x0F, 1, 0, 0x44, 0, 1, 0, 0x00, 0x10, 1, 0, 0x00, 0, 1, 0,
        ];
        run(&mut network, &[(Command::Bwr, 0, 0, 0x0800, &sm, 0)]);
        for control in [0x02u8, 0x04] {
            run(
                &mut network,
                &[(Command::Bwr, 0, 0, 0x0120, &[control, 0], 0)],
            );
        }
        let status = |network: &mut Network, position: u16| {
            let out = run(
                network,
                &[(
                    Command::Aprd,
                    0,
                    0u16.wrapping_sub(position),
                    0x0130,
                    &[0; 6],
                    0,
                )],
            );
            out[0].3.clone()
        };
        assert_eq!(status(&mut network, 0), vec![0x04, 0, 0, 0, 0, 0]);
        // PRE-OP (2) with the error indicator (0x10), code 0x0035.
        assert_eq!(status(&mut network, 1), vec![0x12, 0, 0, 0, 0x35, 0]);
        // Asked again after an acknowledge, it refuses again.
        run(
            &mut network,
            &[(
                Command::Apwr,
                0,
                0u16.wrapping_sub(1),
                0x0120,
                &[0x14, 0],
                0,
            )],
        );
        assert_eq!(status(&mut network, 1), vec![0x12, 0, 0, 0, 0x35, 0]);
    }
}
