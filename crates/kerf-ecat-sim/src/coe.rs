//! The mailbox (ETG.1000.4 §5.6: 6-byte header with length, address, type and counter)
//! and CoE SDO services on it (ETG.1000.6 §5.6.2, CiA 301): upload and download,
//! expedited (up to 4 bytes in the initiate frame) and normal (size then data), and the
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
    /// Something this emulator does not serve (segments, complete access, SDO info…).
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

/// Serves one mailbox request from a dictionary; `on_write` sees each accepted download.
pub fn serve(
    od: &mut Od,
    mailbox: &[u8],
    pre_op: bool,
    mut on_write: impl FnMut(u16, u8, &[u8]),
) -> Option<Vec<u8>> {
    let (counter, request) = decode(mailbox)?;
    Some(match request {
        SdoRequest::Upload { index, sub_index } => match od.read(index, sub_index) {
            Ok(value) => upload_response(counter, index, sub_index, value),
            Err(code) => abort(counter, index, sub_index, code),
        },
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
        let out = serve(&mut od, &upload_request(), true, |_, _, _| {}).unwrap();
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
        let out = serve(&mut od, &upload_request(), true, |_, _, _| {}).unwrap();
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
        let out = serve(&mut od, &m, true, |i, s, v| seen = Some((i, s, v.to_vec()))).unwrap();
        assert_eq!(&out[8..12], &[0x60, 0x60, 0x60, 0x00]);
        assert_eq!(od.get_u32(0x6060, 0), 9);
        assert_eq!(seen, Some((0x6060, 0, vec![9])));
    }

    #[test]
    fn a_normal_upload_carries_the_size_then_the_data() {
        let mut od = Od::default();
        od.insert(0x1008, 0, b"Kerf drive", Access::ReadOnly);
        let mut m = upload_request();
        m[9] = 0x08;
        m[11] = 0;
        let out = serve(&mut od, &m, true, |_, _, _| {}).unwrap();
        assert_eq!(out[8], 0x41);
        assert_eq!(&out[12..16], &[10, 0, 0, 0]);
        assert_eq!(&out[16..26], b"Kerf drive");
        assert_eq!(u16::from_le_bytes([out[0], out[1]]), 20);
    }
}
