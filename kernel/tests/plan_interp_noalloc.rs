//! The interpolator runs on the RT thread: after `Interpolator::new` it must not allocate
//! (ARCHITECTURE.md, threads). Counted per thread by the
//! shared counting allocator, so other threads of the test harness do not count.

#[global_allocator]
static ALLOC: alloc_count::Counting = alloc_count::Counting;

mod plan_common;

use kernel::interp::{InterpState, Interpolator};
use kernel::plan::Planner;
use plan_common::*;

#[test]
fn push_and_tick_do_not_allocate() {
    for profile in [1u8, 2, 3] {
        // Plan outside the counted region (the planner thread may allocate). Profile 3: the
        // per-axis box on the setpoints (`config_box`).
        let mut cfg = if profile == 3 {
            config_box()
        } else {
            config(profile)
        };
        cfg.min_block_time_s = 0.0;
        let mut pl = Planner::new(cfg, 1);
        let mut blocks = mixed_arcs();
        blocks.extend(dense_circle(10.0, 0.05, 6000.0).into_iter().skip(1));
        let mut segs = vec![];
        for b in &blocks {
            pl.push(b).unwrap();
            segs.extend(std::iter::from_fn(|| pl.poll()));
        }
        pl.finish();
        segs.extend(std::iter::from_fn(|| pl.poll()));
        let mut ip = Interpolator::new(3, segs[0].path.start());
        let before = alloc_count::allocations();
        let mut next = 0;
        let mut ticks = 0usize;
        loop {
            while next < segs.len() && ip.has_room() {
                ip.push(segs[next]).unwrap();
                next += 1;
            }
            match ticks {
                200 => ip.set_override(150.0),
                400 => ip.hold(),
                700 => ip.resume(),
                _ => {}
            }
            ip.set_in_position(true);
            let out = ip.tick();
            ticks += 1;
            if out.state == InterpState::Idle && next == segs.len() {
                break;
            }
        }
        let after = alloc_count::allocations();
        assert_eq!(after - before, 0, "profile {profile}: {ticks} ticks");
        assert!(ticks > 1000);
    }
}
