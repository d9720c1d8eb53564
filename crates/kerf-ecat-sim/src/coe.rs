//! The mailbox (ETG.1000.4 §5.6: 6-byte header with length, address, type and counter)
//! and CoE SDO services on it (ETG.1000.6 §5.6.2, CiA 301): upload and download,
//! expedited (up to 4 bytes in the initiate frame), normal (size then data, in one
//! mailbox) and segmented, and the abort transfer with its code.
//!
//! Segmented upload, for a value longer than a mailbox holds: the initiate response gives
//! the size only, then each upload-segment request (toggle bit alternating from 0) gets up
//! to mailbox − 9 bytes, the last one flagged. Segmented download: the initiate request
//! gives the complete size and as many bytes as its mailbox holds (the mailbox length
//! says how many); the subdevice checks at once that the entry exists, may be written and
//! has that size (else it aborts), answers the initiate, then each download-segment
//! request (toggle from 0; its data length is the mailbox length − 3, or 7 − the
//! segment's unused-byte count in a minimal 10-byte mailbox) is answered with its toggle,
//! and the value is written when the last segment completes it. A wrong toggle aborts
//! with 0x05030000, more or fewer bytes than announced with 0x06070010, a segment with no
//! transfer under way with 0x05040001; any other request ends a transfer under way.
use crate::od::{ABORT_COMMAND, ABORT_TYPE_MISMATCH, Od};

/// Mailbox type: CoE.
pub const MAILBOX_TYPE_COE: u8 = 3;
/// CoE service: SDO request.
pub const SERVICE_SDO_REQUEST: u16 = 2;
/// CoE service: SDO response.
pub const SERVICE_SDO_RESPONSE: u16 = 3;
/// Mailbox header length.
pub const MAILBOX_HEADER_LEN: usize = 6;

/// An SDO request decoded from a mailbox.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SdoRequest {
    /// Initiate upload (read).
    Upload {
        /// Index.
        index: u16,
        /// Subindex.
        sub_index: u8,
    },
    /// Initiate download (write), with the whole value.
    Download {
        /// Index.
        index: u16,
        /// Subindex.
        sub_index: u8,
        /// The value.
        value: Vec<u8>,
    },
    /// Initiate a segmented download: the complete size and the first bytes.
    DownloadInitiate {
        /// Index.
        index: u16,
        /// Subindex.
        sub_index: u8,
        /// The complete size, bytes.
        size: usize,
        /// The bytes this mailbox carries (fewer than `size`).
        first: Vec<u8>,
    },
    /// Download segment request.
    DownloadSegment {
        /// The toggle bit (alternates from 0).
        toggle: bool,
        /// The last segment.
        last: bool,
        /// Its bytes.
        data: Vec<u8>,
    },
    /// Upload segment request with its toggle bit.
    UploadSegment {
        /// The toggle bit (alternates from 0).
        toggle: bool,
    },
    /// Something this emulator does not serve (complete access, SDO info…).
    Unsupported {
        /// Index.
        index: u16,
        /// Subindex.
        sub_index: u8,
    },
}

/// Decodes a CoE SDO request from a complete mailbox; `None` when it is not one.
pub fn decode(mailbox: &[u8]) -> Option<(u8, SdoRequest)> {
    if mailbox.len() < MAILBOX_HEADER_LEN + 10 {
        return None;
    }
    let len = usize::from(u16::from_le_bytes([mailbox[0], mailbox[1]]));
    let type_counter = mailbox[5];
    if type_counter & 0x0F != MAILBOX_TYPE_COE || len < 10 {
        return None;
    }
    let coe = u16::from_le_bytes([mailbox[6], mailbox[7]]);
    if coe >> 12 != SERVICE_SDO_REQUEST {
        return None;
    }
    let command = mailbox[8];
    let index = u16::from_le_bytes([mailbox[9], mailbox[10]]);
    let sub_index = mailbox[11];
    let complete_access = command & 0x10 != 0;
    // The bytes the mailbox length covers after the CoE header (2 bytes).
    let end = (MAILBOX_HEADER_LEN + len).min(mailbox.len());
    let request = match command >> 5 {
        2 if !complete_access => SdoRequest::Upload { index, sub_index },
        1 if !complete_access => {
            let data = &mailbox[12..];
            if command & 0x02 != 0 {
                let size = if command & 0x01 != 0 {
                    4 - usize::from((command >> 2) & 0x03)
                } else {
                    4
                };
                SdoRequest::Download {
                    index,
                    sub_index,
                    value: data[..size].to_vec(),
                }
            } else {
                let size = u32::from_le_bytes([data[0], data[1], data[2], data[3]]) as usize;
                let here = mailbox.get(16..end).unwrap_or(&[]);
                if size > here.len() {
                    SdoRequest::DownloadInitiate {
                        index,
                        sub_index,
                        size,
                        first: here.to_vec(),
                    }
                } else {
                    SdoRequest::Download {
                        index,
                        sub_index,
                        value: here[..size].to_vec(),
                    }
                }
            }
        }
        0 => {
            let data_len = if len > 10 {
                len - 3
            } else {
                7 - usize::from((command >> 1) & 0x07)
            };
            let data = mailbox
                .get(9..(9 + data_len).min(mailbox.len()))
                .unwrap_or(&[]);
            SdoRequest::DownloadSegment {
                toggle: command & 0x10 != 0,
                last: command & 0x01 != 0,
                data: data.to_vec(),
            }
        }
        3 => SdoRequest::UploadSegment {
            toggle: command & 0x10 != 0,
        },
        _ => SdoRequest::Unsupported { index, sub_index },
    };
    Some((type_counter & 0x70, request))
}

fn response(counter: u8, command: u8, index: u16, sub_index: u8, tail: &[u8]) -> Vec<u8> {
    let len = 2 + 4 + tail.len().max(4);
    let mut out = Vec::with_capacity(MAILBOX_HEADER_LEN + len);
    out.extend_from_slice(&(len as u16).to_le_bytes());
    out.extend_from_slice(&[0, 0, 0, MAILBOX_TYPE_COE | counter]);
    out.extend_from_slice(&(SERVICE_SDO_RESPONSE << 12).to_le_bytes());
    out.push(command);
    out.extend_from_slice(&index.to_le_bytes());
    out.push(sub_index);
    out.extend_from_slice(tail);
    out.resize(MAILBOX_HEADER_LEN + len, 0);
    out
}

/// The abort transfer response.
pub fn abort(counter: u8, index: u16, sub_index: u8, code: u32) -> Vec<u8> {
    response(counter, 0x80, index, sub_index, &code.to_le_bytes())
}

/// The upload response for `value`: expedited up to 4 bytes, normal above.
pub fn upload_response(counter: u8, index: u16, sub_index: u8, value: &[u8]) -> Vec<u8> {
    if value.len() <= 4 {
        let command = 0x43 | (((4 - value.len()) as u8) << 2);
        let mut data = [0u8; 4];
        data[..value.len()].copy_from_slice(value);
        response(counter, command, index, sub_index, &data)
    } else {
        let mut tail = (value.len() as u32).to_le_bytes().to_vec();
        tail.extend_from_slice(value);
        response(counter, 0x41, index, sub_index, &tail)
    }
}

/// The download response.
pub fn download_response(counter: u8, index: u16, sub_index: u8) -> Vec<u8> {
    response(counter, 0x60, index, sub_index, &[0; 4])
}

/// A segmented upload under way.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Segmented {
    index: u16,
    sub_index: u8,
    data: Vec<u8>,
    sent: usize,
    toggle: bool,
}

/// A segmented download under way.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Receiving {
    index: u16,
    sub_index: u8,
    size: usize,
    data: Vec<u8>,
    toggle: bool,
}

/// The SDO server of one subdevice: serves requests from its dictionary and keeps the
/// state of a segmented upload or download.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SdoServer {
    mailbox_len: usize,
    segmented: Option<Segmented>,
    receiving: Option<Receiving>,
}

/// ETG.1000.6 toggle bit error abort.
pub const ABORT_TOGGLE: u32 = 0x0503_0000;

impl SdoServer {
    /// A server answering in mailboxes of `mailbox_len` bytes.
    pub fn new(mailbox_len: u16) -> SdoServer {
        SdoServer {
            mailbox_len: usize::from(mailbox_len),
            segmented: None,
            receiving: None,
        }
    }

    /// Serves one mailbox request; `on_write` sees each accepted download.
    pub fn serve(
        &mut self,
        od: &mut Od,
        mailbox: &[u8],
        pre_op: bool,
        mut on_write: impl FnMut(u16, u8, &[u8]),
    ) -> Option<Vec<u8>> {
        let (counter, request) = decode(mailbox)?;
        if !matches!(request, SdoRequest::UploadSegment { .. }) {
            self.segmented = None;
        }
        if !matches!(request, SdoRequest::DownloadSegment { .. }) {
            self.receiving = None;
        }
        Some(match request {
            SdoRequest::Upload { index, sub_index } => match od.read(index, sub_index) {
                Ok(value) if 16 + value.len() > self.mailbox_len => {
                    let value = value.to_vec();
                    let size = (value.len() as u32).to_le_bytes();
                    self.segmented = Some(Segmented {
                        index,
                        sub_index,
                        data: value,
                        sent: 0,
                        toggle: false,
                    });
                    response(counter, 0x41, index, sub_index, &size)
                }
                Ok(value) => upload_response(counter, index, sub_index, value),
                Err(code) => abort(counter, index, sub_index, code),
            },
            SdoRequest::UploadSegment { toggle } => self.segment(counter, toggle),
            SdoRequest::Download {
                index,
                sub_index,
                value,
            } => match od.write(index, sub_index, &value, pre_op) {
                Ok(()) => {
                    on_write(index, sub_index, &value);
                    download_response(counter, index, sub_index)
                }
                Err(code) => abort(counter, index, sub_index, code),
            },
            SdoRequest::DownloadInitiate {
                index,
                sub_index,
                size,
                first,
            } => match od.check_write(index, sub_index, size, pre_op) {
                Ok(()) => {
                    self.receiving = Some(Receiving {
                        index,
                        sub_index,
                        size,
                        data: first,
                        toggle: false,
                    });
                    download_response(counter, index, sub_index)
                }
                Err(code) => abort(counter, index, sub_index, code),
            },
            SdoRequest::DownloadSegment { toggle, last, data } => {
                self.download_segment(od, counter, toggle, last, &data, pre_op, on_write)
            }
            SdoRequest::Unsupported { index, sub_index } => {
                abort(counter, index, sub_index, ABORT_COMMAND)
            }
        })
    }

    /// One download segment: its response, or the abort that ends the transfer.
    #[allow(clippy::too_many_arguments)]
    fn download_segment(
        &mut self,
        od: &mut Od,
        counter: u8,
        toggle: bool,
        last: bool,
        data: &[u8],
        pre_op: bool,
        mut on_write: impl FnMut(u16, u8, &[u8]),
    ) -> Vec<u8> {
        let Some(mut download) = self.receiving.take() else {
            return abort(counter, 0, 0, ABORT_COMMAND);
        };
        let (index, sub_index) = (download.index, download.sub_index);
        if toggle != download.toggle {
            return abort(counter, index, sub_index, ABORT_TOGGLE);
        }
        download.data.extend_from_slice(data);
        let complete = download.data.len() == download.size;
        if download.data.len() > download.size || (last && !complete) {
            return abort(counter, index, sub_index, ABORT_TYPE_MISMATCH);
        }
        if last {
            if let Err(code) = od.write(index, sub_index, &download.data, pre_op) {
                return abort(counter, index, sub_index, code);
            }
            on_write(index, sub_index, &download.data);
        } else {
            download.toggle = !download.toggle;
            self.receiving = Some(download);
        }
        // Download segment response: command specifier 1, the toggle echoed.
        let mut out = Vec::with_capacity(MAILBOX_HEADER_LEN + 10);
        out.extend_from_slice(&10u16.to_le_bytes());
        out.extend_from_slice(&[0, 0, 0, MAILBOX_TYPE_COE | counter]);
        out.extend_from_slice(&(SERVICE_SDO_RESPONSE << 12).to_le_bytes());
        out.push(0x20 | (u8::from(toggle) << 4));
        out.resize(MAILBOX_HEADER_LEN + 10, 0);
        out
    }

    fn segment(&mut self, counter: u8, toggle: bool) -> Vec<u8> {
        let Some(mut upload) = self.segmented.take() else {
            return abort(counter, 0, 0, ABORT_COMMAND);
        };
        if toggle != upload.toggle {
            return abort(counter, upload.index, upload.sub_index, ABORT_TOGGLE);
        }
        let room = self
            .mailbox_len
            .saturating_sub(MAILBOX_HEADER_LEN + 3)
            .max(1);
        let chunk = &upload.data[upload.sent..(upload.sent + room).min(upload.data.len())];
        let last = upload.sent + chunk.len() == upload.data.len();
        let unused = 7usize.saturating_sub(chunk.len()) as u8;
        let command = (u8::from(toggle) << 4) | (unused << 1) | u8::from(last);
        let len = 3 + chunk.len().max(7);
        let mut out = Vec::with_capacity(MAILBOX_HEADER_LEN + len);
        out.extend_from_slice(&(len as u16).to_le_bytes());
        out.extend_from_slice(&[0, 0, 0, MAILBOX_TYPE_COE | counter]);
        out.extend_from_slice(&(SERVICE_SDO_RESPONSE << 12).to_le_bytes());
        out.push(command);
        out.extend_from_slice(chunk);
        out.resize(MAILBOX_HEADER_LEN + len, 0);
        upload.sent += chunk.len();
        upload.toggle = !upload.toggle;
        if !last {
            self.segmented = Some(upload);
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::od::Access;

    /// A mailbox as ETG.1000.6 lays it out: upload request of 0x1018:01, counter 1.
    fn upload_request() -> Vec<u8> {
        let mut m = vec![0x0A, 0x00, 0x00, 0x00, 0x00, 0x13, 0x00, 0x20];
        m.extend_from_slice(&[0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0]);
        m.resize(128, 0);
        m
    }

    #[test]
    fn an_expedited_upload_answers_with_size_and_value() {
        let mut od = Od::default();
        od.insert(0x1018, 1, &0x0000_4B52u32.to_le_bytes(), Access::ReadOnly);
        let out = SdoServer::new(128)
            .serve(&mut od, &upload_request(), true, |_, _, _| {})
            .unwrap();
        assert_eq!(
            out,
            vec![
                0x0A, 0x00, 0x00, 0x00, 0x00, 0x13, 0x00, 0x30, // headers, SDO response
                0x43, 0x18, 0x10, 0x01, 0x52, 0x4B, 0x00, 0x00 // 4 bytes expedited
            ]
        );
    }

    #[test]
    fn a_missing_object_aborts_with_its_code() {
        let mut od = Od::default();
        let out = SdoServer::new(128)
            .serve(&mut od, &upload_request(), true, |_, _, _| {})
            .unwrap();
        assert_eq!(
            &out[8..16],
            &[0x80, 0x18, 0x10, 0x01, 0x00, 0x00, 0x02, 0x06]
        );
    }

    #[test]
    fn an_expedited_download_of_one_byte_writes_it() {
        let mut od = Od::default();
        od.insert(0x6060, 0, &[8], Access::ReadWrite);
        // Command 0x2F: download, expedited, size indicated, 3 unused bytes.
        let mut m = vec![0x0A, 0x00, 0x00, 0x00, 0x00, 0x23, 0x00, 0x20];
        m.extend_from_slice(&[0x2F, 0x60, 0x60, 0x00, 0x09, 0, 0, 0]);
        let mut seen = None;
        let out = SdoServer::new(128)
            .serve(&mut od, &m, true, |i, s, v| seen = Some((i, s, v.to_vec())))
            .unwrap();
        assert_eq!(&out[8..12], &[0x60, 0x60, 0x60, 0x00]);
        assert_eq!(od.get_u32(0x6060, 0), 9);
        assert_eq!(seen, Some((0x6060, 0, vec![9])));
    }

    #[test]
    fn downloads_that_do_not_fit_the_object_abort_with_its_code() {
        let mut od = Od::default();
        od.insert(0x6060, 0, &[8], Access::ReadWrite);
        od.insert(0x6041, 0, &[0, 0], Access::ReadOnly);
        // (command, index, subindex, value) → abort code. 0x23: expedited, 4 bytes;
        // 0x2B: expedited, 2 bytes.
        for (command, index, sub_index, code) in [
            (0x23u8, 0x6060u16, 0u8, 0x0607_0010u32), // 4 bytes into 1
            (0x2B, 0x6041, 0, 0x0601_0002),           // read-only
            (0x2B, 0x6060, 1, 0x0609_0011),           // no subindex 1
            (0x2B, 0x2000, 0, 0x0602_0000),           // no object
        ] {
            let mut m = vec![0x0A, 0x00, 0x00, 0x00, 0x00, 0x23, 0x00, 0x20, command];
            m.extend_from_slice(&index.to_le_bytes());
            m.extend_from_slice(&[sub_index, 9, 0, 0, 0]);
            let out = SdoServer::new(128)
                .serve(&mut od, &m, true, |_, _, _| panic!("nothing is written"))
                .unwrap();
            let mut expected = vec![0x80];
            expected.extend_from_slice(&index.to_le_bytes());
            expected.push(sub_index);
            expected.extend_from_slice(&code.to_le_bytes());
            assert_eq!(&out[8..16], &expected[..], "{index:#06x}:{sub_index}");
        }
        assert_eq!(od.get_u32(0x6060, 0), 8);
    }

    #[test]
    fn a_long_value_is_uploaded_in_segments_with_alternating_toggle() {
        let mut od = Od::default();
        let value: Vec<u8> = (0..150u8).collect();
        od.insert(0x100A, 0, &value, Access::ReadOnly);
        let mut server = SdoServer::new(128);
        let mut m = upload_request();
        m[9] = 0x0A;
        m[11] = 0;
        let out = server.serve(&mut od, &m, true, |_, _, _| {}).unwrap();
        // Initiate response: normal, size indicated, size 150, no data (length 10).
        assert_eq!(&out[..2], &[10, 0]);
        assert_eq!(&out[8..16], &[0x41, 0x0A, 0x10, 0x00, 150, 0, 0, 0]);
        // Upload segment request, toggle 0 (command 0x60): 119 bytes (128 − 9), more follow.
        let mut seg = vec![0x0A, 0x00, 0x00, 0x00, 0x00, 0x23, 0x00, 0x20, 0x60];
        seg.resize(16, 0);
        let first = server.serve(&mut od, &seg, true, |_, _, _| {}).unwrap();
        assert_eq!(u16::from_le_bytes([first[0], first[1]]), 3 + 119);
        assert_eq!(first[8], 0x00);
        assert_eq!(&first[9..128], &value[..119]);
        // Toggle 1 (0x70): the remaining 31 bytes, last segment (bit 0), toggle echoed.
        seg[8] = 0x70;
        let second = server.serve(&mut od, &seg, true, |_, _, _| {}).unwrap();
        assert_eq!(u16::from_le_bytes([second[0], second[1]]), 3 + 31);
        assert_eq!(second[8], 0x11);
        assert_eq!(&second[9..40], &value[119..]);
        // A further segment request has no upload under way.
        let third = server.serve(&mut od, &seg, true, |_, _, _| {}).unwrap();
        assert_eq!(third[8], 0x80);
    }

    /// A request mailbox of 128 bytes as the MainDevice writes it: header (length =
    /// CoE header + `sdo`, counter 2), CoE header (SDO request), then `sdo`.
    fn request(sdo: &[u8]) -> Vec<u8> {
        let mut m = ((2 + sdo.len()) as u16).to_le_bytes().to_vec();
        m.extend_from_slice(&[0x00, 0x00, 0x00, 0x23, 0x00, 0x20]);
        m.extend_from_slice(sdo);
        m.resize(128, 0);
        m
    }

    /// Initiate download, normal, size indicated (0x21), of `size` bytes at 0x2000:01,
    /// carrying `first`.
    fn initiate_download(size: u32, first: &[u8]) -> Vec<u8> {
        let mut sdo = vec![0x21, 0x00, 0x20, 0x01];
        sdo.extend_from_slice(&size.to_le_bytes());
        sdo.extend_from_slice(first);
        request(&sdo)
    }

    /// Download segment: toggle, last, data (at least 7 bytes as they are, fewer
    /// padded to 7 with the unused count in the command).
    fn download_segment(toggle: bool, last: bool, data: &[u8]) -> Vec<u8> {
        let unused = 7usize.saturating_sub(data.len()) as u8;
        let mut sdo = vec![(u8::from(toggle) << 4) | (unused << 1) | u8::from(last)];
        sdo.extend_from_slice(data);
        sdo.resize(1 + data.len().max(7), 0);
        request(&sdo)
    }

    fn long_od(len: usize, access: Access) -> Od {
        let mut od = Od::default();
        od.insert(0x2000, 1, &vec![0; len], access);
        od
    }

    /// The SDO part of a response: command byte onwards, as long as its mailbox length.
    fn sdo_of(response: &[u8]) -> &[u8] {
        let len = usize::from(u16::from_le_bytes([response[0], response[1]]));
        &response[8..6 + len]
    }

    #[test]
    fn a_long_value_is_downloaded_in_segments_and_written_when_complete() {
        let value: Vec<u8> = (0..150u8).map(|b| b.wrapping_mul(7)).collect();
        let mut od = long_od(150, Access::ReadWrite);
        let mut server = SdoServer::new(128);
        let mut written = Vec::new();
        // Initiate: 128 − 16 = 112 bytes fit beside the headers and the size.
        let out = server
            .serve(
                &mut od,
                &initiate_download(150, &value[..112]),
                true,
                |i, s, v| written.push((i, s, v.to_vec())),
            )
            .unwrap();
        assert_eq!(out[5], 0x23, "CoE, counter echoed");
        assert_eq!(sdo_of(&out), &[0x60, 0x00, 0x20, 0x01, 0, 0, 0, 0]);
        // Segment 1, toggle 0: 30 bytes (mailbox length 33); answered with toggle 0.
        let out = server
            .serve(
                &mut od,
                &download_segment(false, false, &value[112..142]),
                true,
                |i, s, v| written.push((i, s, v.to_vec())),
            )
            .unwrap();
        assert_eq!(sdo_of(&out), &[0x20, 0, 0, 0, 0, 0, 0, 0]);
        assert!(
            written.is_empty(),
            "nothing written before the last segment"
        );
        assert_eq!(od.read(0x2000, 1).unwrap(), &[0; 150][..]);
        // Segment 2, toggle 1, last: 8 bytes.
        let out = server
            .serve(
                &mut od,
                &download_segment(true, true, &value[142..]),
                true,
                |i, s, v| written.push((i, s, v.to_vec())),
            )
            .unwrap();
        assert_eq!(sdo_of(&out), &[0x30, 0, 0, 0, 0, 0, 0, 0]);
        assert_eq!(od.read(0x2000, 1).unwrap(), &value[..]);
        assert_eq!(written, vec![(0x2000, 1, value.clone())]);
        // The transfer is over: another segment has nothing to continue.
        let out = server
            .serve(
                &mut od,
                &download_segment(false, true, &[1]),
                true,
                |_, _, _| {},
            )
            .unwrap();
        assert_eq!(sdo_of(&out)[0], 0x80);
        assert_eq!(&sdo_of(&out)[4..8], &0x0504_0001u32.to_le_bytes());
    }

    #[test]
    fn a_last_segment_of_fewer_than_7_bytes_gives_its_length_in_the_command() {
        let value: Vec<u8> = (100..216u8).collect();
        let mut od = long_od(116, Access::ReadWrite);
        let mut server = SdoServer::new(128);
        server
            .serve(
                &mut od,
                &initiate_download(116, &value[..112]),
                true,
                |_, _, _| {},
            )
            .unwrap();
        // 4 bytes: mailbox length 10, 3 unused (command 0x07: unused 3, last).
        let segment = download_segment(false, true, &value[112..]);
        assert_eq!((segment[0], segment[8]), (10, 0x07));
        let out = server.serve(&mut od, &segment, true, |_, _, _| {}).unwrap();
        assert_eq!(sdo_of(&out)[0], 0x20);
        assert_eq!(od.read(0x2000, 1).unwrap(), &value[..]);
    }

    #[test]
    fn a_segmented_download_aborts_on_a_wrong_toggle_or_size_and_checks_the_entry_first() {
        let abort_code = |out: &[u8]| {
            let sdo = sdo_of(out);
            assert_eq!(sdo[0], 0x80, "an abort");
            u32::from_le_bytes([sdo[4], sdo[5], sdo[6], sdo[7]])
        };
        let first = [0xAA; 112];
        let serve = |server: &mut SdoServer, od: &mut Od, m: &[u8]| {
            server.serve(od, m, true, |_, _, _| {}).unwrap()
        };
        // Toggle 1 first: 0x05030000, and the transfer is dropped.
        let mut od = long_od(150, Access::ReadWrite);
        let mut server = SdoServer::new(128);
        serve(&mut server, &mut od, &initiate_download(150, &first));
        let out = serve(
            &mut server,
            &mut od,
            &download_segment(true, false, &[1; 10]),
        );
        assert_eq!(abort_code(&out), 0x0503_0000);
        let out = serve(
            &mut server,
            &mut od,
            &download_segment(false, true, &[1; 38]),
        );
        assert_eq!(abort_code(&out), 0x0504_0001);
        // More bytes than announced, or a last segment short of them: 0x06070010.
        serve(&mut server, &mut od, &initiate_download(150, &first));
        let out = serve(
            &mut server,
            &mut od,
            &download_segment(false, false, &[1; 39]),
        );
        assert_eq!(abort_code(&out), 0x0607_0010);
        serve(&mut server, &mut od, &initiate_download(150, &first));
        let out = serve(
            &mut server,
            &mut od,
            &download_segment(false, true, &[1; 37]),
        );
        assert_eq!(abort_code(&out), 0x0607_0010);
        assert_eq!(
            od.read(0x2000, 1).unwrap(),
            &[0; 150][..],
            "nothing written"
        );
        // The initiate is refused at once for an entry of another size, a read-only one,
        // or one that does not exist.
        let out = serve(&mut server, &mut od, &initiate_download(151, &first));
        assert_eq!(abort_code(&out), 0x0607_0010);
        let mut read_only = long_od(150, Access::ReadOnly);
        let out = serve(&mut server, &mut read_only, &initiate_download(150, &first));
        assert_eq!(abort_code(&out), 0x0601_0002);
        let mut empty = Od::default();
        let out = serve(&mut server, &mut empty, &initiate_download(150, &first));
        assert_eq!(abort_code(&out), 0x0602_0000);
        // Another request in between ends the transfer.
        serve(&mut server, &mut od, &initiate_download(150, &first));
        serve(&mut server, &mut od, &upload_request());
        let out = serve(
            &mut server,
            &mut od,
            &download_segment(false, true, &[1; 38]),
        );
        assert_eq!(abort_code(&out), 0x0504_0001);
    }

    #[test]
    fn a_normal_download_that_fits_one_mailbox_is_written_at_once() {
        let mut od = long_od(20, Access::ReadWrite);
        let value = [0x5A; 20];
        let out = SdoServer::new(128)
            .serve(&mut od, &initiate_download(20, &value), true, |_, _, _| {})
            .unwrap();
        assert_eq!(sdo_of(&out)[0], 0x60);
        assert_eq!(od.read(0x2000, 1).unwrap(), &value[..]);
    }

    #[test]
    fn a_wrong_toggle_aborts_with_0x05030000() {
        let mut od = Od::default();
        od.insert(0x100A, 0, &[7; 150], Access::ReadOnly);
        let mut server = SdoServer::new(128);
        let mut m = upload_request();
        m[9] = 0x0A;
        m[11] = 0;
        server.serve(&mut od, &m, true, |_, _, _| {}).unwrap();
        let mut seg = vec![0x0A, 0x00, 0x00, 0x00, 0x00, 0x23, 0x00, 0x20, 0x70];
        seg.resize(16, 0);
        let out = server.serve(&mut od, &seg, true, |_, _, _| {}).unwrap();
        assert_eq!(
            &out[8..16],
            &[0x80, 0x0A, 0x10, 0x00, 0x00, 0x00, 0x03, 0x05]
        );
    }

    #[test]
    fn a_normal_upload_carries_the_size_then_the_data() {
        let mut od = Od::default();
        od.insert(0x1008, 0, b"Kerf drive", Access::ReadOnly);
        let mut m = upload_request();
        m[9] = 0x08;
        m[11] = 0;
        let out = SdoServer::new(128)
            .serve(&mut od, &m, true, |_, _, _| {})
            .unwrap();
        assert_eq!(out[8], 0x41);
        assert_eq!(&out[12..16], &[10, 0, 0, 0]);
        assert_eq!(&out[16..26], b"Kerf drive");
        assert_eq!(u16::from_le_bytes([out[0], out[1]]), 20);
    }
}
