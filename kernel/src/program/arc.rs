//! Circle geometry of the interpreter: the E address, R325 refinement and the R55 end-point
//! check (SPEC §2, §4.6).
//!
//! Arcs are over-determined: start, end and both centre coordinates are programmed, so the end
//! point may miss the circle. Coordinates here are the two plane components (first, second
//! axis of `Plane::axes()`), in mm.

use crate::constants::Refinement;

/// Which centre coordinate an E address or a refinement corrects.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Corrected {
    /// I (decade 8 of E = 0).
    I,
    /// J (decade 8 of E = 1).
    J,
}

/// A decoded `E` address: `Iz = I + E/1000` or `Jz = J + E/1000`, E in µm (SPEC §4.6).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ERefinement {
    pub which: Corrected,
    /// Correction to add to I or J, mm.
    pub delta_mm: f64,
}

/// Why an E word does not decode.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum EWordError {
    #[error("E{0} is outside ±99999.999")]
    OutOfRange(f64),
    #[error("decade 8 of E must be 0 (correct I) or 1 (correct J), not {0}")]
    BadDecade8(u64),
}

impl EWordError {
    /// Stable code (tests and HMIs match it; the message may improve).
    pub fn code(&self) -> crate::diag::DiagCode {
        crate::diag::DiagCode::ERefinementInvalid
    }
}

impl ERefinement {
    /// Decodes E as written: decade 8 (the 10⁴ digit of the integer part) selects I or J,
    /// decades 1..7 are the correction in µm with 0.001 µm resolution, the sign applies to it.
    /// `E2.054` → I + 0.002054 mm; `E-10006.992` → J − 0.006992 mm.
    pub fn decode(e: f64) -> Result<ERefinement, EWordError> {
        if !e.is_finite() || e.abs() >= 100_000.0 {
            return Err(EWordError::OutOfRange(e));
        }
        // Thousandths of a µm, exact for the ±xxxxx.xxx format.
        let milli = (e.abs() * 1000.0).round() as u64;
        let which = match milli / 10_000_000 {
            0 => Corrected::I,
            1 => Corrected::J,
            d => {
                return Err(EWordError::BadDecade8(d));
            }
        };
        let um = (milli % 10_000_000) as f64 / 1000.0;
        let delta_mm = um / 1000.0 * e.signum();
        Ok(ERefinement { which, delta_mm })
    }

    /// Encodes a correction the way the preprocessor records it (for listings and tests).
    pub fn encode(self) -> f64 {
        let um = (self.delta_mm.abs() * 1e6).round() / 1000.0;
        let sel = if self.which == Corrected::J {
            10_000.0
        } else {
            0.0
        };
        (sel + um).copysign(self.delta_mm)
    }

    /// Applies the correction to the centre offsets (I, J).
    pub fn apply(self, ij: (f64, f64)) -> (f64, f64) {
        match self.which {
            Corrected::I => (ij.0 + self.delta_mm, ij.1),
            Corrected::J => (ij.0, ij.1 + self.delta_mm),
        }
    }
}

/// A block whose centre the preprocessor refined (R325, SPEC §4.6).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Refined {
    /// Index of the block in the program, its `N` number and 1-based source line.
    pub seq: u32,
    pub n: Option<u32>,
    pub line: u32,
    /// The refinement the preprocessor applied.
    pub refinement: ERefinement,
    /// The E word the block carries after refinement (a programmed E on the same coordinate
    /// plus the refinement); `None` when a programmed E corrects the other coordinate (a
    /// block has one E word only).
    pub word: Option<ERefinement>,
    /// Byte offset of a programmed E word in its line.
    pub programmed_e_at: Option<usize>,
}

/// Radii of the start and end point about `center`.
pub fn radii(start: (f64, f64), end: (f64, f64), center: (f64, f64)) -> (f64, f64) {
    (
        (start.0 - center.0).hypot(start.1 - center.1),
        (end.0 - center.0).hypot(end.1 - center.1),
    )
}

/// The preprocessor's circle refinement (SPEC §4.6): moves the centre along I or along J, whichever
/// needs the smaller change, so that start and end are exactly equidistant from it. The change is
/// rounded to 0.001 µm (the resolution of E). `None` when no change is needed, when refinement
/// is off, or when the change exceeds the R325 limit (or the 9999.999 µm an E can hold).
pub fn refine(
    start: (f64, f64),
    end: (f64, f64),
    center: (f64, f64),
    setting: Refinement,
) -> Option<ERefinement> {
    let limit_mm = match setting {
        Refinement::Off => return None,
        Refinement::Limited { limit_mm } => limit_mm.min(9.999_999),
        Refinement::Unlimited => 9.999_999,
    };
    // Centre on the perpendicular bisector of the chord: d·(c − m) = 0.
    let d = (start.0 - end.0, start.1 - end.1);
    let m = ((start.0 + end.0) / 2.0, (start.1 + end.1) / 2.0);
    let along_i = (d.0 != 0.0).then(|| m.0 - d.1 * (center.1 - m.1) / d.0 - center.0);
    let along_j = (d.1 != 0.0).then(|| m.1 - d.0 * (center.0 - m.0) / d.1 - center.1);
    let best = match (along_i, along_j) {
        (Some(i), Some(j)) if j.abs() < i.abs() => (Corrected::J, j),
        (Some(i), _) => (Corrected::I, i),
        (None, Some(j)) => (Corrected::J, j),
        (None, None) => return None, // full circle: always consistent
    };
    let delta_mm = (best.1 * 1e6).round() / 1e6;
    if delta_mm == 0.0 || !delta_mm.is_finite() || delta_mm.abs() > limit_mm {
        return None;
    }
    Some(ERefinement {
        which: best.0,
        delta_mm,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    // SPEC §4.6 worked examples.
    #[test]
    fn e_examples_from_the_manual() {
        let e = ERefinement::decode(2.054).unwrap();
        assert_eq!(e.which, Corrected::I);
        let (iz, _) = e.apply((12.345, 0.0));
        assert!((iz - 12.347054).abs() < 1e-12, "{iz}");
        let e = ERefinement::decode(-10006.992).unwrap();
        assert_eq!(e.which, Corrected::J);
        let (_, jz) = e.apply((0.0, 5.088));
        assert!((jz - 5.081008).abs() < 1e-12, "{jz}");
        assert_eq!(e.encode(), -10006.992);
    }

    #[test]
    fn decade_8_above_one_is_refused() {
        assert!(ERefinement::decode(20001.0).is_err());
    }

    #[test]
    fn refinement_makes_the_circle_consistent() {
        // Quarter circle of radius 10 about (0,0) from (10,0) to (0,10); centre written 3 µm off.
        let r = refine(
            (10.0, 0.0),
            (0.0, 10.0),
            (0.003, 0.0),
            Refinement::Limited { limit_mm: 0.01 },
        )
        .unwrap();
        let c = r.apply((0.003, 0.0));
        let (rs, re) = radii((10.0, 0.0), (0.0, 10.0), c);
        assert!((rs - re).abs() < 1e-6, "{rs} {re}");
        assert!(refine((10.0, 0.0), (0.0, 10.0), (0.003, 0.0), Refinement::Off).is_none());
        assert!(
            refine(
                (10.0, 0.0),
                (0.0, 10.0),
                (0.003, 0.0),
                Refinement::Limited { limit_mm: 0.001 }
            )
            .is_none()
        );
    }
}
