//! An object dictionary: values by (index, subindex) as little-endian bytes, with access
//! rights (read-only, read-write, writable only in PRE-OP) and the SDO abort codes of
//! CiA 301 for what it refuses.

use std::collections::BTreeMap;

/// SDO abort 0x06010002: attempt to write a read-only object.
pub const ABORT_READ_ONLY: u32 = 0x0601_0002;
/// SDO abort 0x06020000: object does not exist.
pub const ABORT_NO_OBJECT: u32 = 0x0602_0000;
/// SDO abort 0x06070010: data type does not match, length of service parameter does not
/// match.
pub const ABORT_TYPE_MISMATCH: u32 = 0x0607_0010;
/// SDO abort 0x06090011: subindex does not exist.
pub const ABORT_NO_SUBINDEX: u32 = 0x0609_0011;
/// SDO abort 0x08000022: data cannot be stored because of the present device state.
pub const ABORT_DEVICE_STATE: u32 = 0x0800_0022;
/// SDO abort 0x05040001: client/server command specifier not valid.
pub const ABORT_COMMAND: u32 = 0x0504_0001;

/// Who may write an entry.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Access {
    /// Nobody.
    ReadOnly,
    /// The MainDevice, in any state with a mailbox.
    ReadWrite,
    /// The MainDevice, in PRE-OP only (PDO assignment and mapping).
    PreOpOnly,
}

/// One entry's value and access.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Entry {
    /// Little-endian value.
    pub value: Vec<u8>,
    /// Access rights.
    pub access: Access,
}

/// The dictionary.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Od {
    entries: BTreeMap<(u16, u8), Entry>,
}

impl Od {
    /// Adds (or replaces) an entry.
    pub fn insert(&mut self, index: u16, sub_index: u8, value: &[u8], access: Access) {
        self.entries.insert(
            (index, sub_index),
            Entry {
                value: value.to_vec(),
                access,
            },
        );
    }

    /// Adds a record: subindex 0 holds the count (u8, `access`), then the u32 or u16
    /// values.
    pub fn insert_record(&mut self, index: u16, values: &[u32], value_len: usize, access: Access) {
        self.insert(index, 0, &[values.len() as u8], access);
        for (i, value) in values.iter().enumerate() {
            self.insert(
                index,
                i as u8 + 1,
                &value.to_le_bytes()[..value_len],
                access,
            );
        }
    }

    /// Reads an entry.
    pub fn read(&self, index: u16, sub_index: u8) -> Result<&[u8], u32> {
        match self.entries.get(&(index, sub_index)) {
            Some(entry) => Ok(&entry.value),
            None if self.entries.keys().any(|(i, _)| *i == index) => Err(ABORT_NO_SUBINDEX),
            None => Err(ABORT_NO_OBJECT),
        }
    }

    /// Whether a write of `len` bytes would be accepted, and if not the abort code: the
    /// entry exists, may be written (`pre_op` tells whether the subdevice is in PRE-OP),
    /// and is `len` bytes long.
    pub fn check_write(
        &self,
        index: u16,
        sub_index: u8,
        len: usize,
        pre_op: bool,
    ) -> Result<(), u32> {
        self.read(index, sub_index)?;
        let Some(entry) = self.entries.get(&(index, sub_index)) else {
            return Err(ABORT_NO_OBJECT);
        };
        match entry.access {
            Access::ReadOnly => return Err(ABORT_READ_ONLY),
            Access::PreOpOnly if !pre_op => return Err(ABORT_DEVICE_STATE),
            _ => {}
        }
        if len != entry.value.len() {
            return Err(ABORT_TYPE_MISMATCH);
        }
        Ok(())
    }

    /// Writes an entry, checking access and length ([`Od::check_write`]).
    pub fn write(
        &mut self,
        index: u16,
        sub_index: u8,
        value: &[u8],
        pre_op: bool,
    ) -> Result<(), u32> {
        self.check_write(index, sub_index, value.len(), pre_op)?;
        if let Some(entry) = self.entries.get_mut(&(index, sub_index)) {
            entry.value.copy_from_slice(value);
        }
        Ok(())
    }

    /// Sets a value regardless of access (the device's own update of an input object).
    pub fn set(&mut self, index: u16, sub_index: u8, value: &[u8]) {
        if let Some(entry) = self.entries.get_mut(&(index, sub_index)) {
            entry.value = value.to_vec();
        }
    }

    /// A u8/u16/u32 entry as u32 (0 where absent).
    pub fn get_u32(&self, index: u16, sub_index: u8) -> u32 {
        self.read(index, sub_index).map_or(0, |bytes| {
            let mut word = [0u8; 4];
            let n = bytes.len().min(4);
            word[..n].copy_from_slice(&bytes[..n]);
            u32::from_le_bytes(word)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn od() -> Od {
        let mut od = Od::default();
        od.insert(0x1000, 0, &0x0002_0192u32.to_le_bytes(), Access::ReadOnly);
        od.insert_record(0x1C12, &[0x1600], 2, Access::PreOpOnly);
        od.insert(0x6060, 0, &[8], Access::ReadWrite);
        od
    }

    #[test]
    fn absent_objects_and_subindices_have_their_abort_codes() {
        let od = od();
        assert_eq!(od.read(0x2000, 0), Err(0x0602_0000));
        assert_eq!(od.read(0x1C12, 5), Err(0x0609_0011));
        assert_eq!(od.read(0x1C12, 1), Ok(&[0x00, 0x16][..]));
    }

    #[test]
    fn writes_check_access_state_and_length() {
        let mut od = od();
        assert_eq!(od.write(0x1000, 0, &[0; 4], true), Err(0x0601_0002));
        assert_eq!(od.write(0x1C12, 1, &[0x01, 0x16], false), Err(0x0800_0022));
        assert_eq!(od.write(0x6060, 0, &[9, 0], true), Err(0x0607_0010));
        assert_eq!(od.write(0x2000, 0, &[9], true), Err(0x0602_0000));
        assert_eq!(od.write(0x1C12, 7, &[0, 0], true), Err(0x0609_0011));
        assert_eq!(od.write(0x6060, 0, &[], true), Err(0x0607_0010));
        assert_eq!(od.write(0x6060, 0, &[9], false), Ok(()));
        assert_eq!(od.get_u32(0x6060, 0), 9);
    }
}
