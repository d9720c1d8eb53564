//! The machine's digital inputs and outputs on the bus: each `[io]` entry with a bus bit
//! (`kerf_config::BusBit`, a named bit of an `[[ethercat.io]]` subdevice) linked to its
//! number in the machine's 64-bit I/O words, so that the cycle copies the outputs into
//! the subdevices' process data and their input bits back, without allocating.
//!
//! Bit `b` of a subdevice's process data is bit `b % 8` of its byte `b / 8` (EtherCAT's
//! bit order, as the configuration numbers them). Bits of the process data that no
//! `[io]` output names are left as they are (0 from the bring-up on).

use kerf_config::{BusBit, Config};

use crate::bus::MAX_SUBDEVICES;

/// The most digital inputs (and outputs) of a machine: the bits of a `u64`.
pub const MAX_IO_BITS: usize = 64;

/// One `[io]` entry on the bus.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
struct Link {
    /// Its number in the machine's I/O word (0 to 63).
    number: u8,
    /// The subdevice's ring position.
    position: u16,
    /// The bit in the subdevice's outputs (inputs).
    bit: u16,
}

/// The links of one direction, with the subdevices they touch.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Links {
    links: [Link; MAX_IO_BITS],
    len: usize,
    positions: [u16; MAX_SUBDEVICES],
    positions_len: usize,
}

impl Links {
    fn new(entries: impl Iterator<Item = (u8, BusBit)>) -> Links {
        let mut l = Links {
            links: [Link::default(); MAX_IO_BITS],
            len: 0,
            positions: [0; MAX_SUBDEVICES],
            positions_len: 0,
        };
        for (number, b) in entries {
            if usize::from(number) >= MAX_IO_BITS || l.len == MAX_IO_BITS {
                continue;
            }
            l.links[l.len] = Link {
                number,
                position: b.position,
                bit: b.bit,
            };
            l.len += 1;
            if !l.positions[..l.positions_len].contains(&b.position)
                && l.positions_len < MAX_SUBDEVICES
            {
                l.positions[l.positions_len] = b.position;
                l.positions_len += 1;
            }
        }
        l
    }

    fn of(&self, position: u16) -> impl Iterator<Item = &Link> {
        self.links[..self.len]
            .iter()
            .filter(move |l| l.position == position)
    }
}

/// The `[io]` digital inputs and outputs on the bus (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct IoMap {
    outputs: Links,
    inputs: Links,
}

impl IoMap {
    /// The map of `outputs` and `inputs`: (number in the machine's word, bus bit).
    /// Numbers from 64 on are ignored (the configuration refuses them).
    pub fn new(
        outputs: impl Iterator<Item = (u8, BusBit)>,
        inputs: impl Iterator<Item = (u8, BusBit)>,
    ) -> IoMap {
        IoMap {
            outputs: Links::new(outputs),
            inputs: Links::new(inputs),
        }
    }

    /// The map of `config`'s `[io]`: its digital outputs and inputs that have a bus bit.
    pub fn of(config: &Config) -> IoMap {
        IoMap::new(
            config
                .io
                .digital_outputs
                .iter()
                .filter_map(|o| Some((o.number, o.bus_bit?))),
            config
                .io
                .digital_inputs
                .iter()
                .filter_map(|i| Some((i.number, i.bus_bit?))),
        )
    }

    /// Whether no `[io]` entry is on the bus.
    pub fn is_empty(&self) -> bool {
        self.outputs.len == 0 && self.inputs.len == 0
    }

    /// The ring positions of the subdevices that carry outputs.
    pub fn output_positions(&self) -> &[u16] {
        &self.outputs.positions[..self.outputs.positions_len]
    }

    /// The ring positions of the subdevices that carry inputs.
    pub fn input_positions(&self) -> &[u16] {
        &self.inputs.positions[..self.inputs.positions_len]
    }

    /// Writes the machine's `digital_outputs` (bit n: output n) into the output bits of
    /// the subdevice at `position` (`out`: its output process data).
    pub fn write_outputs(&self, position: u16, digital_outputs: u64, out: &mut [u8]) {
        for l in self.outputs.of(position) {
            let Some(byte) = out.get_mut(usize::from(l.bit / 8)) else {
                continue;
            };
            let mask = 1u8 << (l.bit % 8);
            if digital_outputs >> l.number & 1 != 0 {
                *byte |= mask;
            } else {
                *byte &= !mask;
            }
        }
    }

    /// Sets in `digital_inputs` (bit n: input n) the inputs read from the subdevice at
    /// `position` (`input`: its input process data); an input whose bit is beyond the
    /// data reads as off.
    pub fn read_inputs(&self, position: u16, input: &[u8], digital_inputs: &mut u64) {
        for l in self.inputs.of(position) {
            let on = input
                .get(usize::from(l.bit / 8))
                .is_some_and(|b| b >> (l.bit % 8) & 1 != 0);
            let mask = 1u64 << l.number;
            if on {
                *digital_inputs |= mask;
            } else {
                *digital_inputs &= !mask;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bit(position: u16, bit: u16) -> BusBit {
        BusBit { position, bit }
    }

    #[test]
    fn outputs_land_on_their_bits_and_leave_the_others() {
        // Output 0 on bit 0 and output 5 on bit 9 (byte 1, bit 1) of position 4; output 1
        // on bit 7 of position 6.
        let map = IoMap::new(
            [(0, bit(4, 0)), (5, bit(4, 9)), (1, bit(6, 7))].into_iter(),
            std::iter::empty(),
        );
        assert_eq!(map.output_positions(), &[4, 6]);
        let mut out = [0b0100_0000u8, 0];
        map.write_outputs(4, 0b10_0001, &mut out);
        assert_eq!(out, [0b0100_0001, 0b0000_0010]);
        map.write_outputs(4, 0, &mut out);
        assert_eq!(out, [0b0100_0000, 0]);
        let mut other = [0u8];
        map.write_outputs(6, 0b10, &mut other);
        assert_eq!(other, [0x80]);
        // A bit beyond the data is skipped, not a panic.
        let mut short: [u8; 0] = [];
        map.write_outputs(4, u64::MAX, &mut short);
    }

    #[test]
    fn inputs_are_read_into_their_numbers() {
        // Input 2 on bit 0, input 63 on bit 15 of position 1; input 7 on bit 3 of 2.
        let map = IoMap::new(
            std::iter::empty(),
            [(2, bit(1, 0)), (63, bit(1, 15)), (7, bit(2, 3))].into_iter(),
        );
        let mut word = 0u64;
        map.read_inputs(1, &[0x01, 0x80], &mut word);
        assert_eq!(word, 1 << 2 | 1 << 63);
        map.read_inputs(2, &[0x08], &mut word);
        assert_eq!(word, 1 << 2 | 1 << 63 | 1 << 7);
        map.read_inputs(1, &[0x00], &mut word);
        assert_eq!(word, 1 << 7, "bit 15 is beyond one byte: off");
        assert!(!map.is_empty());
        assert!(IoMap::new(std::iter::empty(), std::iter::empty()).is_empty());
    }
}
