//! The CoE objects of `[ethercat]` checked: identities, PDO mappings (`rx_pdo`, `tx_pdo`)
//! and SDO start-up lists (`sdo`).

use std::ops::RangeInclusive;

use toml::Spanned;

use crate::ethercat::*;
use crate::raw::*;
use crate::*;

use super::Checker;

/// An object the control needs in a PDO: where, its size, and what it is in words.
pub(crate) struct Needed {
    pub(crate) object: (u16, u8),
    pub(crate) bits: u8,
    pub(crate) what: &'static str,
}

/// `index:subindex` as CoE tools print it (`0x607A:0`).
pub(crate) fn object_name((index, subindex): (u16, u8)) -> String {
    format!("0x{index:04X}:{subindex}")
}

impl Checker<'_> {
    /// A whole number within `range`, said in hexadecimal in the message (object indices,
    /// identities).
    pub(crate) fn hex_integer(
        &self,
        key: &str,
        what: &str,
        range: RangeInclusive<u32>,
        value: &Spanned<i64>,
    ) -> Result<u32, ConfigError> {
        match u32::try_from(*value.get_ref()) {
            Ok(v) if range.contains(&v) => Ok(v),
            _ => {
                let v = *value.get_ref();
                let found = if v < 0 {
                    v.to_string()
                } else {
                    format!("0x{v:X}")
                };
                Err(self.error(
                    value.span(),
                    format!(
                        "`{key}` must be {what} from 0x{:X} to 0x{:X}, found {found}",
                        range.start(),
                        range.end()
                    ),
                ))
            }
        }
    }

    /// `vendor_id`, `product_code` and `revision` of the subdevice at `key`.
    pub(crate) fn identity(
        &self,
        key: &str,
        vendor_id: &Spanned<i64>,
        product_code: &Spanned<i64>,
        revision: &Option<Spanned<i64>>,
    ) -> Result<Identity, ConfigError> {
        let what = "a 32-bit number";
        let all = 0..=u32::MAX;
        Ok(Identity {
            vendor_id: self.hex_integer(
                &format!("{key}.vendor_id"),
                what,
                all.clone(),
                vendor_id,
            )?,
            product_code: self.hex_integer(
                &format!("{key}.product_code"),
                what,
                all.clone(),
                product_code,
            )?,
            revision: match revision {
                None => None,
                Some(r) => Some(self.hex_integer(&format!("{key}.revision"), what, all, r)?),
            },
        })
    }

    /// One PDO of a drive at `key` (`rx_pdo` or `tx_pdo`): its mapping object
    /// (`index_key`, within `index_range`) and entries, or `default` where not given; it
    /// must map every object of `needed`.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn pdo(
        &self,
        key: &str,
        index_key: &str,
        index_range: RangeInclusive<u32>,
        raw_index: &Option<Spanned<i64>>,
        raw: &Option<Spanned<Vec<RawPdoEntry>>>,
        default: Pdo,
        needed: &[Needed],
    ) -> Result<Pdo, ConfigError> {
        let index = match raw_index {
            None => default.index,
            Some(i) => self.hex_integer(index_key, "a PDO mapping object", index_range, i)? as u16,
        };
        let Some(raw) = raw else {
            return Ok(Pdo {
                index,
                entries: default.entries,
            });
        };
        let list = raw.get_ref();
        if list.is_empty() || list.len() > MAX_PDO_ENTRIES {
            return Err(self.error(
                raw.span(),
                format!(
                    "`{key}` must list 1 to {MAX_PDO_ENTRIES} entries, found {}",
                    list.len()
                ),
            ));
        }
        let mut entries: Vec<PdoEntry> = Vec::with_capacity(list.len());
        let mut at_bit = 0usize;
        for (i, e) in list.iter().enumerate() {
            let here = format!("{key}[{i}]");
            let entry = self.pdo_entry(&here, e)?;
            if entry.index != 0
                && let Some(j) = entries
                    .iter()
                    .position(|p| (p.index, p.subindex) == (entry.index, entry.subindex))
            {
                return Err(self.error(
                    e.index.span(),
                    format!(
                        "`{here}` maps {} again (it is `{key}[{j}]`)",
                        object_name((entry.index, entry.subindex))
                    ),
                ));
            }
            if entry.bits >= 8 && !at_bit.is_multiple_of(8) {
                return Err(self.error(
                    e.bits.span(),
                    format!(
                        "`{here}` ({}, {} bits) starts at bit {at_bit}: an entry of 8 bits or more must start on a whole byte; put a gap {{ index = 0, subindex = 0, bits = {} }} before it",
                        object_name((entry.index, entry.subindex)),
                        entry.bits,
                        8 - at_bit % 8
                    ),
                ));
            }
            at_bit += usize::from(entry.bits);
            entries.push(entry);
        }
        if !at_bit.is_multiple_of(8) || at_bit / 8 > MAX_PDO_BYTES {
            let fix = if !at_bit.is_multiple_of(8) {
                format!(
                    "a whole number of bytes; end it with a gap {{ index = 0, subindex = 0, bits = {} }}",
                    8 - at_bit % 8
                )
            } else {
                format!("at most {MAX_PDO_BYTES} bytes")
            };
            return Err(self.error(
                raw.span(),
                format!("`{key}` maps {at_bit} bits; a PDO must be {fix}"),
            ));
        }
        let pdo = Pdo { index, entries };
        for n in needed {
            match pdo.bit_offset(n.object.0, n.object.1) {
                Some((_, bits)) if bits == n.bits => {}
                Some((_, bits)) => {
                    return Err(self.error(
                        raw.span(),
                        format!(
                            "`{key}` maps the {} {} with {bits} bits; it is {} bits",
                            n.what,
                            object_name(n.object),
                            n.bits
                        ),
                    ));
                }
                None => {
                    return Err(self.error(
                        raw.span(),
                        format!(
                            "`{key}` must map the {} {} ({} bits): the daemon cannot run the drive without it",
                            n.what,
                            object_name(n.object),
                            n.bits
                        ),
                    ));
                }
            }
        }
        Ok(pdo)
    }

    /// One `{ index, subindex, bits }` of a PDO at `key`.
    fn pdo_entry(&self, key: &str, e: &RawPdoEntry) -> Result<PdoEntry, ConfigError> {
        let index = self.hex_integer(
            &format!("{key}.index"),
            "an object index (0: a gap)",
            0..=0xFFFF,
            &e.index,
        )? as u16;
        let subindex = self.integer(
            &format!("{key}.subindex"),
            "a subindex",
            0..=255,
            &e.subindex,
        )? as u8;
        let bits = *e.bits.get_ref();
        if index == 0 {
            if subindex != 0 {
                return Err(self.error(
                    e.subindex.span(),
                    format!("`{key}` is a gap (index 0): its subindex must be 0, found {subindex}"),
                ));
            }
            if !(1..=64).contains(&bits) {
                return Err(self.error(
                    e.bits.span(),
                    format!("`{key}.bits` of a gap must be 1 to 64, found {bits}"),
                ));
            }
        } else if !matches!(bits, 1 | 8 | 16 | 32 | 64) {
            return Err(self.error(
                e.bits.span(),
                format!("`{key}.bits` must be 1, 8, 16, 32 or 64, found {bits}"),
            ));
        }
        Ok(PdoEntry {
            index,
            subindex,
            bits: bits as u8,
        })
    }

    /// The SDO start-up list at `key`; `reserved` are the objects the bring-up writes
    /// itself, each with the key that sets it.
    pub(crate) fn sdo_list(
        &self,
        key: &str,
        raw: &[RawSdo],
        reserved: &[(u16, &str)],
    ) -> Result<Vec<SdoWrite>, ConfigError> {
        let mut out = Vec::with_capacity(raw.len());
        for (i, s) in raw.iter().enumerate() {
            let here = format!("{key}[{i}]");
            let index = self.hex_integer(
                &format!("{here}.index"),
                "an object index",
                0x1000..=0xFFFF,
                &s.index,
            )? as u16;
            if let Some((_, by)) = reserved.iter().find(|(r, _)| *r == index) {
                return Err(self.error(
                    s.index.span(),
                    format!(
                        "`{here}` writes 0x{index:04X}, which the bring-up sets from {by}; set it there"
                    ),
                ));
            }
            let subindex = self.integer(
                &format!("{here}.subindex"),
                "a subindex",
                0..=255,
                &s.subindex,
            )? as u8;
            let value = self.sdo_value(&here, s)?;
            out.push(SdoWrite {
                index,
                subindex,
                value,
            });
        }
        Ok(out)
    }

    /// `type` and `value` of the SDO write at `key`.
    fn sdo_value(&self, key: &str, s: &RawSdo) -> Result<SdoValue, ConfigError> {
        let v = *s.value.get_ref();
        let (value, range) = match s.kind.get_ref().as_str() {
            "u8" => (u8::try_from(v).ok().map(SdoValue::U8), (0, u8::MAX as i64)),
            "u16" => (
                u16::try_from(v).ok().map(SdoValue::U16),
                (0, u16::MAX as i64),
            ),
            "u32" => (
                u32::try_from(v).ok().map(SdoValue::U32),
                (0, u32::MAX as i64),
            ),
            "i8" => (
                i8::try_from(v).ok().map(SdoValue::I8),
                (i8::MIN as i64, i8::MAX as i64),
            ),
            "i16" => (
                i16::try_from(v).ok().map(SdoValue::I16),
                (i16::MIN as i64, i16::MAX as i64),
            ),
            "i32" => (
                i32::try_from(v).ok().map(SdoValue::I32),
                (i32::MIN as i64, i32::MAX as i64),
            ),
            other => {
                return Err(self.error(
                    s.kind.span(),
                    format!(
                        "`{key}.type` must be one of u8, u16, u32, i8, i16, i32, found `{other}`"
                    ),
                ));
            }
        };
        value.ok_or_else(|| {
            self.error(
                s.value.span(),
                format!(
                    "`{key}.value` must be a {} from {} to {}, found {v}",
                    s.kind.get_ref(),
                    range.0,
                    range.1
                ),
            )
        })
    }
}
