//! Probing from a program (docs/language.md, "Probing"): a straight move that ends where the
//! probe input changes (ISO `G38.2`..`G38.5`, CNC836 `G31`), and what the machine reports
//! back. The interpreter cannot go on before it knows where the move ended, so the pipeline
//! brings the path to rest after a probing move, hands it to its caller
//! ([`crate::pipeline::Observer::probe`]) and feeds the answer back to the interpreter.

use crate::units::AxesMm;

/// What a probing move watches for and what it asks of the result.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ProbeMove {
    /// Toward the workpiece: it ends when the probe touches (G38.2, G38.3, G31); away from
    /// it: when the probe releases (G38.4, G38.5).
    pub toward: bool,
    /// The move must find its change: ending at its target without one is an error
    /// (G38.2, G38.4, G31); G38.3 and G38.5 go on and report it in their parameters.
    pub must_trip: bool,
}

/// Where a probing move ended, machine coordinates.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ProbeResult {
    /// The probe changed (#5070 = 1).
    pub tripped: bool,
    /// The axes' positions in the tick the change was seen (the move's target when it was
    /// not), mm.
    pub trip_mm: AxesMm,
    /// Where the axes came to rest after braking: the next block starts here, mm.
    pub stop_mm: AxesMm,
}

/// How far LinuxCNC's standalone interpreter backs a probing move off its target, mm
/// (0.01 inch in an inch program: the same length).
pub const SIMULATED_BACKOFF_MM: f64 = 0.254;

impl ProbeResult {
    /// What a pass without a machine (validation, preview, the dry run) assumes, as
    /// LinuxCNC's `rs274` does: the move reached its target without a change (#5061.. the
    /// target, #5070 = 0) and the axes rest [`SIMULATED_BACKOFF_MM`] back toward its start.
    pub fn without_machine(start_mm: AxesMm, end_mm: AxesMm) -> Self {
        let back = start_mm - end_mm;
        let length = back.norm(crate::units::MAX_AXES);
        let stop_mm = if length > 0.0 {
            end_mm.lerp(&start_mm, SIMULATED_BACKOFF_MM.min(length) / length)
        } else {
            end_mm
        };
        ProbeResult {
            tripped: false,
            trip_mm: end_mm,
            stop_mm,
        }
    }

    /// As [`Self::without_machine`] for probing block `b`.
    pub fn without_machine_for(b: &crate::block::Block) -> Self {
        match b.motion() {
            Some((start, end, _)) => Self::without_machine(start, end),
            None => Self::default(),
        }
    }
}
