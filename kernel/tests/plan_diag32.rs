//! Diagnostics for issue #32 (ignored: they measure, they assert nothing). Where the time
//! goes on the reference paths, split by cause: the planner's junction caps against the
//! exact bound, the planner's accelerations against the full path acceleration (both as a
//! continuous-time forward/backward pass like the reference's exact one), and the
//! interpolator's ticks against that continuous profile; and the tick where an axis comes
//! closest to its limit. Run:
//! `DIAG_PATHS=splines,arcs cargo test -p kernel --release --test plan_diag32 -- --ignored --nocapture`
//! (`DIAG_DUMP=1` lists every junction).
mod plan_common;

use kernel::units::{AxesMm, TS_S};
use plan_common::*;

fn pass_time(caps: &[f64], a: &[f64], l: &[f64], vseg: &[f64]) -> f64 {
    pass_profile(caps, a, l, vseg).0
}

/// time, and per segment (v0, v1, peak)
fn pass_profile(caps: &[f64], a: &[f64], l: &[f64], vseg: &[f64]) -> (f64, Vec<(f64, f64, f64)>) {
    let mut prof = vec![];
    let n = l.len();
    let mut end = caps.to_vec();
    end[n - 1] = 0.0;
    for k in (1..n).rev() {
        end[k - 1] = end[k - 1].min((end[k] * end[k] + 2.0 * a[k] * l[k]).sqrt());
    }
    let mut t = 0.0;
    let mut v0: f64 = 0.0;
    for k in 0..n {
        let (ak, lk) = (a[k], l[k]);
        end[k] = end[k].min((v0 * v0 + 2.0 * ak * lk).sqrt());
        let v1 = end[k];
        let peak = vseg[k].min(((2.0 * ak * lk + v0 * v0 + v1 * v1) / 2.0).sqrt());
        let ramps = (2.0 * peak * peak - v0 * v0 - v1 * v1) / (2.0 * ak);
        t += (peak - v0) / ak + (peak - v1) / ak + (lk - ramps).max(0.0) / peak;
        prof.push((v0, v1, peak));
        v0 = v1;
    }
    (t, prof)
}

#[test]
#[ignore]
fn where_the_time_goes() {
    let cfg = reference_config();
    let which = std::env::var("DIAG_PATHS").unwrap_or("splines,arcs".into());
    for p in reference_paths() {
        if !which.split(',').any(|w| w == p.name) {
            continue;
        }
        let r = run(cfg.clone(), &p.blocks);
        let segs = &r.segments;
        let n = segs.len();
        let mut u = vec![];
        let mut l = vec![];
        let mut vseg = vec![];
        let mut a_full = vec![];
        for s in segs {
            let kernel::plan::SegPath::Line { start, end } = s.path else {
                panic!()
            };
            let d = end - start;
            let len = d.norm(3);
            let uu = d * (1.0 / len);
            u.push(uu);
            l.push(len);
            let mut v = 100.0f64;
            let mut a = f64::INFINITY;
            for k in 0..3 {
                if uu[k].abs() > 1e-12 {
                    v = v.min(333.333333 / uu[k].abs());
                    a = a.min(1000.0 / uu[k].abs());
                }
            }
            vseg.push(v);
            a_full.push(a);
        }
        let mut cap_ex = vec![0.0; n];
        for i in 0..n - 1 {
            let du: AxesMm = u[i + 1] - u[i];
            let chord = du.norm(3);
            let mut c = vseg[i].min(vseg[i + 1]);
            if chord > 1e-12 {
                for k in 0..3 {
                    if du[k].abs() > 1e-15 {
                        c = c.min(1000.0 * TS_S / du[k].abs());
                    }
                }
                c = c.min(1000.0 * TS_S / chord);
                let half = (chord / 2.0).min(1.0).asin();
                let tan = half.tan();
                if tan > 0.0 {
                    c = c.min(0.008 / (TS_S * tan));
                }
            }
            cap_ex[i] = c;
        }
        let cap_pl: Vec<f64> = segs
            .iter()
            .map(|s| {
                if s.v_end_mm_s == 0.0 {
                    0.0
                } else {
                    s.junction_cap_mm_s
                }
            })
            .collect();
        let a_pl: Vec<f64> = segs.iter().map(|s| s.accel_mm_s2).collect();
        let t_ex = pass_time(&cap_ex, &a_full, &l, &vseg);
        let t_capfull = pass_time(&cap_pl, &a_full, &l, &vseg);
        let capmin: Vec<f64> = cap_pl.iter().zip(&cap_ex).map(|(a, b)| a.min(*b)).collect();
        let t_capmin = pass_time(&capmin, &a_full, &l, &vseg);
        let a_min: Vec<f64> = a_pl.iter().zip(&a_full).map(|(a, b)| a.min(*b)).collect();
        let t_exa = pass_time(&cap_ex, &a_min, &l, &vseg);
        let t_pl = pass_time(&capmin, &a_min, &l, &vseg);
        {
            // Planner caps with its stops passed at the exact caps (full accelerations).
            let unstop: Vec<f64> = capmin
                .iter()
                .zip(&cap_ex)
                .map(|(a, b)| if *a == 0.0 { *b } else { *a })
                .collect();
            println!(
                "  planner caps, stops at exact, full a {:.3}; with planner a {:.3}",
                pass_time(&unstop, &a_full, &l, &vseg),
                pass_time(&unstop, &a_min, &l, &vseg)
            );
        }
        let stops = segs.iter().filter(|s| s.v_end_mm_s == 0.0).count();
        let stops_junc = segs
            .iter()
            .filter(|s| s.v_end_mm_s == 0.0 && s.junction_cap_mm_s > 0.0)
            .count();
        println!(
            "{}: n {n}, ticks {:.3} s; exact {:.3}; planner caps+full a {:.3}; min caps+full a {:.3}; exact caps+planner a {:.3}; min caps + planner a {:.3}; stops {stops} (planned {stops_junc})",
            p.name,
            r.time_s(),
            t_ex,
            t_capfull,
            t_capmin,
            t_exa,
            t_pl
        );
        {
            let (_, prof) = pass_profile(&capmin, &a_min, &l, &vseg);
            let mut starts = vec![0.0];
            for k in 0..n {
                let x = starts[k] + l[k];
                starts.push(x);
            }
            let mut lost = [0.0f64; 3];
            let mut env_t = [0.0f64; 3];
            let mut seg = 0usize;
            let mut pos = 0.0f64;
            let mut prev = r.ticks[0].position;
            for t in &r.ticks[1..] {
                let ds = (t.position - prev).norm(3);
                prev = t.position;
                let mid = pos + ds / 2.0;
                pos += ds;
                while seg + 1 < n && starts[seg + 1] < mid {
                    seg += 1;
                }
                let x = mid - starts[seg];
                let (v0, v1, pk) = prof[seg];
                let a = a_min[seg];
                let va = (v0 * v0 + 2.0 * a * x).sqrt();
                let vb = (v1 * v1 + 2.0 * a * (l[seg] - x).max(0.0)).sqrt();
                let (v, c) = if va <= vb && va <= pk {
                    (va, 0)
                } else if vb <= pk {
                    (vb, 1)
                } else {
                    (pk, 2)
                };
                let v = v.max(1e-3);
                lost[c] += TS_S - ds / v;
                env_t[c] += ds / v;
            }
            println!(
                "  interp loss vs envelope: accel {:.3} brake {:.3} flat {:.3} (envelope time accel {:.3} brake {:.3} flat {:.3})",
                lost[0], lost[1], lost[2], env_t[0], env_t[1], env_t[2]
            );
        }
        // histogram of cap ratio at junctions where exact cap < feed
        let mut hist = [0usize; 12];
        for i in 0..n - 1 {
            if cap_ex[i] < 99.0 {
                let rr = (cap_pl[i] / cap_ex[i]).min(1.19);
                hist[(rr * 10.0) as usize] += 1;
            }
        }
        println!("  cap ratio histogram (0.1 bins): {hist:?}");
        if std::env::var("DIAG_DUMP").is_ok() {
            // per junction: index, length, exact cap, planner cap, accel
            let mut s0 = 0.0;
            for i in 0..n {
                s0 += l[i];
                println!(
                    "J {i} s {s0:.3} L {:.3} ex {:.2} pl {:.2} vend {:.2} a {:.0} afull {:.0}",
                    l[i], cap_ex[i], cap_pl[i], segs[i].v_end_mm_s, a_pl[i], a_full[i]
                );
            }
        }
    }
}

#[test]
#[ignore]
fn worst_axis_tick() {
    let cfg = reference_config();
    let which = std::env::var("DIAG_PATHS").unwrap_or("arcs".into());
    for p in reference_paths() {
        if !which.split(',').any(|w| w == p.name) {
            continue;
        }
        let r = run(cfg.clone(), &p.blocks);
        let t = &r.ticks;
        let v = |k: usize, i: usize| (t[k].position[i] - t[k - 1].position[i]) / TS_S;
        let mut worst = (0.0, 0, 0);
        for k in 2..t.len() {
            for i in 0..3 {
                let a = ((v(k, i) - v(k - 1, i)) / TS_S).abs() / 1000.0;
                if a > worst.0 {
                    worst = (a, k, i);
                }
            }
        }
        println!(
            "{}: worst {:.6} at tick {} axis {}",
            p.name, worst.0, worst.1, worst.2
        );
        let by_seq: std::collections::HashMap<u32, usize> = r
            .segments
            .iter()
            .enumerate()
            .map(|(i, s)| (s.seq, i))
            .collect();
        for k in worst.1 - 3..worst.1 + 3 {
            let i = by_seq[&t[k].seq];
            let s = &r.segments[i];
            println!(
                "tick {k} v {:.4} seg {i} L {:.4} cap {:.3} vend {:.3} a {:.1} | a_axes {:?}",
                t[k].path_v_mm_s,
                s.length_mm,
                s.junction_cap_mm_s,
                s.v_end_mm_s,
                s.accel_mm_s2,
                (0..3)
                    .map(|ax| (v(k, ax) - v(k - 1, ax)) / TS_S)
                    .collect::<Vec<_>>()
            );
        }
        let i = by_seq[&t[worst.1].seq];
        for s in &r.segments[i.saturating_sub(3)..i + 3] {
            if let kernel::plan::SegPath::Line { start, end } = s.path {
                println!(
                    "  seg L {:.4} from {:?} to {:?} cap {:.3} vend {:.3} a {:.1} stop_a {:.1}",
                    s.length_mm,
                    &start.0[..2],
                    &end.0[..2],
                    s.junction_cap_mm_s,
                    s.v_end_mm_s,
                    s.accel_mm_s2,
                    s.stop_accel_mm_s2
                );
            }
        }
    }
}
