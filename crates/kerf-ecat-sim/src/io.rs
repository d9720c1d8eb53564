//! A digital I/O subdevice without a mailbox: `inputs` input bits (TxPDO 0x1A00, objects
//! 0x6000:01…) and `outputs` output bits (RxPDO 0x1600, objects 0x7000:01…), mapped from
//! the EEPROM, each direction rounded up to whole bytes. A test sets the inputs and reads
//! the outputs through an [`IoHandle`].

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use crate::al::AlState;
use crate::esc::{AppSnapshot, Application};
use crate::sii::{Identity, Pdo, PdoEntry, SiiSpec, SmConfig, SmUsage};

/// The most bits per direction.
pub const MAX_BITS: u8 = 64;

/// The test's side of an I/O subdevice: bit n of the inputs is input n.
#[derive(Debug, Clone, Default)]
pub struct IoHandle {
    inputs: Arc<AtomicU64>,
    outputs: Arc<AtomicU64>,
}

impl IoHandle {
    /// Sets the input bits the MainDevice will read.
    pub fn set_inputs(&self, bits: u64) {
        self.inputs.store(bits, Ordering::SeqCst);
    }

    /// The output bits the MainDevice last wrote in OP.
    pub fn outputs(&self) -> u64 {
        self.outputs.load(Ordering::SeqCst)
    }
}

/// What an I/O subdevice shows, for the emulator's `state` command.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct IoSnapshot {
    /// Number of input bits.
    pub input_bits: u8,
    /// Number of output bits.
    pub output_bits: u8,
    /// The input bits (bit n: input n).
    pub inputs: u64,
    /// The output bits last written in OP (cleared when it leaves OP).
    pub outputs: u64,
}

/// The I/O subdevice.
#[derive(Debug)]
pub struct IoDevice {
    sii: SiiSpec,
    input_bits: u8,
    output_bits: u8,
    in_bytes: u16,
    out_bytes: u16,
    handle: IoHandle,
}

fn bit_pdo(index: u16, object: u16, sync_manager: u8, bits: u8) -> Pdo {
    Pdo {
        index,
        sync_manager,
        entries: (1..=bits)
            .map(|n| PdoEntry {
                index: object,
                sub_index: n,
                bit_len: 1,
            })
            .collect(),
    }
}

impl IoDevice {
    /// An I/O subdevice with this identity, name and bit counts (each at most
    /// [`MAX_BITS`], clamped).
    pub fn new(identity: Identity, name: &str, inputs: u8, outputs: u8) -> (IoDevice, IoHandle) {
        let inputs = inputs.min(MAX_BITS);
        let outputs = outputs.min(MAX_BITS);
        let out_bytes = u16::from(outputs).div_ceil(8);
        let in_bytes = u16::from(inputs).div_ceil(8);
        let sii = SiiSpec {
            identity,
            alias: 0,
            name: name.into(),
            mailbox: None,
            sync_managers: vec![
                SmConfig {
                    start: 0x0F00,
                    len: out_bytes,
                    control: 0x44,
                    usage: SmUsage::Outputs,
                },
                SmConfig {
                    start: 0x1000,
                    len: in_bytes,
                    control: 0x00,
                    usage: SmUsage::Inputs,
                },
            ],
            fmmus: vec![1, 2],
            tx_pdos: vec![bit_pdo(0x1A00, 0x6000, 1, inputs)],
            rx_pdos: vec![bit_pdo(0x1600, 0x7000, 0, outputs)],
        };
        let handle = IoHandle::default();
        (
            IoDevice {
                sii,
                input_bits: inputs,
                output_bits: outputs,
                in_bytes,
                out_bytes,
                handle: handle.clone(),
            },
            handle,
        )
    }
}

impl Application for IoDevice {
    fn sii(&self) -> &SiiSpec {
        &self.sii
    }

    fn process_data_len(&self) -> (u16, u16) {
        (self.out_bytes, self.in_bytes)
    }

    fn mailbox(&mut self, _request: &[u8], _state: AlState) -> Option<Vec<u8>> {
        None
    }

    fn outputs(&mut self, data: &[u8], apply: bool, _now_ns: u64) {
        if apply {
            let mut word = [0u8; 8];
            let n = data.len().min(8);
            word[..n].copy_from_slice(&data[..n]);
            self.handle
                .outputs
                .store(u64::from_le_bytes(word), Ordering::SeqCst);
        }
    }

    fn inputs(&mut self, data: &mut [u8]) {
        let word = self.handle.inputs.load(Ordering::SeqCst).to_le_bytes();
        for (i, byte) in data.iter_mut().enumerate() {
            *byte = word.get(i).copied().unwrap_or(0);
        }
    }

    fn watchdog_expired(&mut self, _now_ns: u64) {
        self.handle.outputs.store(0, Ordering::SeqCst);
    }

    fn transition(&mut self, _from: AlState, to: AlState) {
        if to < AlState::Op {
            self.handle.outputs.store(0, Ordering::SeqCst);
        }
    }

    fn snapshot(&self) -> AppSnapshot {
        let mask = |bits: u8| u64::MAX.checked_shr(64 - u32::from(bits)).unwrap_or(0);
        AppSnapshot::Io(IoSnapshot {
            input_bits: self.input_bits,
            output_bits: self.output_bits,
            inputs: self.handle.inputs.load(Ordering::SeqCst) & mask(self.input_bits),
            outputs: self.handle.outputs.load(Ordering::SeqCst),
        })
    }
}
