//! The mailbox (ETG.1000.4 §5.6: 6-byte header with length, address, type and counter)
//! and CoE SDO services on it (ETG.1000.6 §5.6.2, CiA 301): upload and download,
//! expedited (up to 4 bytes in the initiate frame) and normal (size then data), segmented
//! upload (a value longer than the mailbox: the initiate response gives the size, then
//! each upload-segment request gets up to mailbox − 9 bytes with the toggle bit), and the
//! abort transfer with its code.

use crate::od::{ABORT_COMMAND, Od};

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
    /// Upload segment request with its toggle bit.
    UploadSegment {
        /// The toggle bit (alternates from 0).
        toggle: bool,
    },
    /// Something this emulator does not serve (download segments, complete access, SDO
    /// info…).
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
                let available = len.saturating_sub(10).min(data.len().saturating_sub(4));
                if size > available {
                    SdoRequest::Unsupported { index, sub_index }
                } else {
                    SdoRequest::Download {
                        index,
                        sub_index,
                        value: data[4..4 + size].to_vec(),
                    }
                }
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

/// The SDO server of one subdevice: serves requests from its dictionary and keeps the
/// state of a segmented upload.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SdoServer {
    mailbox_len: usize,
    segmented: Option<Segmented>,
}

/// ETG.1000.6 toggle bit error abort.
pub const ABORT_TOGGLE: u32 = 0x0503_0000;

impl SdoServer {
    /// A server answering in mailboxes of `mailbox_len` bytes.
    pub fn new(mailbox_len: u16) -> SdoServer {
        SdoServer {
            mailbox_len: usize::from(mailbox_len),
            segmented: None,
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
            SdoRequest::Unsupported { index, sub_index } => {
                abort(counter, index, sub_index, ABORT_COMMAND)
            }
        })
    }

    fn segment(&mut self, counter: u8, toggle: bool) -> Vec<u8> {
        let Some(mut upload) = self.segmented.take() else {
            return abort(counter, 0, 0, ABORT_COMMAND);
        };
        if toggle != upload.toggle {
            return abort(counter, upload.index, upload.sub_index, ABORT_TOGGLE);
        }
        let room = self.mailbox_len - MAILBOX_HEADER_LEN - 3;
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
