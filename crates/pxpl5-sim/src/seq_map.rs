//! [`SeqMap`]: a map from sequence numbers handed out in order (0, 1, 2, ...) to the values of
//! the ones still alive, for things that are numbered as they start and end roughly in order
//! (messages between their send and their last use).
//!
//! A `BTreeMap` keyed by the number did the same at several hundred host instructions an insert
//! or remove, and moved its values within its nodes on every remove; here each operation is an
//! index into a circular buffer of slots, from the oldest live number to the newest one inserted.
//! The price is memory: a slot for every number between the oldest live one and the newest, so a
//! value that lives long while many later ones come and go holds their emptied slots until it
//! is removed.

use std::collections::VecDeque;

/// Values keyed by sequence number, for numbers inserted in increasing order (a number may be
/// skipped) and removed in any order.
#[derive(Clone, Debug)]
pub struct SeqMap<T> {
    /// The number of `slots[0]`: every number below it has been removed (or skipped).
    base: u64,
    /// `slots[i]` holds number `base + i`; the front slot, if any, is always full.
    slots: VecDeque<Option<T>>,
    len: usize,
}

impl<T> Default for SeqMap<T> {
    fn default() -> SeqMap<T> {
        SeqMap::new()
    }
}

impl<T> SeqMap<T> {
    pub fn new() -> SeqMap<T> {
        SeqMap {
            base: 0,
            slots: VecDeque::new(),
            len: 0,
        }
    }

    /// Insert value `v` as number `n`; `Err(v)` back, and nothing inserted, if `n` is not above
    /// every number inserted before (numbers are handed out in order: the caller has a bug).
    pub fn insert(&mut self, n: u64, v: T) -> Result<(), T> {
        let next = self.base + self.slots.len() as u64;
        if n < next {
            return Err(v);
        }
        if self.slots.is_empty() {
            self.base = n;
        } else {
            // A skipped number holds an empty slot until the ones before it are removed.
            self.slots.extend((next..n).map(|_| None));
        }
        self.slots.push_back(Some(v));
        self.len += 1;
        Ok(())
    }

    fn index(&self, n: u64) -> Option<usize> {
        let i = n.checked_sub(self.base)?;
        (i < self.slots.len() as u64).then_some(i as usize)
    }

    pub fn get(&self, n: u64) -> Option<&T> {
        self.slots.get(self.index(n)?)?.as_ref()
    }

    pub fn get_mut(&mut self, n: u64) -> Option<&mut T> {
        let i = self.index(n)?;
        self.slots.get_mut(i)?.as_mut()
    }

    /// Remove number `n`, returning its value if it was there.
    pub fn remove(&mut self, n: u64) -> Option<T> {
        let i = self.index(n)?;
        let v = self.slots[i].take()?;
        self.len -= 1;
        // Keep the front slot full: drop the emptied slots of the oldest numbers.
        while let Some(None) = self.slots.front() {
            self.slots.pop_front();
            self.base += 1;
        }
        Some(v)
    }

    /// How many values it holds.
    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;

    use super::*;

    /// A seeded mix of inserts (in order, some numbers skipped), removes in any order and
    /// look-ups, checked step by step against a `BTreeMap`.
    #[test]
    fn agrees_with_a_btree_map() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let mut map = SeqMap::new();
        let mut model = BTreeMap::new();
        let mut n = 0u64;
        for step in 0..20_000u64 {
            match next() % 4 {
                0 | 1 => {
                    n += 1 + next() % 3;
                    assert_eq!(map.insert(n, step), Ok(()));
                    model.insert(n, step);
                }
                2 => {
                    let k = n.saturating_sub(next() % 40);
                    assert_eq!(map.remove(k), model.remove(&k), "remove {k}");
                }
                _ => {
                    let k = n.saturating_sub(next() % 40);
                    if let Some(v) = map.get_mut(k) {
                        *v += 1;
                    }
                    if let Some(v) = model.get_mut(&k) {
                        *v += 1;
                    }
                    assert_eq!(map.get(k), model.get(&k), "get {k}");
                }
            }
            assert_eq!(map.len(), model.len());
            assert_eq!(map.is_empty(), model.is_empty());
        }
        // Every number handed out: the same value, or none, in both.
        for k in 0..=n {
            assert_eq!(map.get(k), model.get(&k), "number {k} at the end");
        }
    }

    #[test]
    fn emptied_slots_are_dropped_from_the_front() {
        let mut map = SeqMap::new();
        for n in 0..100 {
            assert_eq!(map.insert(n, n), Ok(()));
        }
        for n in 1..100 {
            map.remove(n);
        }
        // Number 0 is still alive: every later slot stays.
        assert_eq!(map.slots.len(), 100);
        assert_eq!(map.remove(0), Some(0));
        assert!(map.slots.is_empty() && map.is_empty());
        // A map emptied starts again at the next number inserted.
        assert_eq!(map.insert(500, 1), Ok(()));
        assert_eq!(
            (map.base, map.slots.len(), map.get(500)),
            (500, 1, Some(&1))
        );
        assert_eq!(map.get(499), None);
    }

    #[test]
    fn numbers_out_of_order_are_refused() {
        let mut map = SeqMap::new();
        assert_eq!(map.insert(5, 'a'), Ok(()));
        assert_eq!(map.insert(5, 'b'), Err('b'));
        assert_eq!(map.insert(4, 'c'), Err('c'));
        assert_eq!((map.len(), map.get(5)), (1, Some(&'a')));
        // Below the oldest live number, once those before it are gone, too.
        assert_eq!(map.insert(6, 'd'), Ok(()));
        assert_eq!(map.remove(5), Some('a'));
        assert_eq!(map.insert(5, 'e'), Err('e'));
    }
}
