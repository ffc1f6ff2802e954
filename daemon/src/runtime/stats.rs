//! Tick statistics of the real-time loop: wake-up lateness against the absolute deadline and
//! overruns. Recording never allocates (the histogram is sized once, auto-resize off).

use hdrhistogram::Histogram;

/// Largest lateness the histogram resolves, µs; later wake-ups are recorded as this value
/// (and counted as overruns anyway).
const MAX_LATENESS_US: u64 = 10_000_000;

/// Summary published in the status snapshot.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TickSummary {
    pub ticks: u64,
    /// Deadlines missed: ticks that woke more than one period late (the loop skips the missed
    /// grid points rather than drifting).
    pub overruns: u64,
    pub lateness_p50_us: u32,
    pub lateness_p99_us: u32,
    pub lateness_max_us: u32,
}

pub struct TickStats {
    hist: Histogram<u64>,
    summary: TickSummary,
}

impl Default for TickStats {
    fn default() -> Self {
        Self::new()
    }
}

impl TickStats {
    pub fn new() -> Self {
        let mut hist = Histogram::new_with_bounds(1, MAX_LATENESS_US, 2)
            .expect("static histogram bounds are valid");
        hist.auto(false);
        TickStats {
            hist,
            summary: TickSummary::default(),
        }
    }

    /// Records one tick's lateness and how many grid points it had to skip.
    pub fn record(&mut self, lateness_ns: u64, missed: u64) {
        let us = (lateness_ns / 1000).min(MAX_LATENESS_US);
        self.hist.saturating_record(us);
        self.summary.ticks += 1;
        self.summary.overruns += missed;
        self.summary.lateness_max_us = self.summary.lateness_max_us.max(us as u32);
    }

    /// Refreshes the percentiles (a walk over the buckets: call every few dozen ticks, not
    /// every tick).
    pub fn refresh(&mut self) {
        self.summary.lateness_p50_us = self.hist.value_at_quantile(0.5) as u32;
        self.summary.lateness_p99_us = self.hist.value_at_quantile(0.99) as u32;
    }

    pub fn summary(&self) -> TickSummary {
        self.summary
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_and_overruns() {
        let mut s = TickStats::new();
        for i in 0..1000u64 {
            s.record(i * 1000, 0);
        }
        s.record(9_000_000, 2);
        s.refresh();
        let m = s.summary();
        assert_eq!(m.ticks, 1001);
        assert_eq!(m.overruns, 2);
        assert!((495..=505).contains(&m.lateness_p50_us), "{m:?}");
        assert!((985..=1000).contains(&m.lateness_p99_us), "{m:?}");
        assert_eq!(m.lateness_max_us, 9000);
    }
}
