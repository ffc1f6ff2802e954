//! Axis scaling between the controller's units (mm, degrees, rpm) and the drive's integer
//! units (increments, velocity units), shared by every bus.

/// `value` in drive units at `units_per` drive units per controller unit, rounded and
/// saturated to the 32-bit field the drives take (CANopen PDO, serial request).
pub fn to_units(value: f64, units_per: f64) -> i32 {
    (value * units_per)
        .round()
        .clamp(f64::from(i32::MIN), f64::from(i32::MAX)) as i32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rounds_and_saturates() {
        assert_eq!(to_units(1.234_56, 1000.0), 1235);
        assert_eq!(to_units(-0.0006, 1000.0), -1);
        assert_eq!(to_units(1e12, 1000.0), i32::MAX);
        assert_eq!(to_units(-1e12, 1000.0), i32::MIN);
        assert_eq!(to_units(f64::NAN, 1.0), 0);
    }
}
