//! A bounded memo of segment limits for repeated geometry: dense CAM code repeats the same
//! arcs, corners and transitions (translated along the path, which leaves the inputs of
//! the limit searches bit for bit the same), and the searches in [`crate::budget`] are
//! the planner's main cost.
//!
//! A key holds the exact bit patterns of every input the limits are computed from (see
//! [`crate::budget::limits_key`]), so a hit returns exactly what the computation would.
//! The table has a fixed number of slots, allocated once; a new entry replaces the one in
//! its slot, so the memo never grows with the program. The same holds for the arc-length
//! tables of transitions, which depend on the coefficients of degree 1 and up only.

use kerf_geom::TABLE_POINTS;

/// Words of a key: enough for the largest key (a transition: 15 coefficients and the
/// scalars).
pub(crate) const KEY_WORDS: usize = 24;

/// Slots of a table: 2,048 of at most 500 bytes (a key and an arc-length table), at most
/// 1 MiB per table. The CAM pattern of 1 mm lines and arcs over a 100 mm field needs
/// about a thousand entries in flight: 512 slots missed 5 % there, 2,048 slots 0.4 %.
const SLOTS: usize = 2048;

/// Tag of the arc-length keys (the limits' keys use 1 and 2, see
/// [`crate::budget::limits_key`]).
pub(crate) const KEY_ARC_LENGTH: u64 = 3;

/// A key: the exact bits of the inputs, padded with zeros (the first word tells the kinds
/// of key apart).
pub(crate) type Key = [u64; KEY_WORDS];

/// Limits of a segment: `(v, a, j)` at the design override and, where asked, at the
/// highest override.
pub(crate) type Limits = ((f64, f64, f64), Option<(f64, f64, f64)>);

/// Arc length and table of a transition (see `Transition::with_arc_length`), `None` if it
/// has none.
pub(crate) type ArcLength = Option<(f64, [f64; TABLE_POINTS])>;

/// The memo of segment limits.
pub(crate) type LimitsMemo = Memo<Limits>;
/// The memo of transitions' arc-length tables.
pub(crate) type ArcMemo = Memo<ArcLength>;

#[derive(Clone, Copy)]
struct Slot<V> {
    key: Key,
    value: V,
}

/// The memo: a direct-mapped table of [`SLOTS`] entries.
pub(crate) struct Memo<V> {
    slots: Vec<Option<Slot<V>>>,
}

impl<V> std::fmt::Debug for Memo<V> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let used = self.slots.iter().filter(|s| s.is_some()).count();
        write!(f, "Memo {{ used: {used} of {} }}", self.slots.len())
    }
}

impl<V: Copy> Memo<V> {
    pub(crate) fn new() -> Self {
        Memo {
            slots: vec![None; SLOTS],
        }
    }

    fn slot_of(key: &Key) -> usize {
        // Multiply-rotate mixing of every word; any spread will do, equality decides.
        let mut h: u64 = 0;
        for &w in key {
            h = (h.rotate_left(5) ^ w).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
        }
        (h >> 32) as usize % SLOTS
    }

    /// The value stored under `key`, if any.
    pub(crate) fn get(&self, key: &Key) -> Option<V> {
        match &self.slots[Self::slot_of(key)] {
            Some(s) if s.key == *key => Some(s.value),
            _ => None,
        }
    }

    /// Stores `value` under `key` (replacing whatever shared its slot).
    pub(crate) fn put(&mut self, key: Key, value: V) {
        let i = Self::slot_of(&key);
        self.slots[i] = Some(Slot { key, value });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stores_by_exact_key_and_stays_bounded() {
        let mut memo = LimitsMemo::new();
        let mut key = [0u64; KEY_WORDS];
        key[0] = 1;
        key[1] = 1.0f64.to_bits();
        memo.put(key, ((1.0, 2.0, 3.0), None));
        assert_eq!(memo.get(&key), Some(((1.0, 2.0, 3.0), None)));
        // One bit different: another key.
        let mut other = key;
        other[1] ^= 1;
        assert_eq!(memo.get(&other), None);
        // Many more keys than slots: the table keeps its size.
        for i in 0..10 * SLOTS as u64 {
            let mut k = [0u64; KEY_WORDS];
            k[0] = 2;
            k[1] = i;
            memo.put(k, ((i as f64, 0.0, 0.0), Some((0.0, 0.0, 0.0))));
            assert_eq!(memo.get(&k).map(|v| v.0.0), Some(i as f64));
        }
        assert_eq!(memo.slots.len(), SLOTS);
    }
}
