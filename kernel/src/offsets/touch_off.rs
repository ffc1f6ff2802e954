//! Touch-off (issue #47): the length of one entry of TAB0.KOR for one axis, chosen so that the
//! position where the axis stands reads a given value in program coordinates.
//!
//! The table's model (docs/language.md, "Length offsets"): machine position = programmed
//! position + length, so `length = machine − value`. A diameter axis keeps its length as a
//! diameter and its programmed values are diameters: `length = 2·machine − value`. With a work
//! offset system named (ISO programs, where machine = programmed + work offset + length), its
//! offset of the axis is taken off too: `length = machine − work − value`. docs/setup.md.

use super::{MAX_DECIMALS, MAX_VALUE_MM, TableEdit};

/// What a touch-off asks for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TouchOff {
    /// Entry 1..=99.
    pub entry: u8,
    /// Axis index 0..=3 (the table has lengths for axes 1..4 only).
    pub axis: usize,
    /// What the position shall read in program coordinates, mm (a diameter on a diameter
    /// axis).
    pub value_mm: f64,
    /// The work offset of the axis the program will run in (0 for CNC836 programs), mm.
    pub work_mm: f64,
    /// The axis is programmed as a diameter (`[kr] radius_input = "diameter"`).
    pub diameter: bool,
}

/// Why a touch-off cannot be written.
#[derive(Clone, Debug, PartialEq)]
pub enum TouchOffError {
    /// Axes 5 and 6 have no length in the table.
    NoLength(usize),
    /// The value or the resulting length is not a number or beyond ±99999.999 mm.
    OutOfRange(String),
}

impl std::fmt::Display for TouchOffError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            TouchOffError::NoLength(k) => write!(
                f,
                "axis {} has no length in the offset table (lengths are for axes 1..4)",
                k + 1
            ),
            TouchOffError::OutOfRange(m) => f.write_str(m),
        }
    }
}

/// The length to write for `t` when the axis stands at `machine_mm` (machine coordinates,
/// mm), rounded to the table's 6 decimals.
pub fn length_for(t: &TouchOff, machine_mm: f64) -> Result<f64, TouchOffError> {
    if t.axis >= 4 {
        return Err(TouchOffError::NoLength(t.axis));
    }
    if !t.value_mm.is_finite() || t.value_mm.abs() > MAX_VALUE_MM {
        return Err(TouchOffError::OutOfRange(format!(
            "the value {} is not within ±{MAX_VALUE_MM} mm",
            t.value_mm
        )));
    }
    let scale = if t.diameter { 2.0 } else { 1.0 };
    let length = scale * (machine_mm - t.work_mm) - t.value_mm;
    let unit = 10f64.powi(MAX_DECIMALS as i32);
    let length = (length * unit).round() / unit;
    if !length.is_finite() || length.abs() > MAX_VALUE_MM {
        return Err(TouchOffError::OutOfRange(format!(
            "the length would be {length} mm, beyond ±{MAX_VALUE_MM} mm"
        )));
    }
    Ok(length)
}

/// The table edit of a touch-off (with a radius to set beside it, if any).
pub fn edit_for(
    t: &TouchOff,
    machine_mm: f64,
    radius_mm: Option<f64>,
) -> Result<TableEdit, TouchOffError> {
    let length = length_for(t, machine_mm)?;
    if let Some(r) = radius_mm
        && (!r.is_finite() || r.abs() > MAX_VALUE_MM)
    {
        return Err(TouchOffError::OutOfRange(format!(
            "the radius {r} is not within ±{MAX_VALUE_MM} mm"
        )));
    }
    let mut values = [None; 5];
    values[0] = radius_mm;
    values[t.axis + 1] = Some(length);
    Ok(TableEdit {
        entry: t.entry,
        values,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn t(axis: usize, value_mm: f64, work_mm: f64, diameter: bool) -> TouchOff {
        TouchOff {
            entry: 3,
            axis,
            value_mm,
            work_mm,
            diameter,
        }
    }

    #[test]
    fn the_touched_point_reads_the_value() {
        // machine = programmed + length: at 123.4567891 reading 10 → 113.456789.
        assert_eq!(
            length_for(&t(0, 10.0, 0.0, false), 123.456_789_1),
            Ok(113.456_789)
        );
        // ISO with G54 X100: machine = programmed + 100 + length.
        assert_eq!(length_for(&t(0, 0.0, 100.0, false), 150.0), Ok(50.0));
        // A diameter axis: the table and the program speak diameters.
        assert_eq!(length_for(&t(0, 40.0, 0.0, true), 25.0), Ok(10.0));
    }

    #[test]
    fn refusals_change_nothing_and_say_why() {
        assert_eq!(
            length_for(&t(4, 0.0, 0.0, false), 1.0),
            Err(TouchOffError::NoLength(4))
        );
        assert!(length_for(&t(0, f64::NAN, 0.0, false), 1.0).is_err());
        assert!(length_for(&t(0, -99_999.0, 0.0, false), 99_999.0).is_err());
        assert!(edit_for(&t(0, 0.0, 0.0, false), 1.0, Some(f64::INFINITY)).is_err());
        let e = edit_for(&t(2, 0.0, 0.0, false), -12.5, Some(4.0)).unwrap();
        assert_eq!(e.values, [Some(4.0), None, None, Some(-12.5), None]);
    }
}
