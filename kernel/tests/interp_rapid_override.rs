//! Rapid override (issue #19): scales the speed of G0 moves only, as a soft limit of the path
//! speed (approached within the acceleration and jerk limits, like the feed override), so
//! the path, the axis limits and the end point hold.

mod plan_common;

use kernel::block::Continuity;
use plan_common::*;

const V_TOL: f64 = 1.0 + 1e-9;
const A_TOL: f64 = 1.0 + 1e-6;

/// G0 X200, then a feed move at F600.
fn rapid_then_feed() -> Prog {
    let mut p = Prog::new(p3(0.0, 0.0, 0.0), 600.0, Continuity::G23);
    p.g0(p3(200.0, 0.0, 0.0)).g1(p3(210.0, 0.0, 0.0));
    p
}

fn peak(r: &Run, x_from: f64, x_to: f64) -> f64 {
    r.ticks
        .iter()
        .filter(|t| t.position[0] > x_from && t.position[0] < x_to)
        .map(|t| t.path_v_mm_s)
        .fold(0.0, f64::max)
}

#[test]
fn rapid_override_scales_rapids_within_the_limits() {
    for profile in [1u8, 2] {
        let c = config(profile);
        let p = rapid_then_feed();
        let full = run_with(c.clone(), &p.blocks, 1_000_000, |_, _| {});
        // 25 % from the start, 100 % again half way (no step: approached within the limits).
        let slow = run_with(c.clone(), &p.blocks, 1_000_000, |t, ip| match t {
            0 => ip.set_rapid_override(25.0),
            2000 => ip.set_rapid_override(100.0),
            _ => {}
        });
        let rapid_v = peak(&full, 1.0, 199.0);
        let early = slow
            .ticks
            .iter()
            .take(2000)
            .map(|t| t.path_v_mm_s)
            .fold(0.0, f64::max);
        assert!(early <= 0.25 * rapid_v * V_TOL, "{early} vs {rapid_v}");
        assert!(early > 0.2 * rapid_v, "{early} vs {rapid_v}");
        let w = measure(&c, &slow, 8.0);
        assert!(
            w.axis_v <= V_TOL && w.axis_a <= A_TOL && w.path_a <= A_TOL,
            "{w:?}"
        );
        assert_eq!(w.missed_stops, 0, "{w:?}");
        assert!(slow.time_s() > full.time_s());
        // The feed move is not a rapid: its speed is the same in both runs.
        let (a, b) = (peak(&full, 201.0, 209.0), peak(&slow, 201.0, 209.0));
        assert!((a - b).abs() < 1e-9, "{a} {b}");
        assert_eq!(slow.ticks.last().unwrap().position[0], 210.0);
    }
}
