//! The EtherCAT frame (ETG.1000.4): the Ethernet header with EtherType 0x88A4, the
//! 2-byte EtherCAT header and the chain of datagrams (command, index, address, length,
//! interrupt, data, working counter). Parsing works in place on the received bytes, since a
//! subdevice answers by changing a datagram's data, address and working counter and sending
//! the same frame on.

use thiserror::Error;

/// The EtherType of EtherCAT frames.
pub const ETHERTYPE: u16 = 0x88A4;
/// Length of the Ethernet header (destination, source, EtherType), bytes.
pub const ETHERNET_HEADER_LEN: usize = 14;
/// Length of the EtherCAT header, bytes.
pub const ECAT_HEADER_LEN: usize = 2;
/// Length of a datagram header (command to interrupt), bytes.
pub const DATAGRAM_HEADER_LEN: usize = 10;
/// Length of a datagram's working counter, bytes.
pub const WKC_LEN: usize = 2;
/// The EtherCAT header's type for datagrams (the only one a subdevice processes).
pub const TYPE_DATAGRAMS: u8 = 1;

/// Why a frame was not processed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Error)]
pub enum FrameError {
    /// Shorter than its headers.
    #[error("frame of {0} bytes is too short for the Ethernet and EtherCAT headers")]
    TooShort(usize),
    /// Not EtherType 0x88A4.
    #[error("EtherType {0:#06x} is not EtherCAT")]
    NotEthercat(u16),
    /// An EtherCAT header type other than datagrams.
    #[error("EtherCAT header type {0} is not a datagram frame")]
    NotDatagrams(u8),
    /// A datagram runs past the frame's end.
    #[error("datagram at byte {offset} with {len} data bytes runs past the frame's end")]
    Truncated {
        /// Where the datagram starts in the EtherCAT payload.
        offset: usize,
        /// Its data length.
        len: usize,
    },
    /// An unknown command code.
    #[error("unknown datagram command {0:#04x}")]
    UnknownCommand(u8),
}

/// A datagram command (ETG.1000.4 table 12).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Command {
    /// No operation.
    Nop,
    /// Auto-increment physical read.
    Aprd,
    /// Auto-increment physical write.
    Apwr,
    /// Auto-increment physical read-write.
    Aprw,
    /// Configured-address physical read.
    Fprd,
    /// Configured-address physical write.
    Fpwr,
    /// Configured-address physical read-write.
    Fprw,
    /// Broadcast read.
    Brd,
    /// Broadcast write.
    Bwr,
    /// Broadcast read-write.
    Brw,
    /// Logical read.
    Lrd,
    /// Logical write.
    Lwr,
    /// Logical read-write.
    Lrw,
    /// Auto-increment read, multiple write.
    Armw,
    /// Configured-address read, multiple write.
    Frmw,
}

impl Command {
    /// Decodes a command byte.
    pub fn from_code(code: u8) -> Result<Command, FrameError> {
        use Command::*;
        Ok(match code {
            0 => Nop,
            1 => Aprd,
            2 => Apwr,
            3 => Aprw,
            4 => Fprd,
            5 => Fpwr,
            6 => Fprw,
            7 => Brd,
            8 => Bwr,
            9 => Brw,
            10 => Lrd,
            11 => Lwr,
            12 => Lrw,
            13 => Armw,
            14 => Frmw,
            other => return Err(FrameError::UnknownCommand(other)),
        })
    }

    /// The command byte.
    pub fn code(self) -> u8 {
        self as u8
    }
}

/// One datagram, borrowed from the frame: the address words and the working counter are
/// copies that [`for_each_datagram`] writes back after the visitor has run.
#[derive(Debug)]
pub struct Datagram<'a> {
    /// The command.
    pub command: Command,
    /// The index the MainDevice gave it.
    pub index: u8,
    /// Position (auto-increment) or configured address: the address's low word (ADP).
    pub adp: u16,
    /// The register offset: the address's high word (ADO).
    pub ado: u16,
    /// The data bytes.
    pub data: &'a mut [u8],
    /// The working counter.
    pub wkc: u16,
}

impl Datagram<'_> {
    /// The 32-bit logical address of a logical command (ADP low, ADO high word).
    pub fn logical_address(&self) -> u32 {
        u32::from(self.adp) | (u32::from(self.ado) << 16)
    }
}

fn u16_at(bytes: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([bytes[at], bytes[at + 1]])
}

/// Validates an Ethernet frame as EtherCAT and returns the EtherCAT payload's range
/// (datagrams, after the EtherCAT header).
pub fn ecat_payload(frame: &[u8]) -> Result<core::ops::Range<usize>, FrameError> {
    if frame.len() < ETHERNET_HEADER_LEN + ECAT_HEADER_LEN {
        return Err(FrameError::TooShort(frame.len()));
    }
    let ethertype = u16::from_be_bytes([frame[12], frame[13]]);
    if ethertype != ETHERTYPE {
        return Err(FrameError::NotEthercat(ethertype));
    }
    let header = u16_at(frame, ETHERNET_HEADER_LEN);
    let len = usize::from(header & 0x07FF);
    let kind = (header >> 12) as u8;
    if kind != TYPE_DATAGRAMS {
        return Err(FrameError::NotDatagrams(kind));
    }
    let start = ETHERNET_HEADER_LEN + ECAT_HEADER_LEN;
    if start + len > frame.len() {
        return Err(FrameError::Truncated { offset: 0, len });
    }
    Ok(start..start + len)
}

/// Calls `visit` for each datagram of an EtherCAT frame in order, then writes back the
/// datagram's ADP and working counter; sets the locally-administered bit of the source MAC
/// address, as a subdevice does to a frame it has processed (ethercrab tells its own
/// frames from the returning ones by it). The whole chain is checked before any visit, so a
/// malformed frame is left untouched.
pub fn for_each_datagram(
    frame: &mut [u8],
    mut visit: impl FnMut(&mut Datagram<'_>),
) -> Result<(), FrameError> {
    let range = ecat_payload(frame)?;
    // First pass: validate the chain.
    let mut offsets = Vec::new();
    let payload = &frame[range.clone()];
    let mut at = 0;
    loop {
        if at + DATAGRAM_HEADER_LEN > payload.len() {
            return Err(FrameError::Truncated { offset: at, len: 0 });
        }
        Command::from_code(payload[at])?;
        let len_word = u16_at(payload, at + 6);
        let len = usize::from(len_word & 0x07FF);
        if at + DATAGRAM_HEADER_LEN + len + WKC_LEN > payload.len() {
            return Err(FrameError::Truncated { offset: at, len });
        }
        offsets.push((at, len));
        at += DATAGRAM_HEADER_LEN + len + WKC_LEN;
        if len_word & 0x8000 == 0 {
            break;
        }
    }
    let payload = &mut frame[range];
    for (at, len) in offsets {
        let (header, rest) = payload[at..].split_at_mut(DATAGRAM_HEADER_LEN);
        let (data, tail) = rest.split_at_mut(len);
        let mut datagram = Datagram {
            command: Command::from_code(header[0])?,
            index: header[1],
            adp: u16_at(header, 2),
            ado: u16_at(header, 4),
            data,
            wkc: u16_at(tail, 0),
        };
        visit(&mut datagram);
        header[2..4].copy_from_slice(&datagram.adp.to_le_bytes());
        tail[0..2].copy_from_slice(&datagram.wkc.to_le_bytes());
    }
    frame[6] |= 0x02;
    Ok(())
}

/// A datagram to build: command, index, ADP, ADO, data, working counter.
pub type DatagramSpec<'a> = (Command, u8, u16, u16, &'a [u8], u16);

/// A parsed datagram: command code, ADP, ADO, data, working counter.
pub type ParsedDatagram = (u8, u16, u16, Vec<u8>, u16);

/// Builds an Ethernet frame with these EtherCAT datagrams (for tests and tools):
/// broadcast destination, source 10:10:10:10:10:10 (ethercrab's MainDevice address).
pub fn build_frame(datagrams: &[DatagramSpec<'_>]) -> Vec<u8> {
    let mut out = vec![0xFF; 6];
    out.extend_from_slice(&[0x10; 6]);
    out.extend_from_slice(&ETHERTYPE.to_be_bytes());
    let body_len: usize = datagrams
        .iter()
        .map(|d| DATAGRAM_HEADER_LEN + d.4.len() + WKC_LEN)
        .sum();
    let header = (body_len as u16 & 0x07FF) | (u16::from(TYPE_DATAGRAMS) << 12);
    out.extend_from_slice(&header.to_le_bytes());
    for (i, (command, index, adp, ado, data, wkc)) in datagrams.iter().enumerate() {
        out.push(command.code());
        out.push(*index);
        out.extend_from_slice(&adp.to_le_bytes());
        out.extend_from_slice(&ado.to_le_bytes());
        let more = if i + 1 < datagrams.len() { 0x8000 } else { 0 };
        out.extend_from_slice(&((data.len() as u16 & 0x07FF) | more).to_le_bytes());
        out.extend_from_slice(&[0, 0]);
        out.extend_from_slice(data);
        out.extend_from_slice(&wkc.to_le_bytes());
    }
    out
}

/// The datagrams of a frame as (command, ADP, ADO, data, working counter), for tests.
pub fn parse_datagrams(frame: &[u8]) -> Result<Vec<ParsedDatagram>, FrameError> {
    let mut copy = frame.to_vec();
    let mut out = Vec::new();
    for_each_datagram(&mut copy, |d| {
        out.push((d.command.code(), d.adp, d.ado, d.data.to_vec(), d.wkc));
    })?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_hand_built_brd_frame_parses_field_by_field() {
        // ETG.1000.4: BRD (7), index 0x2A, ADP 0, ADO 0x0000, 1 data byte, WKC 0.
        let frame: Vec<u8> = [
            &[0xFF; 6][..],
            &[0x10; 6],
            &[0x88, 0xA4],
            &[0x0D, 0x10], // length 13, type 1
            &[0x07, 0x2A, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00],
            &[0x00],
            &[0x00, 0x00],
        ]
        .concat();
        assert_eq!(frame, build_frame(&[(Command::Brd, 0x2A, 0, 0, &[0], 0)]));
        let parsed = parse_datagrams(&frame).unwrap();
        assert_eq!(parsed, vec![(7, 0, 0, vec![0], 0)]);
    }

    #[test]
    fn visiting_writes_back_the_address_and_working_counter_and_marks_the_source() {
        let mut frame = build_frame(&[
            (Command::Aprd, 1, 0xFFFF, 0x0130, &[0, 0], 0),
            (Command::Fprd, 2, 0x1000, 0x0130, &[0], 0),
        ]);
        for_each_datagram(&mut frame, |d| {
            d.adp = d.adp.wrapping_add(1);
            d.wkc += 1;
        })
        .unwrap();
        let parsed = parse_datagrams(&frame).unwrap();
        assert_eq!(parsed[0], (1, 0x0000, 0x0130, vec![0, 0], 1));
        assert_eq!(parsed[1], (4, 0x1001, 0x0130, vec![0], 1));
        assert_eq!(frame[6], 0x12);
    }

    #[test]
    fn malformed_frames_are_refused_untouched() {
        let mut frame = build_frame(&[(Command::Brd, 0, 0, 0, &[0; 4], 0)]);
        frame.truncate(frame.len() - 3);
        let before = frame.clone();
        assert!(matches!(
            for_each_datagram(&mut frame, |_| {}),
            Err(FrameError::Truncated { .. })
        ));
        assert_eq!(frame, before);
        let mut ip = build_frame(&[]);
        ip[12] = 0x08;
        ip[13] = 0x00;
        assert_eq!(
            for_each_datagram(&mut ip, |_| {}),
            Err(FrameError::NotEthercat(0x0800))
        );
        let mut bad = build_frame(&[(Command::Brd, 0, 0, 0, &[0], 0)]);
        bad[16] = 0x42;
        assert_eq!(
            for_each_datagram(&mut bad, |_| {}),
            Err(FrameError::UnknownCommand(0x42))
        );
    }
}
