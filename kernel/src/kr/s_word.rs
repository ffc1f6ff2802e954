//! What G96/G97 and their S word mean under R329 decade 3 (SPEC §6).
//!
//! Standard: G96 = KŘR with feed in mm/min, G97 = KŘR with feed in mm/rev, S = cutting speed in
//! 0.1 m/min (`S500` = 50 m/min). R329 d3 = 1 swaps G96 and G97, 2 reads S in m/min, 3 does both
//! (the setting the manual recommends for lathes).

use super::config::KrConfigError;
use crate::constants::Constants;

/// The two KŘR codes as written in the program.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CssCode {
    G96,
    G97,
}

/// Whether F is a feed per minute or per spindle revolution (SPEC §5).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FeedBasis {
    PerMinute,
    PerRevolution,
}

/// Decade 3 of R329: how G96/G97 and S are read.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SWordMode {
    /// G96 and G97 swapped (G96 = feed per revolution).
    pub swap_g96_g97: bool,
    /// S is the cutting speed in m/min instead of 0.1 m/min.
    pub s_in_m_min: bool,
}

impl SWordMode {
    /// Reads decade 3 of R329 (0..3; other digits are refused).
    pub fn from_constants(c: &Constants) -> Result<Self, KrConfigError> {
        match c.decade(329, 3) {
            0..=3 => Ok(SWordMode {
                swap_g96_g97: c.css_g96_g97_swapped(),
                s_in_m_min: c.css_s_in_m_min(),
            }),
            d => Err(KrConfigError::R329Decade3(d)),
        }
    }

    /// Feed basis that `code` selects.
    pub fn feed_basis(self, code: CssCode) -> FeedBasis {
        let per_rev = match code {
            CssCode::G96 => self.swap_g96_g97,
            CssCode::G97 => !self.swap_g96_g97,
        };
        if per_rev {
            FeedBasis::PerRevolution
        } else {
            FeedBasis::PerMinute
        }
    }

    /// Cutting speed in mm/min of an S word written under G96/G97.
    pub fn cutting_speed_mm_min(self, s_word: f64) -> f64 {
        if self.s_in_m_min {
            s_word * 1000.0
        } else {
            s_word * 100.0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mode(d3: f64) -> SWordMode {
        let mut c = Constants::new();
        c.set(329, d3 / 10.0);
        SWordMode::from_constants(&c).unwrap()
    }

    // SPEC §6: `S500` = 50 m/min in the standard setting.
    #[test]
    fn s500_is_50_m_min() {
        assert_eq!(mode(0.0).cutting_speed_mm_min(500.0), 50_000.0);
    }

    // SPEC §6 lathe example, R329 d3 = 3: `N20 G96 G1 F200 S90 X50` = 90 m/min, feed per rev.
    #[test]
    fn lathe_example_with_swap() {
        let m = mode(3.0);
        assert_eq!(m.feed_basis(CssCode::G96), FeedBasis::PerRevolution);
        assert_eq!(m.cutting_speed_mm_min(90.0), 90_000.0);
    }

    // Same block without the swap: `N20 G97 G1 F200 S900 X50`.
    #[test]
    fn lathe_example_without_swap() {
        let m = mode(0.0);
        assert_eq!(m.feed_basis(CssCode::G97), FeedBasis::PerRevolution);
        assert_eq!(m.feed_basis(CssCode::G96), FeedBasis::PerMinute);
        assert_eq!(m.cutting_speed_mm_min(900.0), 90_000.0);
    }

    #[test]
    fn single_variants() {
        let swap = mode(1.0);
        assert_eq!(swap.feed_basis(CssCode::G96), FeedBasis::PerRevolution);
        assert_eq!(swap.cutting_speed_mm_min(900.0), 90_000.0);
        let m_min = mode(2.0);
        assert_eq!(m_min.feed_basis(CssCode::G96), FeedBasis::PerMinute);
        assert_eq!(m_min.cutting_speed_mm_min(90.0), 90_000.0);
    }

    #[test]
    fn other_digits_are_refused() {
        let mut c = Constants::new();
        c.set(329, 0.4);
        assert_eq!(
            SWordMode::from_constants(&c),
            Err(KrConfigError::R329Decade3(4))
        );
    }
}
