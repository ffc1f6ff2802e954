//! Canonical blocks: the interpreter's output and the compensator's input and output.
//!
//! A canonical block is self-contained: absolute start and end positions of every axis in
//! millimetres, the resolved feed, and the modal state that later stages need. Later stages
//! never look back at program text.

use crate::units::AxesMm;

/// Working plane (SPEC §2: G17 default = plane of axes 1 and 2).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Plane {
    /// G17: axes 1 and 2 (XY on a mill, XZ on a lathe whose second axis is Z).
    #[default]
    G17,
    /// G18: axes 3 and 1 (ZX).
    G18,
    /// G19: axes 2 and 3 (YZ).
    G19,
}

impl Plane {
    /// Axis indices (first, second) of the plane, ordered so that G2 is clockwise looking
    /// against the plane normal (right-handed: G17 X→Y, G18 Z→X, G19 Y→Z).
    pub fn axes(self) -> (usize, usize) {
        match self {
            Plane::G17 => (0, 1),
            Plane::G18 => (2, 0),
            Plane::G19 => (1, 2),
        }
    }
}

/// Direction of circular interpolation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ArcDir {
    /// G2, clockwise.
    Cw,
    /// G3, counter-clockwise.
    Ccw,
}

/// The path of a motion block.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Path {
    /// G0: positioning at rapid speed, straight line in axis space.
    Rapid,
    /// G1: straight line.
    Line,
    /// G2/G3: circular arc in `plane` about `center` (absolute; only the two plane components are
    /// meaningful); axes outside the plane move linearly (helix).
    Arc {
        dir: ArcDir,
        center: AxesMm,
        plane: Plane,
    },
    /// G38.2..G38.5 (CNC836: G31): a straight line at the feed that ends where the probe
    /// changes; the path is at rest before and after it (`crate::probe`).
    Probe(crate::probe::ProbeMove),
}

/// Feed as programmed, already converted to one unit per mode (SPEC §5).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Feed {
    /// G94/G96: mm/min.
    MmPerMin(f64),
    /// G95/G97: mm per spindle revolution.
    MmPerRev(f64),
}

impl Default for Feed {
    fn default() -> Self {
        Feed::MmPerMin(0.0)
    }
}

/// Radius compensation command in force for a block (SPEC §4).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Comp {
    /// G40.
    #[default]
    Off,
    /// G41: tool centre left of the path; radius from the offset table entry `d`.
    Left { d: u8, radius_mm: f64 },
    /// G42: tool centre right of the path.
    Right { d: u8, radius_mm: f64 },
}

/// Block continuity mode (SPEC §7.1).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Continuity {
    /// G98: ramp to rest at every block end (power-on default).
    #[default]
    G98,
    /// G24: ramp to rest, then wait for the following error to settle.
    G24,
    /// G23: continuous path.
    G23,
}

/// Spindle state (M3/M4/M5 and S).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum SpindleDir {
    Cw,
    Ccw,
    #[default]
    Stopped,
}

#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Spindle {
    pub dir: SpindleDir,
    /// Programmed S word as written (rpm under G94/G95; cutting speed under G96/G97, SPEC §6).
    pub s: f64,
    /// Constant cutting speed (KŘR, G96/G97, SPEC §6) is in force.
    pub css: bool,
    /// G76 spindle speed limit, rpm (0 = none programmed).
    pub limit_rpm: f64,
    /// Gear range selected by an M code (0 = none selected), SPEC §6.
    pub gear: u8,
    /// Tool length offset (`&`, and `G92` writes of that entry) in force for the controlling
    /// axis R67, in that axis's units (a diameter on a diameter axis). KŘR version 2 computes
    /// at the tool tip, carriage − offset, and offset changes act at once (SPEC §6), so the
    /// value rides with the spindle state to the RT thread.
    pub length_offset_mm: f64,
    /// Origin shift in force for the controlling axis, same units. The dialect has no origin
    /// shift function yet (no manual describes one), so the interpreter always writes 0; the
    /// RT thread already honours the field (SPEC §6: "corrected by offsets and shifts").
    pub origin_shift_mm: f64,
    /// P of the gear range in force (rpm), from the machine's gear table (0 = no table given
    /// to the interpreter). Feed per revolution is planned at a nominal speed capped by it.
    pub gear_max_rpm: f64,
    /// The machine outputs the program has switched (M functions on outputs, docs/io.md):
    /// they ride with the spindle state and take effect where it does.
    pub outputs: crate::outputs::ProgramOutputs,
}

impl Spindle {
    /// Nominal spindle speed (rpm) at which a feed per revolution of this block is planned
    /// (SPEC §5: V = S·β), or `None` when the spindle stands or no speed is known. The RT
    /// thread scales the planned feed by actual/nominal every tick (capped at 1), so the
    /// nominal must be the **highest** speed the spindle can reach in the block:
    /// - G95: the programmed S, capped by the gear maximum P (after KŘR ended without S:
    ///   P, the last reached speed is not known before the run);
    /// - KŘR (G96/G97): the speed changes along the cut: min(P, G76 limit).
    pub fn per_rev_nominal_rpm(&self) -> Option<f64> {
        if self.dir == SpindleDir::Stopped {
            return None;
        }
        let p = if self.gear_max_rpm > 0.0 {
            self.gear_max_rpm
        } else {
            f64::INFINITY
        };
        let n = if self.css {
            if self.limit_rpm > 0.0 {
                p.min(self.limit_rpm)
            } else {
                p
            }
        } else if self.s > 0.0 {
            p.min(self.s)
        } else {
            p
        };
        (n.is_finite() && n > 0.0).then_some(n)
    }
}

/// What a block does.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BlockKind {
    /// Motion from `start` to `end` along `path`.
    Motion {
        start: AxesMm,
        end: AxesMm,
        path: Path,
    },
    /// Dwell (no motion) for the given time.
    Dwell { seconds: f64 },
    /// A block with no motion: technology functions (M, S, D ...), modal changes only.
    Technology,
    /// `G92 D<entry> R0=.. R4=..` (SPEC §3 (c)): write the values present (R0 radius, R1..R4
    /// lengths of axes 1..4) into entry 1..99 of the **memory** offset table when the block
    /// executes; the file TAB0.KOR is not touched. The interpreter has already applied it to its
    /// own copy of the table, so later blocks' `D`/`&` lookups see the new values.
    TableWrite { entry: u8, values: [Option<f64>; 5] },
    /// `M6` (with `T<n>`): a manual tool change to tool `tool` (entry n of TAB0.KOR, 0 = no
    /// tool). No motion: the machine comes to rest and holds as at M0 until Resume (or
    /// Start); the interpreter has already put the tool's entries in force for the blocks
    /// after it (docs/language.md, "Tool change").
    ToolChange { tool: u8 },
}

/// Up to four M functions per block, in the order written.
pub type MCodes = [Option<u16>; 4];

/// A program stop at the end of a block (M0, M1): the machine comes to rest on the path and
/// waits for Resume (or Start).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ProgramStop {
    #[default]
    None,
    /// M0: always stops.
    Always,
    /// M1: stops only while "optional stop" is switched on.
    Optional,
    /// M6: always stops, for the operator to put tool `tool` in the spindle.
    ToolChange { tool: u8 },
}

impl ProgramStop {
    /// The stop a block asks for: a tool change, else what its M functions ask for.
    pub fn of_block(b: &Block) -> Self {
        match b.kind {
            BlockKind::ToolChange { tool } => ProgramStop::ToolChange { tool },
            _ => Self::of(&b.m),
        }
    }

    /// Of two stops due at one place, the one that holds: a tool change (it names the
    /// tool), then M0, then M1.
    pub fn stronger(self, other: Self) -> Self {
        let rank = |s: Self| match s {
            ProgramStop::None => 0,
            ProgramStop::Optional => 1,
            ProgramStop::Always => 2,
            ProgramStop::ToolChange { .. } => 3,
        };
        if rank(other) > rank(self) {
            other
        } else {
            self
        }
    }

    /// The stop the M functions of a block ask for (M0 wins over M1).
    pub fn of(m: &MCodes) -> Self {
        let has = |code: u16| m.iter().flatten().any(|&c| c == code);
        if has(0) {
            ProgramStop::Always
        } else if has(1) {
            ProgramStop::Optional
        } else {
            ProgramStop::None
        }
    }
}

/// Whether the M functions of a block end the program (M2, M30): later blocks are not run.
pub fn ends_program(m: &MCodes) -> bool {
    m.iter().flatten().any(|&c| c == 2 || c == 30)
}

/// A canonical block.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Block {
    /// Index of the block in the program (0-based), unique and increasing; traces every later
    /// stage (compensated pieces, planned segments) back to its source.
    pub seq: u32,
    /// Programmed `N` number, if any.
    pub n: Option<u32>,
    /// 1-based source line.
    pub line: u32,
    pub kind: BlockKind,
    pub feed: Feed,
    pub plane: Plane,
    pub comp: Comp,
    pub continuity: Continuity,
    /// Dynamic parameter set 1..4 (SPEC §7.4, `G23 I1..I4`).
    pub dyn_set: u8,
    pub spindle: Spindle,
    pub m: MCodes,
}

impl Block {
    /// Start and end points if this is a motion block.
    pub fn motion(&self) -> Option<(AxesMm, AxesMm, Path)> {
        match self.kind {
            BlockKind::Motion { start, end, path } => Some((start, end, path)),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spindle(css: bool, s: f64, limit_rpm: f64, gear_max_rpm: f64) -> Spindle {
        Spindle {
            dir: SpindleDir::Cw,
            s,
            css,
            limit_rpm,
            gear_max_rpm,
            ..Spindle::default()
        }
    }

    /// Feed per revolution is planned at the highest speed the spindle can have in the block.
    #[test]
    fn per_rev_nominal_speed() {
        // G95: S capped by the gear maximum P (issue #17: M42 with P 2000, S3000).
        assert_eq!(
            spindle(false, 3000.0, 0.0, 2000.0).per_rev_nominal_rpm(),
            Some(2000.0)
        );
        assert_eq!(
            spindle(false, 800.0, 0.0, 2000.0).per_rev_nominal_rpm(),
            Some(800.0)
        );
        // No gear table: the programmed S; after KŘR ended without S: P.
        assert_eq!(
            spindle(false, 800.0, 0.0, 0.0).per_rev_nominal_rpm(),
            Some(800.0)
        );
        assert_eq!(
            spindle(false, 0.0, 0.0, 2000.0).per_rev_nominal_rpm(),
            Some(2000.0)
        );
        assert_eq!(spindle(false, 0.0, 0.0, 0.0).per_rev_nominal_rpm(), None);
        // KŘR: S is a cutting speed; min(P, G76).
        assert_eq!(
            spindle(true, 90.0, 400.0, 2000.0).per_rev_nominal_rpm(),
            Some(400.0)
        );
        assert_eq!(
            spindle(true, 90.0, 0.0, 2000.0).per_rev_nominal_rpm(),
            Some(2000.0)
        );
        assert_eq!(spindle(true, 90.0, 0.0, 0.0).per_rev_nominal_rpm(), None);
        // A standing spindle: none.
        let stopped = Spindle {
            dir: SpindleDir::Stopped,
            ..spindle(false, 800.0, 0.0, 2000.0)
        };
        assert_eq!(stopped.per_rev_nominal_rpm(), None);
    }
}
