//! The SII EEPROM image of a subdevice (ETG.1000.6 / ETG.2010): the fixed words (station
//! alias 0x0004, checksum 0x0007, identity 0x0008–0x000F, standard mailbox 0x0018–0x001C,
//! size 0x003E) and the categories from word 0x0040: strings (10), general (30), FMMU (40),
//! SyncManager (41), TxPDO (50), RxPDO (51), end (0xFFFF).

/// Category type: strings.
pub const CAT_STRINGS: u16 = 10;
/// Category type: general.
pub const CAT_GENERAL: u16 = 30;
/// Category type: FMMU usage.
pub const CAT_FMMU: u16 = 40;
/// Category type: SyncManagers.
pub const CAT_SYNC_MANAGER: u16 = 41;
/// Category type: TxPDOs (subdevice to MainDevice, inputs).
pub const CAT_TXPDO: u16 = 50;
/// Category type: RxPDOs (MainDevice to subdevice, outputs).
pub const CAT_RXPDO: u16 = 51;
/// Category type: end marker.
pub const CAT_END: u16 = 0xFFFF;

/// Mailbox protocol bit: CoE (word 0x001C).
pub const MAILBOX_COE: u16 = 0x0004;

/// A subdevice's identity object as the EEPROM and object 0x1018 hold it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Identity {
    /// Vendor id.
    pub vendor_id: u32,
    /// Product code.
    pub product_code: u32,
    /// Revision number.
    pub revision: u32,
    /// Serial number.
    pub serial: u32,
}

/// What a SyncManager is used for (SII SyncManager category, byte 7).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SmUsage {
    /// Mailbox written by the MainDevice (SM0).
    MailboxOut = 1,
    /// Mailbox read by the MainDevice (SM1).
    MailboxIn = 2,
    /// Process data outputs.
    Outputs = 3,
    /// Process data inputs.
    Inputs = 4,
}

/// One SyncManager's default configuration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SmConfig {
    /// Physical start address.
    pub start: u16,
    /// Length, bytes.
    pub len: u16,
    /// Control byte (register 0x0804 + 8n).
    pub control: u8,
    /// Usage.
    pub usage: SmUsage,
}

/// One PDO entry: index, subindex, bit length.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PdoEntry {
    /// Object index.
    pub index: u16,
    /// Subindex.
    pub sub_index: u8,
    /// Bit length.
    pub bit_len: u8,
}

/// One PDO of the EEPROM's PDO categories.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Pdo {
    /// The PDO's index (0x1600… or 0x1A00…).
    pub index: u16,
    /// The SyncManager it is assigned to.
    pub sync_manager: u8,
    /// Its entries.
    pub entries: Vec<PdoEntry>,
}

/// Everything the image is built from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SiiSpec {
    /// Identity words 0x0008–0x000F.
    pub identity: Identity,
    /// Station alias, word 0x0004.
    pub alias: u16,
    /// Device name (general category's order and name string).
    pub name: String,
    /// Standard mailbox: (receive offset, receive size, send offset, send size); `None`
    /// for a subdevice without a mailbox.
    pub mailbox: Option<(u16, u16, u16, u16)>,
    /// SyncManagers in order SM0, SM1, ….
    pub sync_managers: Vec<SmConfig>,
    /// FMMU usage bytes: 1 outputs, 2 inputs, 3 SyncManager status.
    pub fmmus: Vec<u8>,
    /// TxPDOs (inputs).
    pub tx_pdos: Vec<Pdo>,
    /// RxPDOs (outputs).
    pub rx_pdos: Vec<Pdo>,
}

/// The CRC-8 of ETG.1000.6 over words 0x0000–0x0006 (polynomial x⁸+x²+x+1, initial 0xFF).
pub fn crc8(bytes: &[u8]) -> u8 {
    let mut crc: u8 = 0xFF;
    for &byte in bytes {
        crc ^= byte;
        for _ in 0..8 {
            crc = if crc & 0x80 != 0 {
                (crc << 1) ^ 0x07
            } else {
                crc << 1
            };
        }
    }
    crc
}

fn push_category(words: &mut Vec<u16>, kind: u16, mut bytes: Vec<u8>) {
    if bytes.len() % 2 == 1 {
        bytes.push(0);
    }
    words.push(kind);
    words.push((bytes.len() / 2) as u16);
    words.extend(bytes.chunks(2).map(|c| u16::from_le_bytes([c[0], c[1]])));
}

fn pdo_bytes(pdos: &[Pdo]) -> Vec<u8> {
    let mut out = Vec::new();
    for pdo in pdos {
        out.extend_from_slice(&pdo.index.to_le_bytes());
        out.push(pdo.entries.len() as u8);
        out.push(pdo.sync_manager);
        out.extend_from_slice(&[0, 0, 0, 0]); // DC sync, name, flags
        for entry in &pdo.entries {
            out.extend_from_slice(&entry.index.to_le_bytes());
            out.push(entry.sub_index);
            out.push(0); // name
            out.push(0); // data type
            out.push(entry.bit_len);
            out.extend_from_slice(&[0, 0]); // flags
        }
    }
    out
}

/// Builds the EEPROM image, as 16-bit words.
pub fn build_image(spec: &SiiSpec) -> Vec<u16> {
    let mut words = vec![0u16; 0x40];
    words[0x0004] = spec.alias;
    let mut head = [0u8; 14];
    for (i, word) in words[..7].iter().enumerate() {
        head[2 * i..2 * i + 2].copy_from_slice(&word.to_le_bytes());
    }
    words[0x0007] = u16::from(crc8(&head));
    let id = spec.identity;
    for (i, value) in [id.vendor_id, id.product_code, id.revision, id.serial]
        .into_iter()
        .enumerate()
    {
        words[0x0008 + 2 * i] = value as u16;
        words[0x0009 + 2 * i] = (value >> 16) as u16;
    }
    if let Some((rx_offset, rx_size, tx_offset, tx_size)) = spec.mailbox {
        words[0x0018] = rx_offset;
        words[0x0019] = rx_size;
        words[0x001A] = tx_offset;
        words[0x001B] = tx_size;
        words[0x001C] = MAILBOX_COE;
    }
    words[0x003F] = 1; // version

    // Strings: index 1 is the name.
    let mut strings = vec![1u8, spec.name.len() as u8];
    strings.extend_from_slice(spec.name.as_bytes());
    push_category(&mut words, CAT_STRINGS, strings);

    let mut general = vec![0u8; 32];
    general[2] = 1; // order string
    general[3] = 1; // name string
    if spec.mailbox.is_some() {
        general[5] = 0x01 | 0x02 | 0x04; // SDO, SDO info, PDO assign
    }
    general[0x10] = 0x11; // ports 0 and 1 MII
    push_category(&mut words, CAT_GENERAL, general);
    push_category(&mut words, CAT_FMMU, spec.fmmus.clone());

    let mut sms = Vec::new();
    for sm in &spec.sync_managers {
        sms.extend_from_slice(&sm.start.to_le_bytes());
        sms.extend_from_slice(&sm.len.to_le_bytes());
        sms.push(sm.control);
        sms.push(0);
        sms.push(1); // enable
        sms.push(sm.usage as u8);
    }
    push_category(&mut words, CAT_SYNC_MANAGER, sms);
    if !spec.tx_pdos.is_empty() {
        push_category(&mut words, CAT_TXPDO, pdo_bytes(&spec.tx_pdos));
    }
    if !spec.rx_pdos.is_empty() {
        push_category(&mut words, CAT_RXPDO, pdo_bytes(&spec.rx_pdos));
    }
    words.push(CAT_END);
    words.push(0);
    // Size in word 0x003E: (KiB·8 / 1) − 1 as ethercrab reads it: (value + 1) · 128 bytes.
    let bytes = words.len() * 2;
    words[0x003E] = bytes.div_ceil(128).saturating_sub(1) as u16;
    words.resize((usize::from(words[0x003E]) + 1) * 64, 0xFFFF);
    words
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec() -> SiiSpec {
        SiiSpec {
            identity: Identity {
                vendor_id: 0x0000_4B52,
                product_code: 0x0000_0402,
                revision: 0x0001_0000,
                serial: 7,
            },
            alias: 0,
            name: "Drive".into(),
            mailbox: Some((0x1000, 128, 0x1080, 128)),
            sync_managers: vec![SmConfig {
                start: 0x1000,
                len: 128,
                control: 0x26,
                usage: SmUsage::MailboxOut,
            }],
            fmmus: vec![1, 2],
            tx_pdos: vec![],
            rx_pdos: vec![Pdo {
                index: 0x1600,
                sync_manager: 2,
                entries: vec![PdoEntry {
                    index: 0x6040,
                    sub_index: 0,
                    bit_len: 16,
                }],
            }],
        }
    }

    #[test]
    fn the_crc_matches_the_spec_check_value() {
        // CRC-8 with polynomial 0x07 and initial 0xFF over "123456789" is 0xFB.
        assert_eq!(crc8(b"123456789"), 0xFB);
    }

    #[test]
    fn fixed_words_hold_identity_and_mailbox() {
        let image = build_image(&spec());
        assert_eq!(&image[0x08..0x10], &[0x4B52, 0, 0x0402, 0, 0, 1, 7, 0]);
        assert_eq!(&image[0x18..0x1D], &[0x1000, 128, 0x1080, 128, 4]);
        assert_eq!(image.len() % 64, 0);
        assert_eq!((usize::from(image[0x3E]) + 1) * 64, image.len());
    }

    #[test]
    fn categories_follow_one_another_from_word_0x40() {
        let image = build_image(&spec());
        // Strings: type 10, 4 words: count 1, length 5, "Drive", padding.
        assert_eq!(&image[0x40..0x42], &[10, 4]);
        assert_eq!(image[0x42], u16::from_le_bytes([1, 5]));
        assert_eq!(image[0x43], u16::from_le_bytes([b'D', b'r']));
        // General follows: type 30, 16 words.
        assert_eq!(&image[0x46..0x48], &[30, 16]);
        // FMMU: type 40, 1 word [1, 2].
        assert_eq!(&image[0x58..0x5B], &[40, 1, 0x0201]);
        // SyncManager: 4 words, start 0x1000, len 128, control 0x26 / status 0, enable 1 / type 1.
        assert_eq!(&image[0x5B..0x61], &[41, 4, 0x1000, 128, 0x0026, 0x0101]);
        // RxPDO: 8 + 8 bytes.
        assert_eq!(&image[0x61..0x63], &[51, 8]);
        assert_eq!(&image[0x63..0x65], &[0x1600, 0x0201]);
        assert_eq!(&image[0x6B..0x6D], &[0xFFFF, 0]);
    }
}
