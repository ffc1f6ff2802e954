//! Planner regressions found by the daemon's tests.

use kernel::plan::{Planner, PlannerConfig};
use kernel::program::{Setup, stream};

/// A long zig-zag of G98 blocks polled after every push: segments must not be emitted before
/// the backward pass has seen their end junction (it underflowed the window bookkeeping).
#[test]
fn zigzag_polled_after_every_push_plans_to_the_end() {
    let mut text = String::from("G0 X0 Y0\nG1 F200\n");
    for i in 0..2000 {
        let x = if i % 2 == 0 { 300 } else { 0 };
        text.push_str(&format!("N{} X{x} Y{:.2}\n", i + 1, i as f64 * 0.01));
    }
    let setup = Setup::new(&['X', 'Y', 'Z']);
    let mut planner = Planner::new(PlannerConfig::uniform(3, 200.0, 800.0), 1);
    let mut segments = 0;
    let mut last_end = None;
    for b in stream(&text, &setup) {
        planner.push(&b.unwrap()).unwrap();
        while let Some(s) = planner.poll() {
            segments += 1;
            last_end = Some(s.path.end());
        }
    }
    planner.finish();
    while let Some(s) = planner.poll() {
        segments += 1;
        last_end = Some(s.path.end());
    }
    // G0 X0 Y0 does not move and G1 F200 is modal only: one segment per zig-zag block.
    assert_eq!(segments, 2000);
    let end = last_end.unwrap();
    assert_eq!((end[0], end[1]), (0.0, 19.99));
}
