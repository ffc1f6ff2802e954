//! Time series of the 4 ms ticks kept at the picture's resolution: per time bucket the range
//! of each quantity and the block boundaries in it. Buckets double in length (merging pairs)
//! whenever their number exceeds the budget, so memory stays bounded for any run time.

use kernel::MAX_AXES;

/// One time bucket.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bucket {
    /// Ticks recorded in the bucket (0: no data, e.g. outside the page).
    pub ticks: u32,
    pub v_min: f64,
    pub v_max: f64,
    pub feed_min: f64,
    pub feed_max: f64,
    pub acc_min: [f64; MAX_AXES],
    pub acc_max: [f64; MAX_AXES],
    /// Block boundaries (changes of the source block) in the bucket.
    pub boundaries: u32,
    /// Of those, boundaries after a red junction (speed drop or stop, SPEC §7.5).
    pub red_boundaries: u32,
}

impl Bucket {
    const EMPTY: Bucket = Bucket {
        ticks: 0,
        v_min: f64::INFINITY,
        v_max: f64::NEG_INFINITY,
        feed_min: f64::INFINITY,
        feed_max: f64::NEG_INFINITY,
        acc_min: [f64::INFINITY; MAX_AXES],
        acc_max: [f64::NEG_INFINITY; MAX_AXES],
        boundaries: 0,
        red_boundaries: 0,
    };

    fn merge(&mut self, o: &Bucket) {
        self.ticks += o.ticks;
        self.v_min = self.v_min.min(o.v_min);
        self.v_max = self.v_max.max(o.v_max);
        self.feed_min = self.feed_min.min(o.feed_min);
        self.feed_max = self.feed_max.max(o.feed_max);
        for i in 0..MAX_AXES {
            self.acc_min[i] = self.acc_min[i].min(o.acc_min[i]);
            self.acc_max[i] = self.acc_max[i].max(o.acc_max[i]);
        }
        self.boundaries += o.boundaries;
        self.red_boundaries += o.red_boundaries;
    }
}

/// What one tick contributes.
#[derive(Clone, Copy, Debug, Default)]
pub struct Sample {
    pub v: f64,
    pub feed: f64,
    pub acc: [f64; MAX_AXES],
    pub boundary: bool,
    pub red_boundary: bool,
}

/// Bucketed series starting at the first recorded tick.
#[derive(Clone, Debug)]
pub struct Series {
    pub buckets: Vec<Bucket>,
    /// Ticks per bucket (a power of two).
    pub ticks_per_bucket: u64,
    /// Index of the first recorded tick.
    pub first_tick: Option<u64>,
    pub last_tick: u64,
    budget: usize,
}

impl Series {
    pub fn new(budget: usize) -> Self {
        Series {
            buckets: Vec::new(),
            ticks_per_bucket: 1,
            first_tick: None,
            last_tick: 0,
            budget: budget.max(2),
        }
    }

    pub fn record(&mut self, tick: u64, s: &Sample) {
        let first = *self.first_tick.get_or_insert(tick);
        self.last_tick = tick;
        let mut idx = ((tick - first) / self.ticks_per_bucket) as usize;
        while idx >= self.budget {
            self.halve();
            idx = ((tick - first) / self.ticks_per_bucket) as usize;
        }
        if self.buckets.len() <= idx {
            self.buckets.resize(idx + 1, Bucket::EMPTY);
        }
        let b = &mut self.buckets[idx];
        b.merge(&Bucket {
            ticks: 1,
            v_min: s.v,
            v_max: s.v,
            feed_min: s.feed,
            feed_max: s.feed,
            acc_min: s.acc,
            acc_max: s.acc,
            boundaries: u32::from(s.boundary),
            red_boundaries: u32::from(s.red_boundary),
        });
    }

    /// Merges neighbouring buckets: twice the ticks per bucket.
    fn halve(&mut self) {
        let merged = self
            .buckets
            .chunks(2)
            .map(|c| {
                let mut b = c[0];
                if let Some(o) = c.get(1) {
                    b.merge(o);
                }
                b
            })
            .collect();
        self.buckets = merged;
        self.ticks_per_bucket *= 2;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounded_and_lossless_for_extremes() {
        let mut s = Series::new(100);
        for t in 0..10_000u64 {
            s.record(
                t + 50,
                &Sample {
                    v: (t % 7) as f64,
                    feed: 6.0,
                    boundary: t % 10 == 0,
                    ..Sample::default()
                },
            );
        }
        assert!(s.buckets.len() <= 100);
        assert_eq!(s.first_tick, Some(50));
        assert_eq!(s.buckets.iter().map(|b| b.ticks).sum::<u32>(), 10_000);
        assert_eq!(s.buckets.iter().map(|b| b.boundaries).sum::<u32>(), 1000);
        assert_eq!(s.buckets.iter().fold(0.0f64, |m, b| m.max(b.v_max)), 6.0);
    }
}
