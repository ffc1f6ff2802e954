//! What each constant the controller reads is, for people: a short name, the unit of its
//! value and its meaning with the SPEC section (`GetConstants` sends them, the HMI's Constants
//! screen shows them). One entry per constant of [`super::CONSTANTS_READ`] (a test below checks
//! both tables agree), so a constant the controller starts to read cannot go unnamed.
//!
//! Units: `mm`, `°`, `mm/s²`, `µm`, `%`, `ms` as the value is read (docs/files.md, and
//! `plan::config` for the constants read as their digit string); `code` for a number naming a
//! choice; `decades` when the digits are separate switches (`8.R95` is decade 8 of R95).

/// A constant the controller reads, named.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ConstantName {
    pub number: u16,
    pub name: &'static str,
    pub unit: &'static str,
    /// What it does, ending with the SPEC section(s) it comes from.
    pub meaning: &'static str,
}

const fn n(
    number: u16,
    name: &'static str,
    unit: &'static str,
    meaning: &'static str,
) -> ConstantName {
    ConstantName {
        number,
        name,
        unit,
        meaning,
    }
}

/// Every constant the controller reads, ascending.
#[rustfmt::skip]
pub const CONSTANT_NAMES: &[ConstantName] = &[
    n(0, "axis 1 code", "code", "Axis 1 in machine order: 0 none, 1..9 = X Y Z U V W A B C; read when cncd starts (SPEC §1)"),
    n(1, "axis 2 code", "code", "Axis 2 in machine order: 0 none, 1..9 = X Y Z U V W A B C; read when cncd starts (SPEC §1)"),
    n(2, "axis 3 code", "code", "Axis 3 in machine order: 0 none, 1..9 = X Y Z U V W A B C; read when cncd starts (SPEC §1)"),
    n(3, "axis 4 code", "code", "Axis 4 in machine order: 0 none, 1..9 = X Y Z U V W A B C; read when cncd starts (SPEC §1)"),
    n(4, "axis 5 code", "code", "Axis 5 in machine order: 0 none, 1..9 = X Y Z U V W A B C; read when cncd starts (SPEC §1)"),
    n(5, "axis 6 code", "code", "Axis 6 in machine order: 0 none, 1..9 = X Y Z U V W A B C; read when cncd starts (SPEC §1)"),
    n(6, "G24 window, axes 1..3", "mm", "Following error under which a G24 block of axes 1..3 counts as arrived and the next starts (SPEC §7.1)"),
    n(7, "G24 window, axes 4..6", "mm", "Following error under which a G24 block of axes 4..6 counts as arrived and the next starts (SPEC §7.1)"),
    n(39, "smooth-junction angle", "°", "Largest angle between the tangents of an automatically smooth junction (R97 = 2); 60 recommended (SPEC §7.1)"),
    n(52, "acceleration to a stop", "mm/s²", "Path acceleration without continuity (G98, G24), and in continuity when R236 = 0 (SPEC §7)"),
    n(55, "arc end tolerance", "mm", "How far an arc's end point may lie off its circle (I, J over-determine it) (SPEC §2)"),
    n(67, "KŘR controlling axis", "code", "Axis whose position gives the radius of constant cutting speed: 1..9 = X Y Z U V W A B C (SPEC §6)"),
    n(95, "radius compensation", "decades", "8.R95 = 1: radius compensation on equidistants (G41/G42) enabled (SPEC §4)"),
    n(97, "continuity rule", "decades", "1.R97 = 1: manual, G23/G24 decide; 2: automatic, by the R39 angle (SPEC §7.1)"),
    n(232, "arc accuracy", "µm, %", "d1..4: largest chord deviation from the circle per tick on arcs, µm (0 off); d5..8: old centripetal limit, percent (SPEC §7.2)"),
    n(234, "continuity test limit", "°", "Below this angle between tangents the equidistants are not intersected: the point on the perpendicular is used (SPEC §4.4)"),
    n(236, "acceleration in continuity", "mm/s²", "Path acceleration of G23 runs; 0 = R52 (SPEC §7)"),
    n(237, "rapid acceleration", "mm/s²", "Acceleration of rapid moves G0 (SPEC §7)"),
    n(325, "circle refinement", "mm, decades", "d1..7: largest refinement of I or J by the preprocessor (address E, at most 3 mm); 8.R325: 0 off, 1 on, 2 without the limit (SPEC §4.6)"),
    n(329, "S units, G96/G97", "decades", "3.R329: 0 standard, 1 G96/G97 swapped, 2 S in m/min, 3 both (lathes) (SPEC §6)"),
    n(338, "envelope profile", "decades", "2.R338: 0 no envelope velocity, 1 linear, 2 parabolic (jerk-limited) (SPEC §7.2, §7.3)"),
    n(339, "compensation corners", "°, decades", "8.R339: 0 intersect, 1 arc at outside corners above the angle in d1..6, 2 also where no intersection, 4 only there; 7.R339 = 1: G40 without motion; minus: report each arc (SPEC §4.2, §4.3)"),
    n(382, "short-block break", "mm", "A block shorter than this breaks continuity; negative = off (SPEC §7.2)"),
    n(383, "short-block merge", "mm", "A line shorter than this is merged into its neighbour; negative = off (SPEC §7.2)"),
    n(384, "contour accuracy", "µm, %", "d1..4: accuracy criterion Lm, vm = Lm/(Ts·tan(α/2)), 0 off; d5..6: percent of the feed under which a junction is a speed drop (red dot) (SPEC §7.2, §7.5)"),
    n(385, "overload acceleration", "mm/s²", "d1..7: dynamic criterion am, vm = am·Ts/(2·sin(α/2)); 8.R385 = 1..4: block-length correction (SPEC §7.2)"),
    n(387, "preview page", "blocks", "Blocks drawn per preview page; 0 = the whole program (SPEC §7.5)"),
    n(395, "ramp rise time", "ms", "Rise towards F inside a block only when that saves more than this; 0 = 500 ms (SPEC §7.2, §7.3)"),
    n(397, "compensation rules", "decades", "d1 = 1 check off, d2 no warning, d3/d4 3-/4-block optimisation, d5 complementary arcs, d6 direct G41↔G42, d7/d8 bad arcs as lines (SPEC §4.5)"),
    n(406, "set 1 control", "decades", "Dynamic set 1 (G23 I1): 1.R406 = 1 enabled; d2..d6 = 1: the next constants name program parameters (SPEC §7.4)"),
    n(407, "set 1 P ramp", "P", "Dynamic set 1: parabolic ramp P, 10000 gentle..150000 steep; 8. = 2, 3 scales by 1/100, 1/1000 (SPEC §7.3, §7.4)"),
    n(408, "set 1 acceleration", "mm/s²", "Dynamic set 1: linear ramp A, the largest acceleration (SPEC §7.3, §7.4)"),
    n(409, "set 1 accuracy", "µm, %", "Dynamic set 1: accuracy Lm (d1..4) and speed-drop percent (d5..6), as R384 (SPEC §7.4)"),
    n(410, "set 1 overload", "mm/s²", "Dynamic set 1: dynamic criterion am, as R385 (SPEC §7.4)"),
    n(411, "set 1 centripetal", "mm/s² ×10", "Dynamic set 1: centripetal acceleration on arcs, 8. = 1: d1..7 / 10 mm/s², else the old form of R232 (SPEC §7.2, §7.4)"),
    n(412, "set 2 control", "decades", "Dynamic set 2 (G23 I2, DYNAM_SET 1): 1. = 1 enabled; d2..d6 = 1: the next constants name program parameters (SPEC §7.4)"),
    n(413, "set 2 P ramp", "P", "Dynamic set 2: parabolic ramp P, as R407 (SPEC §7.3, §7.4)"),
    n(414, "set 2 acceleration", "mm/s²", "Dynamic set 2: linear ramp A, as R408 (SPEC §7.3, §7.4)"),
    n(415, "set 2 accuracy", "µm, %", "Dynamic set 2: accuracy and speed-drop percent, as R384 (SPEC §7.4)"),
    n(416, "set 2 overload", "mm/s²", "Dynamic set 2: dynamic criterion am, as R385 (SPEC §7.4)"),
    n(417, "set 2 centripetal", "mm/s² ×10", "Dynamic set 2: centripetal acceleration on arcs, as R411 (SPEC §7.4)"),
    n(418, "set 3 control", "decades", "Dynamic set 3 (G23 I3, DYNAM_SET 2): 1. = 1 enabled; d2..d6 = 1: the next constants name program parameters (SPEC §7.4)"),
    n(419, "set 3 P ramp", "P", "Dynamic set 3: parabolic ramp P, as R407 (SPEC §7.3, §7.4)"),
    n(420, "set 3 acceleration", "mm/s²", "Dynamic set 3: linear ramp A, as R408 (SPEC §7.3, §7.4)"),
    n(421, "set 3 accuracy", "µm, %", "Dynamic set 3: accuracy and speed-drop percent, as R384 (SPEC §7.4)"),
    n(422, "set 3 overload", "mm/s²", "Dynamic set 3: dynamic criterion am, as R385 (SPEC §7.4)"),
    n(423, "set 3 centripetal", "mm/s² ×10", "Dynamic set 3: centripetal acceleration on arcs, as R411 (SPEC §7.4)"),
    n(424, "set 4 control", "decades", "Dynamic set 4 (G23 I4, DYNAM_SET 3): 1. = 1 enabled; d2..d6 = 1: the next constants name program parameters (SPEC §7.4)"),
    n(425, "set 4 P ramp", "P", "Dynamic set 4: parabolic ramp P, as R407 (SPEC §7.3, §7.4)"),
    n(426, "set 4 acceleration", "mm/s²", "Dynamic set 4: linear ramp A, as R408 (SPEC §7.3, §7.4)"),
    n(427, "set 4 accuracy", "µm, %", "Dynamic set 4: accuracy and speed-drop percent, as R384 (SPEC §7.4)"),
    n(428, "set 4 overload", "mm/s²", "Dynamic set 4: dynamic criterion am, as R385 (SPEC §7.4)"),
    n(429, "set 4 centripetal", "mm/s² ×10", "Dynamic set 4: centripetal acceleration on arcs, as R411 (SPEC §7.4)"),
    n(430, "rapid set control", "decades", "1.R430 = 1: G0 and STOP use the ramp of R431 and R432 (SPEC §7.4)"),
    n(431, "rapid set P ramp", "P", "Rapid and stop set: parabolic ramp P, as R407 (SPEC §7.3, §7.4)"),
    n(432, "rapid set acceleration", "mm/s²", "Rapid and stop set: linear ramp A (SPEC §7.3, §7.4)"),
    n(580, "KŘR version", "code", "0: old KŘR, motion blocks only; 1: version 2, also non-motion blocks, jog, PLC, the G76 limit (SPEC §6)"),
    n(764, "exit optimisation", "%, decades", "d1..3: last working block before a rapid shorter than this percent of the radius (0 = 150 %); d8 = 1 optimise, d7 = 1 report (SPEC §4.5)"),
    n(765, "equidistant position test", "%, decades", "d1..3: report where the equidistant lies farther than this percent of the radius (0 = 300 %); d8 = 1 optimise, d7 = 1 report (SPEC §4.5)"),
];

/// The name, unit and meaning of constant `r`, or `None` for a constant the controller does
/// not read.
pub fn constant_name(r: u16) -> Option<&'static ConstantName> {
    CONSTANT_NAMES
        .binary_search_by_key(&r, |c| c.number)
        .ok()
        .map(|k| &CONSTANT_NAMES[k])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_constant_read_is_named_once_and_nothing_else() {
        let named: Vec<u16> = CONSTANT_NAMES.iter().map(|c| c.number).collect();
        let read: Vec<u16> = super::super::constants_read().collect();
        assert_eq!(named, read, "CONSTANT_NAMES against CONSTANTS_READ");
    }

    #[test]
    fn every_entry_has_a_name_a_unit_and_cites_the_spec() {
        for c in CONSTANT_NAMES {
            assert!(!c.name.is_empty() && !c.unit.is_empty(), "R{}", c.number);
            assert!(
                c.meaning.contains("(SPEC §"),
                "R{} cites no SPEC section",
                c.number
            );
        }
        assert_eq!(constant_name(384).map(|c| c.unit), Some("µm, %"));
        assert_eq!(constant_name(8), None);
    }
}
