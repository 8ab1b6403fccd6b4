//! GPU residency: fixed pools of equal slots in one buffer each, keyed by what they hold,
//! the least recently used slot reused, never one used in the current frame.

use std::collections::HashMap;
use std::hash::Hash;

/// A fixed pool of equal slots in one GPU buffer, keyed by what they hold (a quad, or a
/// layer source at a quad), least recently used reused.
pub(crate) struct SlotPool<K: Eq + Hash + Copy = crate::ecm::QuadId> {
    pub(crate) capacity: u32,
    pub(crate) slots: HashMap<K, (u32, u64)>,
    free: Vec<u32>,
}

impl<K: Eq + Hash + Copy> SlotPool<K> {
    pub(crate) fn new(capacity: u32) -> SlotPool<K> {
        SlotPool { capacity, slots: HashMap::new(), free: (0..capacity).rev().collect() }
    }

    pub(crate) fn get(&self, quad: K) -> Option<u32> {
        self.slots.get(&quad).map(|s| s.0)
    }

    pub(crate) fn touch(&mut self, quad: K, frame: u64) -> Option<u32> {
        self.slots.get_mut(&quad).map(|s| {
            s.1 = frame;
            s.0
        })
    }

    /// A slot for `quad`: a free one, or the least recently used one not used in `frame`.
    pub(crate) fn allocate(&mut self, quad: K, frame: u64) -> Option<u32> {
        if let Some(slot) = self.touch(quad, frame) {
            return Some(slot); // rewritten in place
        }
        let slot = match self.free.pop() {
            Some(s) => s,
            None => {
                let (&victim, &(slot, _)) =
                    self.slots.iter().filter(|(_, (_, used))| *used < frame).min_by_key(|(_, (_, used))| *used)?;
                self.slots.remove(&victim);
                slot
            }
        };
        self.slots.insert(quad, (slot, frame));
        Some(slot)
    }
}

#[cfg(test)]
mod tests {
    use super::SlotPool;

    #[test]
    fn slots_are_reused_least_recently_used_first_never_from_this_frame() {
        let mut pool: SlotPool<u32> = SlotPool::new(2);
        assert_eq!(pool.allocate(10, 1), Some(0));
        pool.allocate(11, 2);
        assert!(pool.allocate(12, 2).is_some(), "10 (frame 1) is reused in frame 2");
        assert_eq!(pool.get(10), None);
        assert_eq!(pool.allocate(13, 2), None, "both slots are used in frame 2");
        let eleven = pool.get(11);
        assert_eq!(pool.allocate(11, 3), eleven, "a key that has a slot keeps it");
        assert_eq!(pool.slots.len(), 2);
    }
}
