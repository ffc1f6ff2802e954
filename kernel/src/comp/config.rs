//! Settings of radius compensation, read once from the machine constants (SPEC §4).
//!
//! Every field names what it means and cites its constant and decade; the compensator never
//! looks at raw constants.

use crate::constants::Constants;

/// What happens at a junction without a common tangent (8.R339, SPEC §4.3).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CornerMode {
    /// 8.R339 = 0: always the intersection of the equidistants; none → error.
    #[default]
    Intersection,
    /// 8.R339 = 1: an arc at outside corners turning more than the limit; else intersection.
    ArcAboveLimit,
    /// 8.R339 = 2: as `ArcAboveLimit`, and an arc wherever no intersection exists.
    ArcAboveLimitOrMissing,
    /// 8.R339 = 4: an arc only where no intersection exists.
    ArcIfMissing,
}

/// R397: equidistant check and optimisation (SPEC §4.5).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct EquidistantCheck {
    /// d1 = 0: check (and allow optimisation) on.
    pub check: bool,
    /// d2 = 0: a failed check gives a warning with the block number.
    pub warn: bool,
    /// d3 = 1: 3-block optimisation (needs the check on; the manual's "needs d1 = 1"
    /// contradicts d1's own meaning and is read as d1 = 0, as SPEC §4.5 says).
    pub optimise_3_blocks: bool,
    /// d4 = 1: 4-block optimisation (needs d3).
    pub optimise_4_blocks: bool,
    /// d5 = 1: an arc whose equidistant runs backwards is replaced by its chord.
    pub complementary_arc_to_line: bool,
    /// d6 = 1: G41 ↔ G42 may change directly (jet cleaning).
    pub allow_side_change: bool,
    /// d7 = 1: an arc whose end point is not on its circle is replaced by its chord.
    pub arc_off_circle_to_line: bool,
    /// d8 = 1: an arc whose equidistant has no intersection with its neighbour's is replaced
    /// by its chord.
    pub arc_without_intersection_to_line: bool,
}

/// R764 (exit optimisation) or R765 (position test): a percentage of the radius and two flags.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PercentRule {
    /// d1..3 as a percentage of the tool radius (0 reads as the manual's default).
    pub percent: f64,
    /// d7 = 1: report.
    pub report: bool,
    /// d8 = 1: optimise.
    pub optimise: bool,
}

/// All settings of the compensator. `Default` is compensation enabled (8.R95 = 1) with every
/// other constant zero: intersections only, R397 check on with warnings, no optimisation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CompConfig {
    /// 8.R95 = 1: radius compensation with equidistant is available.
    pub enabled: bool,
    /// 8.R339.
    pub corner_mode: CornerMode,
    /// R339 d1..6: arcs are inserted only where the tangents turn by more than this, degrees.
    pub arc_insertion_limit_deg: f64,
    /// R339 sign `-`: an information message for every inserted arc.
    pub report_inserted_arcs: bool,
    /// 7.R339 = 1: G40 may stand in a block without motion in the plane.
    pub g40_without_motion: bool,
    /// R234: below this angle between tangents, no intersection is computed, degrees.
    pub continuity_limit_deg: f64,
    pub check: EquidistantCheck,
    /// R764: exit optimisation on the last working block before a rapid.
    pub exit: PercentRule,
    /// R765: position test of the equidistant at corners.
    pub position: PercentRule,
    /// R55: how far an arc end point may lie off its circle, mm (used by R397 d7).
    pub arc_end_tolerance_mm: f64,
    /// 6.R765 = 1: a gouge found by the whole-run check is an error (the program is refused),
    /// not a warning (docs/compensation.md decision 19; a decade the manual leaves unused).
    pub refuse_gouges: bool,
}

impl Default for CompConfig {
    fn default() -> Self {
        CompConfig {
            enabled: true,
            corner_mode: CornerMode::Intersection,
            arc_insertion_limit_deg: 0.0,
            report_inserted_arcs: false,
            g40_without_motion: false,
            continuity_limit_deg: 0.0,
            check: EquidistantCheck {
                check: true,
                warn: true,
                ..EquidistantCheck::default()
            },
            exit: PercentRule {
                percent: 150.0,
                ..PercentRule::default()
            },
            position: PercentRule {
                percent: 300.0,
                ..PercentRule::default()
            },
            arc_end_tolerance_mm: DEFAULT_ARC_END_TOLERANCE_MM,
            refuse_gouges: false,
        }
    }
}

/// Arc end tolerance of `CompConfig::default()` (R55 default, 10 µm). From the constants it is
/// `Constants::arc_tolerance_mm`, the interpreter's too.
pub const DEFAULT_ARC_END_TOLERANCE_MM: f64 = 0.010;

impl CompConfig {
    /// How much closer than the radius `radius_mm` the tool centre may come to the contour
    /// without a gouge being reported: 1 µm, plus the error of R234's perpendicular point
    /// r·(1 − cos(α/2)) which the machinist chose (SPEC §4.4).
    pub fn gouge_tolerance_mm(&self, radius_mm: f64) -> f64 {
        let half = self.continuity_limit_deg.to_radians() / 2.0;
        super::gouge::GOUGE_TOLERANCE_MM + radius_mm * (1.0 - half.cos())
    }

    /// Reads R95, R234, R339, R397, R764, R765 and R55 (SPEC §1 decades, §4).
    pub fn from_constants(c: &Constants) -> Self {
        let corner_mode = match c.decade(339, 8) {
            1 => CornerMode::ArcAboveLimit,
            2 => CornerMode::ArcAboveLimitOrMissing,
            4 => CornerMode::ArcIfMissing,
            // 0 and values the manual does not define: the safe, documented behaviour.
            _ => CornerMode::Intersection,
        };
        let d397 = |d| c.decade(397, d) == 1;
        let check = !d397(1);
        let pct = |r: u16, default: f64| match c.field_digits(r, 1, 3) {
            0 => default,
            p => p as f64,
        };
        CompConfig {
            enabled: c.decade(95, 8) == 1,
            corner_mode,
            arc_insertion_limit_deg: c.field_value(339, 1, 6),
            report_inserted_arcs: c.is_negative(339),
            g40_without_motion: c.decade(339, 7) == 1,
            continuity_limit_deg: c.get(234).abs(),
            check: EquidistantCheck {
                check,
                warn: check && !d397(2),
                optimise_3_blocks: check && d397(3),
                optimise_4_blocks: check && d397(3) && d397(4),
                complementary_arc_to_line: d397(5),
                allow_side_change: d397(6),
                arc_off_circle_to_line: d397(7),
                arc_without_intersection_to_line: d397(8),
            },
            exit: PercentRule {
                percent: pct(764, 150.0),
                report: c.decade(764, 7) == 1,
                optimise: c.decade(764, 8) == 1,
            },
            position: PercentRule {
                percent: pct(765, 300.0),
                report: c.decade(765, 7) == 1,
                optimise: c.decade(765, 8) == 1,
            },
            // One accessor for the interpreter and the compensator (issue #14).
            arc_end_tolerance_mm: c.arc_tolerance_mm(),
            refuse_gouges: c.decade(765, 6) == 1,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // SPEC §4.5 recommended flame-cutter set.
    #[test]
    fn flame_cutter_constants() {
        let mut c = Constants::new();
        c.set(95, 10000.0);
        c.set(234, 0.8);
        c.set(339, -21140.0);
        c.set(397, 1011.110);
        c.set(764, 11000.0);
        c.set(765, 11000.0);
        let cfg = CompConfig::from_constants(&c);
        assert!(cfg.enabled);
        assert_eq!(cfg.corner_mode, CornerMode::ArcAboveLimitOrMissing);
        assert_eq!(cfg.arc_insertion_limit_deg, 140.0);
        assert!(cfg.report_inserted_arcs);
        assert!(cfg.g40_without_motion);
        assert_eq!(cfg.continuity_limit_deg, 0.8);
        assert!(cfg.check.check && !cfg.check.warn);
        assert!(cfg.check.optimise_3_blocks && cfg.check.optimise_4_blocks);
        assert!(cfg.check.complementary_arc_to_line);
        assert!(!cfg.check.allow_side_change);
        assert!(cfg.check.arc_off_circle_to_line && !cfg.check.arc_without_intersection_to_line);
        assert_eq!(cfg.exit.percent, 150.0);
        assert!(cfg.exit.report && cfg.exit.optimise);
        assert_eq!(cfg.position.percent, 300.0);
        assert!(!cfg.refuse_gouges);
        c.set(765, 11100.0);
        assert!(CompConfig::from_constants(&c).refuse_gouges);
    }

    #[test]
    fn r397_d1_switches_everything_off() {
        let mut c = Constants::new();
        c.set(397, 11111.111);
        c.set(95, 0.0);
        let cfg = CompConfig::from_constants(&c);
        assert!(!cfg.enabled);
        assert!(!cfg.check.check && !cfg.check.warn && !cfg.check.optimise_3_blocks);
        // d5..d8 are replacements and the side change, not the check: they stay.
        assert!(cfg.check.complementary_arc_to_line && cfg.check.allow_side_change);
    }

    #[test]
    fn percent_fields() {
        let mut c = Constants::new();
        c.set(764, 10000.120);
        c.set(339, 10005.0);
        let cfg = CompConfig::from_constants(&c);
        assert_eq!(cfg.exit.percent, 120.0);
        assert!(cfg.exit.optimise && !cfg.exit.report);
        assert_eq!(cfg.corner_mode, CornerMode::ArcAboveLimit);
        assert_eq!(cfg.arc_insertion_limit_deg, 5.0);
        assert!(!cfg.report_inserted_arcs && !cfg.g40_without_motion);
    }
}
