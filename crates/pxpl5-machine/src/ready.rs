//! The set of units the machine's loop must look at in an instant: a bit per unit, so an
//! instant costs the units that can act, not every unit. The main job's 16 GPs were each looked
//! at twice in each of 2.2 M instants; looking only at those that can act (and parking a refused
//! sender until its queue frees words) took its hemisphere run from 19.60 G to 16.61 G
//! instructions, by callgrind.

/// Unit indices `0 .. n`, each in the set or not; iterated in ascending order, the order in
/// which the loop acts on them.
#[derive(Clone, Debug)]
pub(crate) struct Ready {
    words: Vec<u64>,
}

impl Ready {
    /// The set of `n` units, every one in it (a unit starts able to act).
    pub fn full(n: usize) -> Ready {
        let mut words = vec![u64::MAX; n.div_ceil(64)];
        if !n.is_multiple_of(64)
            && let Some(last) = words.last_mut()
        {
            *last = (1 << (n % 64)) - 1;
        }
        Ready { words }
    }

    /// Put unit `i` in the set or take it out.
    pub fn set(&mut self, i: usize, ready: bool) {
        let (w, b) = (i / 64, i % 64);
        if ready {
            self.words[w] |= 1 << b;
        } else {
            self.words[w] &= !(1 << b);
        }
    }

    /// The first unit in the set at index `from` or above.
    pub fn next_from(&self, from: usize) -> Option<usize> {
        let mut w = from / 64;
        let mut bits = *self.words.get(w)? & (u64::MAX << (from % 64));
        loop {
            if bits != 0 {
                return Some(w * 64 + bits.trailing_zeros() as usize);
            }
            w += 1;
            bits = *self.words.get(w)?;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Ready;

    /// Every member is found once, in ascending order, across word boundaries.
    #[test]
    fn iterates_members_in_order() {
        for n in [1, 5, 63, 64, 65, 130] {
            let mut r = Ready::full(n);
            let all: Vec<usize> =
                std::iter::successors(r.next_from(0), |&i| r.next_from(i + 1)).collect();
            assert_eq!(all, (0..n).collect::<Vec<_>>(), "n = {n}");
            for i in (0..n).filter(|i| i % 3 != 0) {
                r.set(i, false);
            }
            let some: Vec<usize> =
                std::iter::successors(r.next_from(0), |&i| r.next_from(i + 1)).collect();
            assert_eq!(some, (0..n).step_by(3).collect::<Vec<_>>(), "n = {n}");
            assert_eq!(r.next_from(0), Some(0));
            for i in (0..n).step_by(3) {
                r.set(i, false);
            }
            assert_eq!(r.next_from(0), None, "n = {n}");
        }
    }
}
