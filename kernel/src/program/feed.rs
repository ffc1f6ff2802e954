//! Feed word F and the feed group G94/G95/G96/G97 (SPEC §5, §6).

use super::words::Num;
use crate::block::Feed;
use crate::diag::DiagCode;

/// Feed limit under G94/G96 (SPEC §5).
pub const MAX_FEED_MM_MIN: f64 = 90_000.0;

/// Feed limit under G95/G97 (SPEC §5: F99999 or F99.999).
pub const MAX_FEED_MM_REV: f64 = 99.999;

/// The feed group ("G6" in the manual): one of G94, G95, G96, G97 is always in force.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FeedMode {
    /// G94: feed per minute, spindle speed in rpm (power-on default).
    #[default]
    G94,
    /// G95: feed per revolution, spindle speed in rpm.
    G95,
    /// G96: constant cutting speed, feed per minute (per revolution when 3.R329 swaps).
    G96,
    /// G97: constant cutting speed, feed per revolution (per minute when 3.R329 swaps).
    G97,
}

impl FeedMode {
    /// Whether F is per revolution, after the optional G96/G97 swap of 3.R329 (SPEC §6).
    pub fn per_rev(self, swapped: bool) -> bool {
        match self {
            FeedMode::G94 => false,
            FeedMode::G95 => true,
            FeedMode::G96 => swapped,
            FeedMode::G97 => !swapped,
        }
    }

    /// Constant cutting speed (KŘR) is in force.
    pub fn css(self) -> bool {
        matches!(self, FeedMode::G96 | FeedMode::G97)
    }
}

/// Why an F word is refused.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum FeedError {
    #[error("feed F cannot be negative")]
    Negative,
    #[error(
        "feed {0} mm/rev is above the limit {MAX_FEED_MM_REV} mm/rev \
         (G95: F without a decimal point is µm/rev, with a point mm/rev)"
    )]
    AbovePerRevLimit(f64),
    #[error(
        "feed {0} mm/min is above the limit {MAX_FEED_MM_MIN} mm/min \
         (G94: F without a decimal point is mm/min, with a point m/min)"
    )]
    AbovePerMinLimit(f64),
}

impl FeedError {
    /// Stable code (tests and HMIs match it; the message may improve).
    pub fn code(&self) -> DiagCode {
        DiagCode::FeedOutOfRange
    }
}

/// Converts an F word to a feed (SPEC §5). Per minute: no point = mm/min, point = m/min.
/// Per revolution: no point = µm/rev, point = mm/rev. Limits 90000 mm/min and 99.999 mm/rev.
pub fn convert(f: Num, per_rev: bool) -> Result<Feed, FeedError> {
    if f.value < 0.0 {
        return Err(FeedError::Negative);
    }
    if per_rev {
        let mm_rev = if f.point { f.value } else { f.value / 1000.0 };
        // Compare in µm/rev so that F99.999 and F99999 are both exactly at the limit.
        if (mm_rev * 1000.0).round() > MAX_FEED_MM_REV * 1000.0 || mm_rev > MAX_FEED_MM_REV + 1e-9 {
            return Err(FeedError::AbovePerRevLimit(mm_rev));
        }
        Ok(Feed::MmPerRev(mm_rev))
    } else {
        // ×1000 is not exact in binary (4.036 × 1000 = 4035.9999…): round to 10⁻⁶ mm/min, far
        // below any written decimal, so F4.036 and F4036 give the same feed.
        let mm_min = if f.point {
            (f.value * 1e9).round() / 1e6
        } else {
            f.value
        };
        if mm_min > MAX_FEED_MM_MIN {
            return Err(FeedError::AbovePerMinLimit(mm_min));
        }
        Ok(Feed::MmPerMin(mm_min))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn n(value: f64, point: bool) -> Num {
        Num { value, point }
    }

    // SPEC §5 examples.
    #[test]
    fn units_follow_the_decimal_point() {
        assert_eq!(convert(n(1000.0, false), false), Ok(Feed::MmPerMin(1000.0)));
        assert_eq!(convert(n(0.5, true), false), Ok(Feed::MmPerMin(500.0)));
        assert_eq!(convert(n(1.2, true), false), Ok(Feed::MmPerMin(1200.0)));
        assert_eq!(convert(n(1000.0, false), true), Ok(Feed::MmPerRev(1.0)));
        assert_eq!(convert(n(0.2, true), true), Ok(Feed::MmPerRev(0.2)));
    }

    #[test]
    fn point_and_no_point_agree_exactly() {
        for k in 1..=90_000u32 {
            let with_point: f64 = format!("{}.{:03}", k / 1000, k % 1000).parse().unwrap();
            assert_eq!(
                convert(n(with_point, true), false),
                convert(n(f64::from(k), false), false),
                "F{with_point}"
            );
        }
    }

    #[test]
    fn limits() {
        assert!(convert(n(90000.0, false), false).is_ok());
        assert!(convert(n(90001.0, false), false).is_err());
        assert!(convert(n(90.001, true), false).is_err());
        assert!(convert(n(99999.0, false), true).is_ok());
        assert!(convert(n(99.999, true), true).is_ok());
        assert!(convert(n(100000.0, false), true).is_err());
        assert!(convert(n(100.0, true), true).is_err());
        assert!(convert(n(-1.0, false), false).is_err());
    }

    #[test]
    fn css_swap() {
        assert!(!FeedMode::G96.per_rev(false));
        assert!(FeedMode::G96.per_rev(true));
        assert!(FeedMode::G97.per_rev(false));
        assert!(!FeedMode::G97.per_rev(true));
    }
}

/// SPEC §5: the speed of a rotary axis at radius `radius_mm` from its centre of rotation,
/// mm/min, when the axis alone moves at `f_kpulses_min` thousands of encoder pulses per minute
/// and its encoder gives `kpulses_per_rev` thousands of pulses per revolution:
/// Fsk = F · 2πR / (thousands of pulses per revolution).
pub fn rotary_surface_speed_mm_min(
    f_kpulses_min: f64,
    radius_mm: f64,
    kpulses_per_rev: f64,
) -> f64 {
    f_kpulses_min * 2.0 * std::f64::consts::PI * radius_mm / kpulses_per_rev
}

/// The factor from the programmed F to the feed along the whole axis vector of a line from
/// `start` to `end` (linear axes in mm, rotary axes in degrees) that the planner follows
/// (docs/lathe.md, "Rotary axes"). `kpulses_per_rev[k]` > 0 marks axis `k` rotary.
///
/// - No rotary axis moves: 1 (F is the path speed).
/// - Linear and rotary axes move: F is the path speed of the linear axes (mm/min, or mm/rev);
///   the rotary axes take the same time: factor = L_all / L_linear.
/// - Only rotary axes move: F is in thousands of encoder pulses per minute (per revolution
///   under G95) along the rotary axes' vector in pulses: factor = L_degrees / L_kpulses.
pub fn rotary_feed_factor(start: &[f64], end: &[f64], kpulses_per_rev: &[f64]) -> f64 {
    let (mut lin2, mut deg2, mut kp2) = (0.0, 0.0, 0.0);
    for k in 0..start.len().min(end.len()).min(kpulses_per_rev.len()) {
        let d = end[k] - start[k];
        let kppr = kpulses_per_rev[k];
        if kppr > 0.0 {
            deg2 += d * d;
            let kp = d * kppr / 360.0;
            kp2 += kp * kp;
        } else {
            lin2 += d * d;
        }
    }
    if deg2 == 0.0 {
        1.0
    } else if lin2 > 0.0 {
        ((lin2 + deg2) / lin2).sqrt()
    } else {
        (deg2 / kp2).sqrt()
    }
}

#[cfg(test)]
mod rotary_tests {
    use super::*;

    #[test]
    fn fsk_is_f_times_2_pi_r_over_kpulses() {
        // 360 000 pulses/rev (1000 per degree): F3600 = 10 rev/min; at R100 that is
        // 2π·100·10 mm/min.
        let v = rotary_surface_speed_mm_min(3600.0, 100.0, 360.0);
        assert!((v - 2.0 * std::f64::consts::PI * 1000.0).abs() < 1e-9);
    }

    #[test]
    fn factors_of_linear_mixed_and_rotary_lines() {
        let kppr = [0.0, 0.0, 720.0]; // X, Y linear; A with 2000 pulses per degree
        assert_eq!(rotary_feed_factor(&[0.0; 3], &[3.0, 4.0, 0.0], &kppr), 1.0);
        // X30 A40: L_all 50, L_lin 30.
        let f = rotary_feed_factor(&[0.0; 3], &[30.0, 0.0, 40.0], &kppr);
        assert!((f - 50.0 / 30.0).abs() < 1e-12);
        // A90 alone: 90° = 180 kpulses; F kpulses/min → F/2 °/min.
        let f = rotary_feed_factor(&[0.0; 3], &[0.0, 0.0, 90.0], &kppr);
        assert!((f - 0.5).abs() < 1e-12);
    }
}
