use super::*;
use crate::plan::SegPath;

fn line(seq: u32, from: [f64; 3], to: [f64; 3], feed: f64, v_end: f64) -> Segment {
    let mut s = AxesMm::ZERO;
    let mut e = AxesMm::ZERO;
    s.0[..3].copy_from_slice(&from);
    e.0[..3].copy_from_slice(&to);
    let path = SegPath::Line { start: s, end: e };
    Segment {
        seq,
        path,
        length_mm: path.length(3),
        feed_mm_s: feed,
        v_max_mm_s: 1000.0,
        v_end_mm_s: v_end,
        accel_mm_s2: 500.0,
        jerk_mm_s3: f64::INFINITY,
        stop_accel_mm_s2: 500.0,
        ..Segment::default()
    }
}

fn run(ip: &mut Interpolator, max_ticks: usize) -> Vec<TickOut> {
    let mut out = vec![];
    for _ in 0..max_ticks {
        let t = ip.tick();
        out.push(t);
        if t.state == InterpState::Idle {
            break;
        }
    }
    out
}

fn check_limits(trace: &[TickOut], v_max: f64, a_max: f64) {
    let mut prev_v = 0.0;
    for w in trace.windows(2) {
        let v = (w[1].position - w[0].position).norm(3) / TS_S;
        assert!(v <= v_max * (1.0 + 1e-9) + 1e-9, "speed {v} > {v_max}");
        let a = (v - prev_v).abs() / TS_S;
        assert!(a <= a_max * (1.0 + 1e-6) + 1e-6, "accel {a} > {a_max}");
        prev_v = v;
    }
}

/// An interpolator on one X line from 0 to `to_x` mm at 50 mm/s, at rest at both ends, after
/// `ticks` ticks; with its trace so far, from the tick at rest before the first.
fn on_x_line(to_x: f64, ticks: usize) -> (Interpolator, Vec<TickOut>) {
    let mut ip = Interpolator::new(3, AxesMm::ZERO);
    ip.push(line(0, [0.0; 3], [to_x, 0.0, 0.0], 50.0, 0.0))
        .unwrap();
    let mut trace = vec![TickOut::default()];
    for _ in 0..ticks {
        trace.push(ip.tick());
    }
    (ip, trace)
}

#[test]
fn single_line_ends_exactly_within_limits() {
    let mut ip = Interpolator::new(3, AxesMm::ZERO);
    ip.push(line(0, [0.0; 3], [10.0, 5.0, 0.0], 50.0, 0.0))
        .unwrap();
    let mut trace = vec![TickOut::default()];
    trace.extend(run(&mut ip, 10_000));
    let end = trace.last().unwrap().position;
    assert_eq!(&end.0[..3], &[10.0, 5.0, 0.0]);
    check_limits(&trace, 50.0, 500.0);
}

#[test]
fn smooth_junction_does_not_stop() {
    let mut ip = Interpolator::new(3, AxesMm::ZERO);
    ip.push(line(0, [0.0; 3], [10.0, 0.0, 0.0], 50.0, 50.0))
        .unwrap();
    ip.push(line(1, [10.0, 0.0, 0.0], [20.0, 0.0, 0.0], 50.0, 0.0))
        .unwrap();
    let trace = run(&mut ip, 10_000);
    let min_mid = trace
        .iter()
        .filter(|t| (5.0..15.0).contains(&t.position[0]))
        .map(|t| t.path_v_mm_s)
        .fold(f64::INFINITY, f64::min);
    assert!(min_mid > 49.0, "slowed to {min_mid}");
    assert_eq!(trace.last().unwrap().position[0], 20.0);
}

#[test]
fn hold_brakes_and_resume_finishes() {
    let (mut ip, mut trace) = on_x_line(100.0, 100);
    ip.hold();
    for _ in 0..100 {
        trace.push(ip.tick());
    }
    assert_eq!(ip.state(), InterpState::Held);
    ip.resume();
    trace.extend(run(&mut ip, 10_000));
    check_limits(&trace, 50.0, 500.0);
    assert_eq!(trace.last().unwrap().position[0], 100.0);
}

#[test]
fn hold_before_the_first_segment_holds_at_the_start() {
    // The daemon's job starts before the planner has delivered its first segment: a hold
    // pressed then must hold the job at its start, not be lost.
    let mut ip = Interpolator::new(3, AxesMm::ZERO);
    ip.hold();
    ip.push(line(0, [0.0; 3], [10.0, 0.0, 0.0], 50.0, 0.0))
        .unwrap();
    for _ in 0..100 {
        let t = ip.tick();
        assert_eq!(t.position[0], 0.0);
        assert_eq!(t.state, InterpState::Held);
    }
    ip.resume();
    let trace = run(&mut ip, 10_000);
    assert_eq!(trace.last().unwrap().position[0], 10.0);
}

#[test]
fn stop_brakes_then_drops_the_rest() {
    let (mut ip, mut trace) = on_x_line(100.0, 100);
    ip.stop();
    trace.extend(run(&mut ip, 1000));
    check_limits(&trace, 50.0, 500.0);
    assert_eq!(ip.state(), InterpState::Idle);
    assert!(ip.position()[0] < 100.0);
}

#[test]
fn jerk_filter_limits_jerk_and_arrives_exactly() {
    let mut ip = Interpolator::new(3, AxesMm::ZERO);
    let mut seg = line(0, [0.0; 3], [30.0, 0.0, 0.0], 80.0, 0.0);
    seg.jerk_mm_s3 = 20_000.0;
    ip.push(seg).unwrap();
    let mut trace = vec![TickOut::default()];
    trace.extend(run(&mut ip, 10_000));
    assert!(ip.filter_ticks() > 1);
    assert_eq!(trace.last().unwrap().position[0], 30.0);
    let v: Vec<f64> = trace
        .windows(2)
        .map(|w| (w[1].position - w[0].position).norm(3) / TS_S)
        .collect();
    let a: Vec<f64> = v.windows(2).map(|w| (w[1] - w[0]) / TS_S).collect();
    for w in a.windows(2) {
        let j = (w[1] - w[0]).abs() / TS_S;
        assert!(j <= 20_000.0 * 1.001 + 1e-3, "jerk {j}");
    }
    assert!(a.iter().all(|x| x.abs() <= 500.0 * 1.001));
}

#[test]
fn axis_filter_rounds_a_smooth_corner_and_settles_exactly() {
    // Two lines with a smooth 30° corner at speed 5 mm/s, axis filter 3 ticks.
    let mut ip = Interpolator::new(3, AxesMm::ZERO);
    let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
    let mut a = line(0, [0.0; 3], [2.0, 0.0, 0.0], 20.0, 5.0);
    let mut b = line(1, [2.0, 0.0, 0.0], [2.0 + 2.0 * c, 2.0 * s, 0.0], 20.0, 0.0);
    a.axis_filter_ticks = 3;
    b.axis_filter_ticks = 3;
    b.last = true;
    ip.push(a).unwrap();
    ip.push(b).unwrap();
    let mut trace = vec![TickOut::default()];
    trace.extend(run(&mut ip, 10_000));
    assert_eq!(ip.axis_filter_ticks(), 3);
    let last = trace.last().unwrap();
    assert_eq!(&last.position.0[..3], &[2.0 + 2.0 * c, 2.0 * s, 0.0]);
    assert!(last.program_end);
    // The corner is cut (a setpoint off both lines), by much less than the raw tick.
    let off = trace
        .iter()
        .map(|t| t.position[1] - (t.position[0] - 2.0).max(0.0) * s / c)
        .fold(0.0f64, |m, d| m.max(d.abs()));
    assert!(off > 1e-6 && off < 5.0 * TS_S, "{off}");
    // Per-axis velocity of the Y axis starts over several ticks, not in one.
    let vy: Vec<f64> = trace
        .windows(2)
        .map(|w| (w[1].position[1] - w[0].position[1]) / TS_S)
        .collect();
    let first = vy.iter().position(|v| *v > 0.0).unwrap();
    assert!(vy[first] < 0.5 * 5.0 * s, "{:?}", &vy[first..first + 6]);
}

#[test]
fn a_cut_waits_for_the_spindle_a_rapid_does_not() {
    use crate::block::SpindleDir;
    let mut ip = Interpolator::new(3, AxesMm::ZERO);
    let mut cut = line(0, [0.0; 3], [1.0, 0.0, 0.0], 50.0, 0.0);
    cut.spindle.dir = SpindleDir::Cw;
    cut.spindle.s = 1000.0;
    ip.set_spindle_ready(false);
    ip.push(cut).unwrap();
    // The spindle state is in force at once, the axes wait.
    for _ in 0..50 {
        let t = ip.tick();
        assert_eq!(t.spindle.dir, SpindleDir::Cw);
        assert_eq!(t.position[0], 0.0);
        assert!(ip.waiting_for_spindle());
    }
    ip.set_spindle_ready(true);
    ip.tick();
    assert!(!ip.waiting_for_spindle());
    run(&mut ip, 1000);
    assert_eq!(ip.position()[0], 1.0);
    let mut rapid = line(1, [1.0, 0.0, 0.0], [2.0, 0.0, 0.0], 50.0, 0.0);
    rapid.rapid = true;
    ip.set_spindle_ready(false);
    ip.push(rapid).unwrap();
    run(&mut ip, 1000);
    assert_eq!(ip.position()[0], 2.0);
}

#[test]
fn floor_is_the_minimum_of_the_window() {
    // Against the minimum of a plain FIFO, on a sequence with repeats, rises and falls.
    let vals = [
        5.0,
        3.0,
        3.0,
        4.0,
        7.0,
        3.0,
        2.0,
        9.0,
        9.0,
        1.0,
        6.0,
        f64::INFINITY,
    ];
    let mut f = Floor::new(8);
    let mut fifo = std::collections::VecDeque::new();
    for (i, v) in vals.iter().enumerate() {
        f.add(*v);
        fifo.push_back(*v);
        if i % 3 == 2 {
            let out = fifo.pop_front().unwrap();
            f.remove(out);
        }
        let want = fifo.iter().copied().fold(f64::INFINITY, f64::min);
        assert_eq!(f.value(), want, "after {i}");
    }
    while let Some(out) = fifo.pop_front() {
        f.remove(out);
        let want = fifo.iter().copied().fold(f64::INFINITY, f64::min);
        assert_eq!(f.value(), want);
    }
    assert_eq!(f.value(), f64::INFINITY);
}

#[test]
fn g24_waits_for_in_position() {
    let mut ip = Interpolator::new(3, AxesMm::ZERO);
    let mut a = line(0, [0.0; 3], [1.0, 0.0, 0.0], 50.0, 0.0);
    a.wait_in_position = true;
    ip.push(a).unwrap();
    ip.push(line(1, [1.0, 0.0, 0.0], [2.0, 0.0, 0.0], 50.0, 0.0))
        .unwrap();
    ip.set_in_position(false);
    for _ in 0..500 {
        ip.tick();
    }
    assert_eq!(ip.position()[0], 1.0);
    ip.set_in_position(true);
    run(&mut ip, 1000);
    assert_eq!(ip.position()[0], 2.0);
}

/// Setpoint speeds, accelerations and jerks (finite differences along X) of one move.
fn parabolic_move(l: f64, feed: f64, a: f64, j: f64) -> (usize, f64, f64, Vec<f64>) {
    let mut ip = Interpolator::new(3, AxesMm::ZERO);
    let mut seg = line(0, [0.0; 3], [l, 0.0, 0.0], feed, 0.0);
    seg.accel_mm_s2 = a;
    seg.stop_accel_mm_s2 = a;
    seg.jerk_mm_s3 = j;
    ip.push(seg).unwrap();
    let mut x = vec![0.0];
    loop {
        let t = ip.tick();
        x.push(t.position[0]);
        if t.state == InterpState::Idle {
            break;
        }
        assert!(x.len() < 100_000);
    }
    assert_eq!(*x.last().unwrap(), l);
    let moving = x.iter().rposition(|p| *p < l).unwrap() + 1;
    let v: Vec<f64> = x.windows(2).map(|w| (w[1] - w[0]) / TS_S).collect();
    let acc: Vec<f64> = v.windows(2).map(|w| (w[1] - w[0]) / TS_S).collect();
    let jerk = acc
        .windows(2)
        .map(|w| ((w[1] - w[0]) / TS_S).abs())
        .fold(0.0, f64::max);
    let a_max = acc.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    (moving, a_max, jerk, v)
}

#[test]
fn parabolic_move_takes_the_ideal_jerk_limited_time() {
    // (length, feed, a, J): a reached; pure parabola (manual's F300, P = 50000); short moves.
    for (l, feed, a, j) in [
        (100.0, 50.0, 500.0, 20_000.0),
        (30.0, 80.0, 500.0, 20_000.0),
        (5.0, 5.0, 500.0, crate::plan::jerk_from_p_mm_s3(50_000.0)),
        (2.0, 100.0, 800.0, 40_000.0),
        // Too short for F: the filter is sized for the peak the move reaches.
        (2.0, 100.0, 600.0, crate::plan::jerk_from_p_mm_s3(50_000.0)),
    ] {
        let (ticks, a_max, jerk, _) = parabolic_move(l, feed, a, j);
        let t = ticks as f64 * TS_S;
        let ideal = ideal_jerk_limited_move_s(l, feed, a, j);
        assert!(
            t <= ideal * 1.03 + 2.0 * TS_S,
            "{l} mm F{feed}: {t} s vs {ideal} s"
        );
        assert!(a_max <= a * (1.0 + 1e-6), "accel {a_max} > {a}");
        assert!(jerk <= j * (1.0 + 1e-6) + 1e-6, "jerk {jerk} > {j}");
    }
}

#[test]
fn pure_parabola_ramp_matches_the_manual() {
    // F300 mm/min, P = 50000: T = 1.478·√(F/P) from rest to F.
    let j = crate::plan::jerk_from_p_mm_s3(50_000.0);
    let (_, _, _, v) = parabolic_move(20.0, 5.0, 500.0, j);
    let reached = v.iter().position(|x| *x >= 5.0 * (1.0 - 1e-9)).unwrap() + 1;
    let manual = 1.478 * (300.0f64 / 50_000.0).sqrt();
    let t = reached as f64 * TS_S;
    assert!((t - manual).abs() <= 0.05 * manual, "{t} s vs {manual} s");
}

/// Ticks until the path holds at rest; the held tick.
fn until_held(ip: &mut Interpolator, trace: &mut Vec<TickOut>) -> TickOut {
    for _ in 0..10_000 {
        let t = ip.tick();
        trace.push(t);
        if t.state == InterpState::Held {
            return t;
        }
    }
    panic!("never held: {:?}", trace.last());
}

/// Single block switched on while the path runs through smooth junctions: it stops at rest
/// exactly on a block end (the first it can still brake for), names that block, and each
/// resume runs one more block; the limits hold throughout.
#[test]
fn single_block_stops_exactly_at_a_block_end() {
    let mut ip = Interpolator::new(3, AxesMm::ZERO);
    for k in 0..6u32 {
        let x = k as f64 * 2.0;
        let v_end = if k == 5 { 0.0 } else { 50.0 };
        ip.push(line(k, [x, 0.0, 0.0], [x + 2.0, 0.0, 0.0], 50.0, v_end))
            .unwrap();
    }
    let mut trace = vec![TickOut::default()];
    // At full speed inside block 0 (1.5 mm in): its end is 0.5 mm ahead, 2.5 mm of braking
    // are needed, so the first end it can brake for is that of block 1 or 2.
    while trace.last().unwrap().position[0] < 1.5 {
        trace.push(ip.tick());
    }
    ip.set_single_block(true);
    let held = until_held(&mut ip, &mut trace);
    assert!(ip.at_block_stop());
    let x = held.position[0];
    assert!([4.0, 6.0].contains(&x), "held at {x}");
    assert_eq!(
        held.seq as f64,
        x / 2.0 - 1.0,
        "names the block just finished"
    );
    for seq in (held.seq + 1)..5 {
        ip.resume();
        let t = until_held(&mut ip, &mut trace);
        assert_eq!((t.position[0], t.seq), ((seq + 1) as f64 * 2.0, seq));
    }
    ip.set_single_block(false);
    ip.resume();
    trace.extend(run(&mut ip, 10_000));
    assert_eq!(trace.last().unwrap().position[0], 12.0);
    check_limits(&trace, 50.0, 500.0);
}

/// A deterministic spread of values over several decades (no rand dependency here).
fn spread(seed: &mut u64, lo: f64, hi: f64) -> f64 {
    *seed = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    let f = (*seed >> 11) as f64 / (1u64 << 53) as f64;
    lo * (hi / lo).powf(f)
}

#[test]
fn skipped_caps_never_lower_the_limit() {
    // `v_brake_at_least` and `ahead::group_bound_clear` skip a cap only when v_brake from it
    // is at least the limit: the look-ahead's result is then what evaluating it gives.
    let mut seed = 7u64;
    let (mut skipped, mut grouped) = (0, 0);
    for _ in 0..200_000 {
        let a = spread(&mut seed, 1e-3, 1e5);
        let cur = spread(&mut seed, 1e-3, 2e3);
        let cap = cur * spread(&mut seed, 1e-6, 1.0);
        let d = spread(&mut seed, 1e-7, 1e3);
        let coast = (spread(&mut seed, 1.0, 300.0) - 1.0).floor();
        if Interpolator::v_brake_at_least(d, cap, a, coast, cur) {
            skipped += 1;
            assert!(
                Interpolator::v_brake(d, cap, a, coast) >= cur,
                "d {d} cap {cap} a {a} coast {coast} cur {cur}"
            );
        }
        // A stretch of caps in [c_lo, cur), distances ≥ d, accelerations in [a_lo, a].
        let c_lo = cap * spread(&mut seed, 1e-3, 1.0);
        let a_lo = a * spread(&mut seed, 1e-2, 1.0);
        let lead_s = if coast > 0.0 { 0.004 * coast } else { 0.0 };
        if ahead::group_bound_clear(cur, c_lo, d, lead_s, a_lo, a, coast) {
            grouped += 1;
            for _ in 0..8 {
                let c = c_lo + (cur - c_lo) * spread(&mut seed, 1e-9, 1.0).min(0.999_999);
                let dk = d * spread(&mut seed, 1.0, 3.0);
                let ak = a_lo * (a / a_lo).powf(spread(&mut seed, 1e-6, 1.0));
                let dc = dk - c * lead_s;
                assert!(
                    c >= cur || Interpolator::v_brake(dc, c, ak, coast) >= cur,
                    "group: d {dk} cap {c} a {ak} coast {coast} cur {cur}"
                );
            }
        }
    }
    assert!(skipped > 1000 && grouped > 1000, "{skipped} {grouped}");
}

/// Uniform in [0, 1).
fn uniform(seed: &mut u64) -> f64 {
    spread(seed, 1.0, 2.0).log2()
}

/// A random polyline of `n` short lines (linear profile), now and then a corner and a stop
/// point: the dense paths the piecewise walk is for. `smooth`: caps and accelerations that
/// change slowly along the path, with a dip now and then (as on a dense curve); else
/// independent per segment, lengths 0.002-0.6 mm.
fn random_dense_segments(seed: &mut u64, n: usize, smooth: bool) -> Vec<Segment> {
    let (mut p, mut dir) = ([0.0; 3], [1.0, 0.0, 0.0]);
    let (base, phase) = (spread(seed, 30.0, 200.0), spread(seed, 1.0, 100.0));
    let mut out = vec![];
    for i in 0..n {
        let turn = if uniform(seed) < 0.02 { 1.5 } else { 0.1 };
        for d in &mut dir {
            *d += turn * (2.0 * uniform(seed) - 1.0);
        }
        let norm = (dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]).sqrt();
        dir = dir.map(|d| d / norm);
        let len = if smooth {
            spread(seed, 0.02, 0.1)
        } else {
            spread(seed, 2e-3, 0.6)
        };
        let q = [0, 1, 2].map(|k| p[k] + len * dir[k]);
        let x = i as f64 / 20.0 + phase;
        let (cap, accel) = if !smooth {
            (spread(seed, 5.0, 300.0), spread(seed, 50.0, 5000.0))
        } else {
            let dip = if i % 150 == 149 {
                spread(seed, 0.1, 0.7)
            } else {
                1.0
            };
            (
                dip * base * (1.0 + 0.3 * x.sin()) * spread(seed, 0.98, 1.0),
                (600.0 + 400.0 * (0.7 * x).cos()) * spread(seed, 0.8, 1.0),
            )
        };
        let stop = i + 1 == n || uniform(seed) < 0.002;
        let v_end = if stop {
            0.0
        } else {
            cap * spread(seed, 0.7, 1.0)
        };
        let mut s = line(i as u32, p, q, spread(seed, 20.0, 300.0), v_end);
        s.junction_cap_mm_s = if stop { 0.0 } else { cap };
        s.v_max_mm_s = spread(seed, 100.0, 400.0);
        s.accel_mm_s2 = accel;
        s.stop_accel_mm_s2 = accel * spread(seed, 0.5, 1.0);
        out.push(s);
        p = q;
    }
    out
}

/// The piecewise walk leaves early where its result cannot exceed the exact limits
/// (`piecewise::Settled`) and skips the caps of groups that cannot lower a needed R
/// (`piecewise_group_clear`): the trajectory must be bit-identical to the full walk's, on
/// random dense paths with feed holds and override changes.
#[test]
fn piecewise_bounds_keep_the_trajectory() {
    let mut seed = 32u64;
    let (mut ticks, mut left, mut groups) = (0, 0, 0);
    for case in 0..40 {
        let segs = random_dense_segments(&mut seed, 1500, case % 2 == 0);
        let mut ips = [true, false].map(|bounds| {
            let mut ip = Interpolator::new(3, AxesMm::ZERO);
            ip.pw_bounds = bounds;
            for s in &segs {
                ip.push(*s).unwrap();
            }
            ip
        });
        for t in 0..200_000 {
            if t % 997 == 500 {
                let ov = spread(&mut seed, 10.0, 150.0);
                ips.iter_mut().for_each(|ip| ip.set_override(ov));
            }
            if case % 4 == 1 && t % 1500 == 700 {
                ips.iter_mut().for_each(|ip| ip.hold());
            }
            if case % 4 == 1 && t % 1500 == 1000 {
                ips.iter_mut().for_each(|ip| ip.resume());
            }
            let (a, b) = (ips[0].tick(), ips[1].tick());
            assert_eq!(a, b, "case {case} tick {t}");
            ticks += 1;
            if a.state == InterpState::Idle {
                break;
            }
        }
        left += ips[0].pw_stats.0;
        groups += ips[0].pw_stats.1;
        assert_eq!(ips[1].pw_stats, (0, 0));
    }
    eprintln!("{ticks} ticks: {left} walks left early, {groups} groups skipped");
    assert!(left > 1000 && groups > 100);
}

/// `piecewise::Settled`: an R at or below a threshold inverts (`g_inverse`) to less than the
/// exact limit it was made for, on random stretches of E within one tick's distance (as the
/// walk records them), random speeds, accelerations 1e-3..1e5 mm/s².
#[test]
fn settled_thresholds_bound_the_inversion() {
    let mut seed = 11u64;
    let mut ip = Interpolator::new(3, AxesMm::ZERO);
    let mut checked = 0;
    for _ in 0..100_000 {
        let v_now = spread(&mut seed, 1e-3, 2e3);
        let w = v_now * TS_S;
        // (The first segment is the one the raw position is on: it starts at or before it.)
        let first = w * spread(&mut seed, 1e-4, 2.0);
        let mut start = -first * spread(&mut seed, 1e-9, 1.0);
        let (mut e, mut points, mut a_hi) = (0.0, 0, 0.0f64);
        while start <= w && points < 20 {
            let len = if points == 0 {
                first
            } else {
                w * spread(&mut seed, 1e-4, 2.0)
            };
            let end = start + len;
            let a = spread(&mut seed, 1e-3, 1e5);
            a_hi = a_hi.max(a);
            e += a * (end - start.max(0.0));
            ip.pw_points[points] = (end, e, a);
            points += 1;
            start = end;
        }
        let exact = v_now * spread(&mut seed, 1e-6, 1.0).min(0.999_999);
        let need = (true, spread(&mut seed, 1e-3, 1.0) < 0.5);
        let mut settled = piecewise::Settled::new(need, (exact, exact), v_now, a_hi, 0.0);
        let g = |v: f64| v * v + 2.0 * ip.e_at(points, v * TS_S);
        if spread(&mut seed, 1e-3, 1.0) < 0.7 {
            settled.raise(g);
        }
        for thr in [settled.r.0, settled.r.1] {
            if thr.is_finite() && thr > 0.0 {
                let r = thr * (1.0 - spread(&mut seed, 1e-17, 1e-3));
                for r in [thr, r] {
                    let v = ip.g_inverse(points, r, v_now);
                    assert!(
                        v < exact,
                        "r {r} thr {thr} v {v} exact {exact} v_now {v_now}"
                    );
                    checked += 1;
                }
            }
        }
    }
    assert!(checked > 100_000, "{checked}");
}

/// A straight X line of 80 segments of 0.5 mm, all at 1000 mm/s² but one at `a_low` (a line
/// next to a turn), a cap of 20 mm/s at the end of segment 70 (x = 35.5) and a stop at the
/// end; F 100 mm/s. The
/// trace and the accelerations of the segments.
fn braking_through_a_low_segment(a_low: f64, low: usize) -> (Vec<TickOut>, Vec<f64>) {
    let mut ip = Interpolator::new(3, AxesMm::ZERO);
    let mut accels = vec![];
    for i in 0..80 {
        let x = 0.5 * i as f64;
        let v_end = match i {
            70 => 20.0,
            79 => 0.0,
            _ => 100.0,
        };
        let mut s = line(i as u32, [x, 0.0, 0.0], [x + 0.5, 0.0, 0.0], 100.0, v_end);
        let a = if i == low { a_low } else { 1000.0 };
        s.accel_mm_s2 = a;
        s.stop_accel_mm_s2 = a;
        s.junction_cap_mm_s = v_end;
        accels.push(a);
        ip.push(s).unwrap();
    }
    let mut trace = vec![TickOut::default()];
    trace.extend(run(&mut ip, 10_000));
    (trace, accels)
}

/// Issue #32: the look-ahead brakes for a cap with the acceleration of each stretch of the way
/// (`piecewise`), not with the smallest one on the whole way: a 0.5 mm segment of low
/// acceleration before a cap no longer makes the whole braking zone slow. Each tick's speed
/// still falls by at most the smallest acceleration of the segments it covers, and the cap
/// point is passed at its cap.
#[test]
fn braking_uses_each_stretch_s_own_acceleration() {
    let (trace, accels) = braking_through_a_low_segment(300.0, 67);
    let x = |t: &TickOut| t.position[0];
    let mut prev_v = 0.0;
    for w in trace.windows(2) {
        let v = (x(&w[1]) - x(&w[0])) / TS_S;
        let (from, to) = (x(&w[0]), x(&w[1]));
        let a_min = (0..80)
            .filter(|&i| 0.5 * (i as f64) < to && 0.5 * (i + 1) as f64 > from)
            .map(|i| accels[i])
            .fold(f64::INFINITY, f64::min);
        assert!(
            prev_v - v <= a_min * TS_S * (1.0 + 1e-9) + 1e-9,
            "drop {} at x {from}..{to}, a {a_min}",
            prev_v - v
        );
        if from < 35.5 && to > 35.5 {
            assert!(v <= 20.0 + 1e-9, "cap passed at {v}");
        }
        prev_v = v;
    }
    // At x = 28 braking with 300 mm/s² all the way (the smallest on the way) allows only
    // √(20² + 2·300·7.5) = 70 mm/s; each stretch's own allows the feed.
    let at_28 = trace
        .windows(2)
        .find(|w| x(&w[0]) <= 28.0 && x(&w[1]) > 28.0)
        .map(|w| (x(&w[1]) - x(&w[0])) / TS_S)
        .unwrap();
    assert!(at_28 > 99.0, "{at_28}");
}

/// Arc length of `p` on the path (0,0) → (5,0) → (10,5).
fn s_on_corner(p: &AxesMm) -> f64 {
    if p[1] == 0.0 && p[0] <= 5.0 {
        p[0]
    } else {
        5.0 + (p[0] - 5.0).hypot(p[1])
    }
}

/// The corner of `s_on_corner` run to its end: a 5 mm line into the corner (cap 30 mm/s),
/// then 5 mm at 45°, both with budget 200 mm/s² and free acceleration 800 mm/s² up to
/// `v_cover`; the second line's start budget `accel_start_mm_s2` (0: none). The arc length
/// of every tick, from rest.
fn corner_run(v_cover: f64, accel_start_mm_s2: f64) -> Vec<f64> {
    let mut ip = Interpolator::new(3, AxesMm::ZERO);
    let mut a = line(0, [0.0; 3], [5.0, 0.0, 0.0], 100.0, 30.0);
    a.junction_cap_mm_s = 30.0;
    let mut b = line(1, [5.0, 0.0, 0.0], [10.0, 5.0, 0.0], 100.0, 0.0);
    for s in [&mut a, &mut b] {
        s.accel_mm_s2 = 200.0;
        s.stop_accel_mm_s2 = 200.0;
        s.free_accel_mm_s2 = 800.0;
        s.free_accel_v_max_mm_s = v_cover;
    }
    b.accel_start_mm_s2 = accel_start_mm_s2;
    ip.push(a).unwrap();
    ip.push(b).unwrap();
    let mut trace = vec![TickOut::default()];
    trace.extend(run(&mut ip, 10_000));
    assert_eq!(&trace.last().unwrap().position.0[..2], &[10.0, 5.0]);
    trace.iter().map(|t| s_on_corner(&t.position)).collect()
}

/// Issue #32: a tick whose step and the step before it stay inside one line has no turn in
/// its second difference and may use the line's free acceleration; the ticks whose steps
/// touch the junction keep the line's own (the share the turn leaves it), and the free
/// ticks never carry the line past the speed its acceleration was planned for.
#[test]
fn ticks_inside_a_line_use_its_free_acceleration() {
    for v_cover in [f64::INFINITY, 20.0] {
        let s = corner_run(v_cover, 0.0);
        let touches = |k: usize| s[k - 1] < 5.0 && s[k] >= 5.0;
        let mut free_used = false;
        for k in 2..s.len() {
            let (v0, v1) = ((s[k - 1] - s[k - 2]) / TS_S, (s[k] - s[k - 1]) / TS_S);
            let acc = (v1 - v0) / TS_S;
            assert!(acc.abs() <= 800.0 * (1.0 + 1e-9), "tick {k}: {acc}");
            if touches(k) || touches(k - 1) || v1 > v_cover + 1e-9 {
                assert!(acc <= 200.0 * (1.0 + 1e-9), "tick {k}: {acc} at {v1}");
            }
            free_used |= acc > 201.0;
        }
        assert!(free_used);
    }
}

/// Issue #32: a braking tick whose two steps stay inside one line brakes at the line's free
/// acceleration (`piecewise::stretches`, `Interpolator::free_down_mm_s2`); the ticks whose
/// steps touch a junction brake at most at the budgets of the segments they cover, and the
/// cap is passed at its cap.
#[test]
fn braking_inside_a_line_uses_its_free_acceleration() {
    let mut ip = Interpolator::new(3, AxesMm::ZERO);
    let ends = [(40.0, 100.0), (40.5, 10.0), (50.0, 0.0)];
    let mut from = 0.0;
    for (i, &(to, v_end)) in ends.iter().enumerate() {
        let mut s = line(i as u32, [from, 0.0, 0.0], [to, 0.0, 0.0], 100.0, v_end);
        s.junction_cap_mm_s = v_end;
        s.accel_mm_s2 = 200.0;
        s.stop_accel_mm_s2 = 200.0;
        s.free_accel_mm_s2 = 800.0;
        s.free_accel_v_max_mm_s = f64::INFINITY;
        ip.push(s).unwrap();
        from = to;
    }
    let mut trace = vec![TickOut::default()];
    trace.extend(run(&mut ip, 10_000));
    let x: Vec<f64> = trace.iter().map(|t| t.position[0]).collect();
    assert_eq!(*x.last().unwrap(), 50.0);
    let mut free_braking = false;
    for k in 2..x.len() {
        let (v0, v1) = ((x[k - 1] - x[k - 2]) / TS_S, (x[k] - x[k - 1]) / TS_S);
        let acc = (v1 - v0) / TS_S;
        assert!(acc.abs() <= 800.0 * (1.0 + 1e-9), "tick {k}: {acc}");
        let touches = [40.0, 40.5].iter().any(|&j| x[k - 2] < j && x[k] > j);
        if touches {
            assert!(
                acc >= -200.0 * (1.0 + 1e-9),
                "tick {k}: {acc} at {}",
                x[k - 1]
            );
        }
        if x[k - 1] < 40.5 && x[k] >= 40.5 {
            assert!(v1 <= 10.0 + 1e-9, "cap passed at {v1}");
        }
        free_braking |= acc < -201.0;
    }
    assert!(free_braking);
}

/// Issue #32: a tick whose steps touch one junction of a line only uses that junction's
/// budget (`Segment::accel_start_mm_s2`, `accel_end_mm_s2`), not the line's budget for
/// both ends. Accelerating: after the corner at s = 5 the tick whose last step crossed it
/// (and whose next one stays inside the line) accelerates by the start budget, the tick
/// crossing it by the budget of the line before. Braking: the ticks whose tick point lies
/// before the gentle junction at x = 40 and whose next step crosses it brake by more than
/// the line's budget for both ends, and the cap after it is passed at its cap.
#[test]
fn ticks_touching_one_junction_use_that_junction_s_budget() {
    let s = corner_run(f64::INFINITY, 400.0);
    let crosses = |k: usize| s[k - 1] < 5.0 && s[k] >= 5.0;
    let mut start_used = false;
    for k in 2..s.len() {
        let (v0, v1) = ((s[k - 1] - s[k - 2]) / TS_S, (s[k] - s[k - 1]) / TS_S);
        let acc = (v1 - v0) / TS_S;
        assert!(acc.abs() <= 800.0 * (1.0 + 1e-9), "tick {k}: {acc}");
        if crosses(k) {
            assert!(acc <= 200.0 * (1.0 + 1e-9), "tick {k}: {acc}");
        }
        if crosses(k - 1) {
            assert!(acc <= 400.0 * (1.0 + 1e-9), "tick {k}: {acc}");
            start_used |= acc > 201.0;
        }
    }
    assert!(start_used);

    let mut ip = Interpolator::new(3, AxesMm::ZERO);
    let mut a = line(0, [0.0; 3], [40.0, 0.0, 0.0], 100.0, 20.0);
    a.junction_cap_mm_s = 20.0;
    a.accel_mm_s2 = 200.0;
    a.stop_accel_mm_s2 = 200.0;
    a.free_accel_mm_s2 = 400.0;
    a.free_accel_v_max_mm_s = f64::INFINITY;
    a.accel_start_mm_s2 = 200.0;
    a.accel_end_mm_s2 = 400.0;
    let mut b = line(1, [40.0, 0.0, 0.0], [50.0, 0.0, 0.0], 100.0, 0.0);
    b.accel_mm_s2 = 800.0;
    b.stop_accel_mm_s2 = 800.0;
    ip.push(a).unwrap();
    ip.push(b).unwrap();
    let mut trace = vec![TickOut::default()];
    trace.extend(run(&mut ip, 10_000));
    let x: Vec<f64> = trace.iter().map(|t| t.position[0]).collect();
    assert_eq!(*x.last().unwrap(), 50.0);
    let mut end_used = false;
    for k in 2..x.len() {
        let (v0, v1) = ((x[k - 1] - x[k - 2]) / TS_S, (x[k] - x[k - 1]) / TS_S);
        let acc = (v1 - v0) / TS_S;
        assert!(acc.abs() <= 800.0 * (1.0 + 1e-9), "tick {k}: {acc}");
        // The tick point before the junction, within a step of it.
        if x[k - 1] < 40.0 && x[k - 1] + (x[k - 1] - x[k - 2]).max(x[k] - x[k - 1]) >= 40.0 {
            assert!(acc >= -400.0 * (1.0 + 1e-9), "tick {k}: {acc}");
            end_used |= acc < -201.0;
        }
        if x[k - 1] < 40.0 && x[k] >= 40.0 {
            assert!(v1 <= 20.0 + 1e-9, "cap passed at {v1}");
        }
    }
    assert!(end_used);
}

/// A new job names no block until its first segment is followed: the ticks between its
/// start and its first segment showed the last job's block (a status "in N30" of a job
/// still planning its N10).
#[test]
fn a_new_job_names_no_block_before_its_first_segment() {
    let mut ip = Interpolator::new(3, AxesMm::ZERO);
    let mut s = line(7, [0.0; 3], [1.0, 0.0, 0.0], 100.0, 0.0);
    s.n = Some(30);
    s.line = 3;
    ip.push(s).unwrap();
    let last = *run(&mut ip, 10_000).last().unwrap();
    assert_eq!((last.seq, last.n, last.line), (7, Some(30), 3));
    // Idle after the job: the block it ended in stays shown.
    assert_eq!(ip.tick().n, Some(30));
    ip.forget_block();
    let t = ip.tick();
    assert_eq!((t.seq, t.n, t.line), (0, None, 0));
    let mut next = line(1, [1.0, 0.0, 0.0], [2.0, 0.0, 0.0], 100.0, 0.0);
    next.n = Some(10);
    ip.push(next).unwrap();
    assert_eq!(ip.tick().n, Some(10));
}

/// The segments of a dense polygon (a circle of radius 10 mm in 0.1 mm chords, F6000, G23) on
/// the reference machine of issue #49 with a parabolic constants file: the jerk-limited box
/// judges them.
fn parabolic_circle_segments() -> (crate::plan::PlannerConfig, Vec<Segment>) {
    use crate::block::{Block, BlockKind, Comp, Continuity, Feed, Path, Plane, Spindle};
    use crate::plan::{AxisLimits, Planner, PlannerConfig};
    let c = crate::constants::Constants::parse("R338=0.020\nR384=0.008\nR385=1.000\n").unwrap();
    let axis = AxisLimits {
        v_max_mm_s: 20000.0 / 60.0,
        a_max_mm_s2: 1000.0,
    };
    let cfg = PlannerConfig::for_machine(&[axis; 3], 0.0, Some(&c));
    let point = |i: usize| {
        let phi = i as f64 * 0.01;
        AxesMm([
            10.0 * phi.cos() - 10.0,
            10.0 * phi.sin(),
            0.0,
            0.0,
            0.0,
            0.0,
        ])
    };
    let mut pl = Planner::new(cfg.clone(), 1);
    let mut segs = vec![];
    for i in 0..600 {
        let block = Block {
            seq: i as u32,
            n: None,
            line: i as u32 + 1,
            kind: BlockKind::Motion {
                start: point(i),
                end: point(i + 1),
                path: Path::Line,
            },
            feed: Feed::MmPerMin(6000.0),
            plane: Plane::G17,
            comp: Comp::Off,
            continuity: Continuity::G23,
            dyn_set: 1,
            spindle: Spindle::default(),
            m: [None; 4],
        };
        while !pl.wants_input() {
            segs.extend(pl.poll());
        }
        pl.push(&block).unwrap();
        while let Some(s) = pl.poll() {
            segs.push(s);
        }
    }
    pl.finish();
    while let Some(s) = pl.poll() {
        segs.push(s);
    }
    (cfg, segs)
}

/// Largest |third difference| of each axis's setpoints over its jerk limit × Ts³.
fn worst_axis_jerk(trace: &[TickOut], j_mm_s3: f64) -> f64 {
    let mut worst = 0.0f64;
    for w in trace.windows(4) {
        for ax in 0..3 {
            let d3 = w[3].position[ax] - 3.0 * w[2].position[ax] + 3.0 * w[1].position[ax]
                - w[0].position[ax];
            worst = worst.max(d3.abs() / (j_mm_s3 * TS_S.powi(3)));
        }
    }
    worst
}

/// The jerk-limited box hands the motion to the envelope at rest where it finds no step
/// (`jerk_box::REFUSE_TICKS`): here forced at a hold. The envelope sizes its jerk filter and
/// runs on to the end within the axes' jerk; at the next rest the box may take over again.
#[test]
fn the_jerk_box_hands_a_refused_departure_to_the_envelope() {
    let (cfg, segs) = parabolic_circle_segments();
    assert!(segs.iter().all(|s| s.axis_box.jerk.is_set()));
    let mut ip = Interpolator::new(3, segs[0].path.start());
    let (mut next, mut trace, mut held) = (0, vec![], false);
    let mut envelope_ran = false;
    for tick in 0..20_000 {
        while next < segs.len() && ip.has_room() {
            ip.push(segs[next]).unwrap();
            next += 1;
        }
        if tick == 100 {
            assert_eq!(ip.filter_ticks(), 1, "the box runs the circle");
            ip.hold();
        }
        if !held && ip.state() == InterpState::Held {
            held = true;
            (ip.jbox_refused, ip.jbox_refused_s) = (true, ip.raw_s());
            ip.resume();
        }
        envelope_ran |= held && ip.filter_ticks() > 1;
        let out = ip.tick();
        trace.push(out);
        if out.state == InterpState::Idle && next == segs.len() {
            break;
        }
    }
    assert!(held && envelope_ran);
    assert_eq!(trace.last().unwrap().state, InterpState::Idle);
    let end = segs.last().unwrap().path.end();
    assert!((trace.last().unwrap().position - end).norm(3) < 1e-9);
    let j_axis = cfg.axis_j_max_mm_s3[0];
    let worst = worst_axis_jerk(&trace, j_axis);
    assert!(worst <= 1.0 + 1e-6, "axis jerk {worst}");
}

/// A refusal while the raw position rests but the axis filter has not settled yet (forced as
/// the hold's braking comes to rest, resumed at once): the raw position waits for the filters
/// to settle and the envelope's jerk filter to be sized, and the envelope never runs with the
/// jerk filter out (it would, at an acceleration of J·Ts: within the jerk, but crawling).
#[test]
fn a_refusal_before_the_filters_settle_waits_for_them() {
    let (cfg, segs) = parabolic_circle_segments();
    let mut ip = Interpolator::new(3, segs[0].path.start());
    let (mut next, mut trace, mut forced) = (0, vec![], false);
    let mut unfiltered_envelope = 0;
    for tick in 0..20_000 {
        while next < segs.len() && ip.has_room() {
            ip.push(segs[next]).unwrap();
            next += 1;
        }
        if tick == 100 {
            ip.hold();
        }
        if !forced && tick > 100 && ip.raw_v_mm_s == 0.0 && !ip.settled() {
            forced = true;
            (ip.jbox_refused, ip.jbox_refused_s) = (true, ip.raw_s());
            ip.resume();
        }
        let out = ip.tick();
        if forced && ip.raw_v_mm_s > 0.0 && ip.filter_ticks() == 1 && !ip.jbox_applies() {
            unfiltered_envelope += 1;
        }
        trace.push(out);
        if out.state == InterpState::Idle && next == segs.len() {
            break;
        }
    }
    assert!(forced);
    assert_eq!(unfiltered_envelope, 0);
    assert_eq!(trace.last().unwrap().state, InterpState::Idle);
    let worst = worst_axis_jerk(&trace, cfg.axis_j_max_mm_s3[0]);
    assert!(worst <= 1.0 + 1e-6, "axis jerk {worst}");
}
