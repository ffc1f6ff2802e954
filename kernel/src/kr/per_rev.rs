//! Feed per revolution and spindle speed (SPEC §5): V = S·β, βmax = Vmax/S, Smax = Vmax/βmax.

/// Feed rate of the axes from spindle speed and feed per revolution: V = S·β (SPEC §5).
pub fn feed_rate_mm_min(spindle_rpm: f64, feed_mm_rev: f64) -> f64 {
    spindle_rpm * feed_mm_rev
}

/// Largest feed per revolution the axes can follow at spindle speed `spindle_rpm`:
/// βmax = Vmax/S (SPEC §5). `None` when the spindle stands (any β is then reachable).
pub fn max_feed_mm_rev(max_feed_rate_mm_min: f64, spindle_rpm: f64) -> Option<f64> {
    (spindle_rpm.abs() > 0.0).then(|| max_feed_rate_mm_min / spindle_rpm.abs())
}

/// Largest spindle speed at which the axes can still follow feed per revolution
/// `feed_mm_rev`: Smax = Vmax/βmax (SPEC §5). `None` for a zero feed (no limit).
pub fn max_spindle_rpm(max_feed_rate_mm_min: f64, feed_mm_rev: f64) -> Option<f64> {
    (feed_mm_rev.abs() > 0.0).then(|| max_feed_rate_mm_min / feed_mm_rev.abs())
}

#[cfg(test)]
mod tests {
    use super::*;

    // SPEC §5 / seed manual: Vmax = 2000 mm/min, S = 1000 rpm → βmax = 2 mm/rev.
    #[test]
    fn manual_example_beta_max() {
        assert_eq!(max_feed_mm_rev(2000.0, 1000.0), Some(2.0));
        assert_eq!(max_spindle_rpm(2000.0, 2.0), Some(1000.0));
        assert_eq!(feed_rate_mm_min(1000.0, 2.0), 2000.0);
    }

    #[test]
    fn standing_spindle_and_zero_feed_have_no_limit() {
        assert_eq!(max_feed_mm_rev(2000.0, 0.0), None);
        assert_eq!(max_spindle_rpm(2000.0, 0.0), None);
        // M4 (negative speed) limits like M3.
        assert_eq!(max_feed_mm_rev(2000.0, -500.0), Some(4.0));
    }
}
