//! The modal state of an ISO program (LinuxCNC 2.9's power-on state unless said otherwise)
//! and where the tool is. Positions are kept in machine coordinates, mm; the program's
//! coordinates are derived: program = machine − (work offset + G92 offset + tool length).

use crate::block::{Continuity, Plane, Spindle};
use crate::offsets::WorkOffsets;
use crate::units::{AxesMm, MAX_AXES};

/// Millimetres per inch (G20).
pub const MM_PER_INCH: f64 = 25.4;

/// The motion mode (modal group 1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MotionMode {
    Rapid,
    Line,
    Cw,
    Ccw,
    /// A canned cycle: G73, G81, G82, G83, G85, G89.
    Cycle(u8),
    /// G80: no motion mode; axis words alone are an error.
    Off,
    /// G38.2..G38.5: a probing move (`crate::probe`).
    Probe(crate::probe::ProbeMove),
}

/// Feed mode (group 5).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FeedMode {
    /// G93: F is the inverse of the move's time in minutes.
    InverseTime,
    /// G94: units per minute.
    PerMinute,
    /// G95: units per spindle revolution.
    PerRev,
}

/// Radius compensation side (group 7).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CompSide {
    Off,
    Left,
    Right,
}

/// What a canned cycle remembers between blocks (LinuxCNC: R, Z, P, Q stay in force while
/// the cycle does; the initial level is the Z where the first cycle block started).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CycleMemory {
    /// R and Z (bottom) in mm, program coordinates of the third axis.
    pub r_mm: Option<f64>,
    pub bottom_mm: Option<f64>,
    pub p_s: Option<f64>,
    pub q_mm: Option<f64>,
    /// The third axis's program coordinate when the first cycle block started.
    pub initial_mm: Option<f64>,
}

/// Modal state and position; `Clone`, so a line works on a copy and commits it whole.
#[derive(Clone, Debug)]
pub struct State {
    pub motion: MotionMode,
    pub plane: Plane,
    pub inches: bool,
    pub absolute: bool,
    /// G90.1: arc centres I J K are absolute.
    pub arc_absolute: bool,
    pub feed_mode: FeedMode,
    /// F in force, mm/min (G94), mm/rev (G95) or 1/min (G93); `None` until written.
    pub feed: Option<f64>,
    pub spindle: Spindle,
    pub comp: CompSide,
    /// Table entry of the radius in force (D, or the tool in the spindle).
    pub comp_entry: u8,
    pub comp_radius_mm: f64,
    pub continuity: Continuity,
    /// G99: canned cycles retract to R; G98: to the initial level.
    pub retract_to_r: bool,
    /// The tool in the spindle (M6) and the one T selected for the next change.
    pub tool: u8,
    pub next_tool: u8,
    /// The table entry whose lengths are in force (G43), 0 = none.
    pub length_entry: u8,
    /// The length offsets in force, mm per axis.
    pub length_mm: AxesMm,
    /// The work offsets (a G10 changes this copy) and the system in force (0 = G54).
    pub work: WorkOffsets,
    pub system: usize,
    /// The G92 offset in force, mm per axis.
    pub g92_mm: AxesMm,
    pub cycle: CycleMemory,
    /// Where the tool is, machine coordinates, mm.
    pub machine: AxesMm,
}

impl State {
    pub fn power_on(start: AxesMm, work: WorkOffsets) -> Self {
        State {
            // LinuxCNC starts in G80: axis words need a motion code first.
            motion: MotionMode::Off,
            plane: Plane::G17,
            inches: false,
            absolute: true,
            arc_absolute: false,
            feed_mode: FeedMode::PerMinute,
            feed: None,
            spindle: Spindle::default(),
            comp: CompSide::Off,
            comp_entry: 0,
            comp_radius_mm: 0.0,
            continuity: Continuity::G23,
            // LinuxCNC's interpreter starts in G99 (retract to R).
            retract_to_r: true,
            tool: 0,
            next_tool: 0,
            length_entry: 0,
            length_mm: AxesMm::ZERO,
            system: work.active.min(crate::offsets::work::SYSTEMS - 1),
            work,
            g92_mm: AxesMm::ZERO,
            cycle: CycleMemory::default(),
            machine: start,
        }
    }

    /// Program coordinates = machine − this, per axis.
    pub fn offset(&self) -> AxesMm {
        let mut o = AxesMm::ZERO;
        for k in 0..MAX_AXES {
            o[k] = self.work.get(self.system, k) + self.g92_mm[k] + self.length_mm[k];
        }
        o
    }

    /// Where the tool is in program coordinates, mm.
    pub fn program_pos(&self) -> AxesMm {
        self.machine - self.offset()
    }

    /// A length of the program (axis word, I J K, R, Q, F) in mm.
    pub fn mm(&self, v: f64) -> f64 {
        if self.inches { v * MM_PER_INCH } else { v }
    }

    /// A length in mm in the program's units.
    pub fn units(&self, mm: f64) -> f64 {
        if self.inches { mm / MM_PER_INCH } else { mm }
    }
}
