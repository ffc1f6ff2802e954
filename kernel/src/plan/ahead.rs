//! The path known ahead of the first junction not yet finalized (`Planner::ahead_known`):
//! its length is kept as blocks arrive and junctions are finalized, instead of summed again
//! for every junction (that scan, ~20 blocks per push on dense chords, was ~3 % of the
//! planner's pass; issue #32). The running sum is rounded differently from a fresh sum in
//! order, so it carries a bound of that difference and decides only where the bound settles
//! the comparison; elsewhere the caller sums afresh, and the decision is always the one the
//! fresh sum gives.

/// Unit roundoff of f64.
const U: f64 = f64::EPSILON / 2.0;

/// Σ of the lengths of the blocks after one junction up to the last block summed, with a
/// bound of its rounding. Blocks and junctions by absolute number (the window's index plus
/// the blocks already dropped from its front).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct AheadSum {
    /// The junction at the end of block `junction`; `None` before the first.
    junction: Option<u64>,
    /// One past the last block summed.
    end: u64,
    sum_mm: f64,
    /// Bound of |sum_mm − the exact sum of those lengths|, mm.
    err_mm: f64,
}

/// What the running sum says of `sum ≥ need` for the same lengths summed afresh in order.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Verdict {
    Reached,
    NotReached,
    /// Too close to tell: sum afresh.
    Unsure,
}

impl AheadSum {
    /// Nothing summed after `junction` yet.
    pub(super) fn start(junction: u64) -> Self {
        AheadSum {
            junction: Some(junction),
            end: junction + 1,
            sum_mm: 0.0,
            err_mm: 0.0,
        }
    }

    /// Kept for `junction`, with its rounding bound still far below any length that matters
    /// (it grows by a few ulp per block; a fresh start resets it).
    pub(super) fn is_for(&self, junction: u64) -> bool {
        self.junction == Some(junction) && self.err_mm < 1e-9
    }

    /// One past the last block summed.
    pub(super) fn end(&self) -> u64 {
        self.end
    }

    /// Adds the next block.
    pub(super) fn add(&mut self, length_mm: f64) {
        self.sum_mm += length_mm;
        self.err_mm += 2.0 * U * (self.sum_mm.abs() + length_mm);
        self.end += 1;
    }

    /// Junction `finalized` was finalized: the sum moves on to the next one, whose first
    /// block, `first_len_mm` long, leaves it (forgotten where the sum was for another
    /// junction or had not reached that block).
    pub(super) fn next_junction(&mut self, finalized: u64, first_len_mm: f64) {
        if self.junction != Some(finalized) || self.end <= finalized + 1 {
            self.junction = None;
            return;
        }
        self.junction = Some(finalized + 1);
        self.sum_mm -= first_len_mm;
        self.err_mm += 2.0 * U * (self.sum_mm.abs() + first_len_mm);
    }

    /// Whether the same lengths summed afresh in order reach `need_mm`: that sum of m
    /// non-negative terms lies within 2·m·U of the exact one, which lies within `err_mm` of
    /// this one.
    pub(super) fn compare(&self, need_mm: f64) -> Verdict {
        let Some(j) = self.junction else {
            return Verdict::Unsure;
        };
        let m = (self.end - j - 1) as f64;
        let slack = self.err_mm + 2.0 * (m + 1.0) * U * (self.sum_mm.abs() + self.err_mm);
        if self.sum_mm - slack >= need_mm {
            Verdict::Reached
        } else if self.sum_mm + slack < need_mm {
            Verdict::NotReached
        } else {
            Verdict::Unsure
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against a fresh sum in order of random lengths, over many junctions: the verdict is
    /// never the wrong one, and decided wherever the need is 1e-9 of the sum away.
    #[test]
    fn verdicts_agree_with_a_fresh_sum_in_order() {
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        let mut rnd = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let lengths: Vec<f64> = (0..20_000).map(|_| 0.01 + 0.49 * rnd()).collect();
        let mut s = AheadSum::start(0);
        let mut unsure = 0;
        for j in 0..19_000u64 {
            if !s.is_for(j) {
                s = AheadSum::start(j);
            }
            let end = (j + 2 + (rnd() * 40.0) as u64)
                .min(lengths.len() as u64)
                .max(s.end());
            while s.end() < end {
                s.add(lengths[s.end() as usize]);
            }
            let fresh: f64 = lengths[(j + 1) as usize..end as usize].iter().sum();
            // Needs right at the fresh sum and a hair either side of it: any verdict but a
            // wrong one.
            for need in [fresh, fresh * (1.0 + 1e-15), fresh * (1.0 - 1e-15)] {
                match s.compare(need) {
                    Verdict::Reached => assert!(fresh >= need, "junction {j}"),
                    Verdict::NotReached => assert!(fresh < need, "junction {j}"),
                    Verdict::Unsure => unsure += 1,
                }
            }
            // Needs 1e-9 of the sum away from it: always decided.
            assert_eq!(s.compare(fresh * (1.0 - 1e-9)), Verdict::Reached);
            assert_eq!(s.compare(fresh * (1.0 + 1e-9)), Verdict::NotReached);
            s.next_junction(j, lengths[(j + 1) as usize]);
        }
        assert!(
            unsure > 0,
            "the needs at the sum were never too close to tell"
        );
        // The needs far from the sum are always decided.
        let mut s = AheadSum::start(5);
        s.add(1.0);
        s.add(2.0);
        assert_eq!(s.compare(2.9), Verdict::Reached);
        assert_eq!(s.compare(3.1), Verdict::NotReached);
    }
}
