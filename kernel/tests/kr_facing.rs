//! Simulated lathe in virtual time (SPEC §6): facing from Ø300 to Ø50 under G96, the planner and
//! the 4 ms interpolator moving X, KŘR stepped every tick with the interpolated X.

use std::f64::consts::TAU;

use kernel::block::{Block, BlockKind, Comp, Continuity, Feed, Path, Plane, Spindle, SpindleDir};
use kernel::constants::Constants;
use kernel::interp::{InterpState, Interpolator};
use kernel::kr::{
    ControllingAxis, Gear, Kr, KrConfig, KrInput, KrOutput, Motion, ProgramSpindle, RadiusInput,
};
use kernel::plan::{Planner, PlannerConfig};
use kernel::plc::{CellId, PlcArea, cntr};
use kernel::units::AxesMm;

/// Gear 1: P 1000 rpm, U 7FFFh. Gear 2: P 450 rpm, U 6000h.
fn kr() -> Kr {
    let mut c = Constants::new();
    c.set(0, 1.0); // R0: X
    c.set(1, 3.0); // R1: Z
    c.set(2, 0.0); // no third axis
    c.set(67, 1.0); // X controls KŘR
    c.set(580, 0.001); // version 2
    let gears = vec![
        Gear {
            max_rpm: 1000.0,
            output_range: 0x7FFF,
            m_code: Some(41),
        },
        Gear {
            max_rpm: 450.0,
            output_range: 0x6000,
            m_code: Some(42),
        },
    ];
    Kr::new(KrConfig::from_constants(&c, RadiusInput::Diameter, gears).unwrap())
}

/// `N20 G96 G1 F2000 S900 X50` from X300 Z-1 (standard R329: G96 feed in mm/min, S900 =
/// 90 m/min), with G76 `limit_rpm` and gear `gear`.
fn facing_block(css: bool, s: f64, limit_rpm: f64, gear: u8) -> Block {
    let at = |x: f64| {
        let mut a = AxesMm::ZERO;
        a[0] = x;
        a[1] = -1.0;
        a
    };
    Block {
        seq: 2,
        n: Some(20),
        line: 3,
        kind: BlockKind::Motion {
            start: at(300.0),
            end: at(50.0),
            path: Path::Line,
        },
        feed: Feed::MmPerMin(2000.0),
        plane: Plane::G17,
        comp: Comp::Off,
        continuity: Continuity::G98,
        dyn_set: 1,
        spindle: Spindle {
            dir: SpindleDir::Cw,
            s,
            css,
            limit_rpm,
            gear,
            ..Spindle::default()
        },
        m: [None; 4],
    }
}

/// One tick of the run: interpolated X, KŘR output and the PLC area after the tick.
struct Tick {
    x_mm: f64,
    out: KrOutput,
    plc: PlcArea,
}

/// Runs the block to its end. `between(k, plc, axis)` runs before tick `k` (the PLC side's
/// writes and the offsets in force for tick `k`).
fn run(
    block: &Block,
    mut between: impl FnMut(usize, &mut PlcArea, &mut ControllingAxis),
) -> Vec<Tick> {
    let mut planner = Planner::new(PlannerConfig::uniform(2, 100.0, 500.0), 1);
    planner.push(block).unwrap();
    planner.finish();
    let mut interp = Interpolator::new(2, block.motion().unwrap().0);
    while let Some(seg) = planner.poll() {
        interp.push(seg).unwrap();
    }
    let mut kr = kr();
    let mut plc = PlcArea::new();
    let mut axis = ControllingAxis::default();
    let program = ProgramSpindle::from_block(block);
    let mut trace = Vec::new();
    for k in 0..100_000 {
        between(k, &mut plc, &mut axis);
        plc.begin_tick();
        let t = interp.tick();
        axis.carriage_mm = t.position[0];
        let out = kr.tick(
            &KrInput {
                program,
                motion: Motion::Feed,
                axis,
            },
            &mut plc,
        );
        trace.push(Tick {
            x_mm: t.position[0],
            out,
            plc,
        });
        if t.state == InterpState::Idle {
            break;
        }
    }
    trace
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() < 1e-9 * b.abs().max(1.0)
}

/// What every cell must show for speed `n_rpm` at radius `r_mm` in gear (P, U).
fn check_cells(k: usize, t: &Tick, n_rpm: f64, r_mm: f64, p_rpm: f64, u: i32) {
    let cell = |c| t.plc.input(c);
    assert!(
        close(t.out.speed_rpm, n_rpm),
        "tick {k}: {} rpm, expected {n_rpm}",
        t.out.speed_rpm
    );
    assert_eq!(t.out.spindle_rpm, t.out.speed_rpm, "tick {k}: M3");
    assert_eq!(
        cell(CellId::AkrrActS),
        (n_rpm * 1000.0).round() as i32,
        "k {k}"
    );
    let out = (n_rpm / p_rpm * f64::from(u)).round() as i32;
    assert_eq!(cell(CellId::AkrrActOut), out, "tick {k}");
    assert_eq!(i32::from(t.out.output), out, "tick {k}");
    assert_eq!(
        cell(CellId::AkrrActR),
        (r_mm * 8000.0).round() as i32,
        "k {k}"
    );
    assert_eq!(cell(CellId::AkrrActP), (p_rpm * 1000.0) as i32, "tick {k}");
    assert_eq!(cell(CellId::AkrrActU), u, "tick {k}");
}

/// Speed follows v/(2πr) each tick and is clamped at the G76 limit (400 rpm < P 1000 rpm).
#[test]
fn facing_follows_the_radius_and_clamps_at_g76() {
    let trace = run(&facing_block(true, 900.0, 400.0, 1), |_, _, _| {});
    assert!(trace.len() > 1000, "a real run: {} ticks", trace.len());
    assert_eq!(trace.last().unwrap().x_mm, 50.0);
    let (mut clamped, mut free) = (0, 0);
    for (k, t) in trace.iter().enumerate() {
        let r_mm = t.x_mm / 2.0;
        let n = 90_000.0 / (TAU * r_mm);
        if n >= 400.0 {
            clamped += 1;
        } else {
            free += 1;
        }
        check_cells(k, t, n.min(400.0), r_mm, 1000.0, 0x7FFF);
        assert_eq!(t.plc.input(CellId::AkrrActV), 90_000);
        assert_eq!(t.plc.input(CellId::AkrrActSmax), 400_000);
        assert_eq!(t.plc.input(CellId::AkrrActDist), 0);
        assert_eq!(t.plc.input(CellId::AkrrActVcorr), 0);
    }
    // Below Ø71.62 the limit holds: both regimes occur.
    assert!(clamped > 50 && free > 500, "clamped {clamped}, free {free}");
    // The speed never drops while facing inwards.
    assert!(
        trace
            .windows(2)
            .all(|w| w[1].out.speed_rpm >= w[0].out.speed_rpm)
    );
    // Starts near Ø300 (95.49 rpm), ends clamped.
    let first = trace[0].out.speed_rpm;
    assert!((95.49..95.6).contains(&first), "{first}");
    assert_eq!(trace.last().unwrap().out.speed_rpm, 400.0);
}

/// Gear 2 (P 450 rpm) clamps below a G76 limit of 2000 rpm; the output then is U = 6000h.
#[test]
fn facing_clamps_at_the_gear_maximum() {
    let trace = run(&facing_block(true, 900.0, 2000.0, 2), |_, _, _| {});
    for (k, t) in trace.iter().enumerate() {
        let r_mm = t.x_mm / 2.0;
        check_cells(
            k,
            t,
            (90_000.0 / (TAU * r_mm)).min(450.0),
            r_mm,
            450.0,
            0x6000,
        );
        assert_eq!(t.plc.input(CellId::AkrrActSmax), 2_000_000);
    }
    let last = trace.last().unwrap();
    assert_eq!(last.out.speed_rpm, 450.0);
    assert_eq!(last.plc.input(CellId::AkrrActOut), 0x6000);
}

/// The PLC side switches EXT_AKRR_* bits during the cut; each takes effect on the tick after the
/// write and hands its value to the ACT cell.
#[test]
fn ext_bits_switch_tick_by_tick() {
    const V_AT: usize = 100;
    const SMAX_AT: usize = 300;
    const DIST_AT: usize = 500;
    const VCORR_AT: usize = 700;
    const SHIFT_AT: usize = 850;
    const SUPORT_AT: usize = 900;
    const V_OFF_AT: usize = 1100;
    let mut bits = 0u32;
    let trace = run(&facing_block(true, 900.0, 2000.0, 1), |k, plc, axis| {
        let mut write = |name: &str, value: i64| {
            plc.write_by_name(name, value).unwrap();
        };
        match k {
            V_AT => {
                write("AKRR_V", 120_000);
                bits |= cntr::EXT_AKRR_V;
            }
            SMAX_AT => {
                write("AKRR_SMAX", 300_000);
                bits |= cntr::EXT_AKRR_SMAX;
            }
            DIST_AT => {
                write("AKRR_DIST", 40_000);
                bits |= cntr::EXT_AKRR_DIST;
            }
            VCORR_AT => {
                write("AKRR_VCORR", -10_000);
                bits |= cntr::EXT_AKRR_VCORR;
            }
            SHIFT_AT => axis.origin_shift_mm = 20.0,
            SUPORT_AT => bits |= cntr::EXT_AKRR_SUPORT,
            V_OFF_AT => bits &= !cntr::EXT_AKRR_V,
            _ => return,
        }
        let before = plc.input(CellId::AkrrCntr);
        plc.write_by_name("AKRR_CNTR", i64::from(bits)).unwrap();
        // Staged, not yet in force: the controller still sees the old bits in this gap.
        assert_eq!(plc.input(CellId::AkrrCntr), before);
        assert_eq!(plc.read_by_name("AKRR_CNTR"), Ok(bits as i32));
    });
    assert!(trace.len() > V_OFF_AT + 10);
    for (k, t) in trace.iter().enumerate() {
        let plc_v = (V_AT..V_OFF_AT).contains(&k);
        let v_mm_min = if plc_v { 120_000.0 } else { 90_000.0 };
        let vcorr = if k >= VCORR_AT { -10_000.0 } else { 0.0 };
        let limit = if k >= SMAX_AT { 300.0 } else { 2000.0 };
        let x_mm = if (SHIFT_AT..SUPORT_AT).contains(&k) {
            t.x_mm - 20.0
        } else {
            t.x_mm
        };
        let r_mm = x_mm / 2.0 + if k >= DIST_AT { 5.0 } else { 0.0 };
        let n = ((v_mm_min + vcorr) / (TAU * r_mm)).min(limit).min(1000.0);
        check_cells(k, t, n, r_mm, 1000.0, 0x7FFF);
        let cell = |c| t.plc.input(c);
        assert_eq!(cell(CellId::AkrrActV), v_mm_min as i32, "tick {k}");
        assert_eq!(cell(CellId::AkrrActSmax), (limit * 1000.0) as i32, "k {k}");
        assert_eq!(
            cell(CellId::AkrrActDist),
            if k >= DIST_AT { 40_000 } else { 0 },
            "tick {k}"
        );
        assert_eq!(cell(CellId::AkrrActVcorr), vcorr as i32, "tick {k}");
    }
    // The switch is visible exactly at the tick after the write, not before.
    assert_eq!(trace[V_AT - 1].plc.input(CellId::AkrrActV), 90_000);
    assert_eq!(trace[V_AT].plc.input(CellId::AkrrActV), 120_000);
}

/// EXT_AKRR_REQ: the PLC starts KŘR during a cut programmed with plain S (200 rpm), and ends it;
/// the program's S200 is then in force again.
#[test]
fn plc_request_starts_and_ends_kr_during_the_cut() {
    const REQ_AT: usize = 200;
    const END_AT: usize = 600;
    let trace = run(&facing_block(false, 200.0, 0.0, 1), |k, plc, _| match k {
        REQ_AT => {
            plc.write_by_name("AKRR_V", 60_000).unwrap();
            plc.write_by_name(
                "AKRR_CNTR",
                i64::from(cntr::EXT_AKRR_REQ | cntr::EXT_AKRR_V),
            )
            .unwrap();
        }
        END_AT => plc.write_by_name("AKRR_CNTR", 0).unwrap(),
        _ => {}
    });
    for (k, t) in trace.iter().enumerate() {
        let r_mm = t.x_mm / 2.0;
        let (active, n) = if k < REQ_AT {
            (false, 200.0)
        } else if k < END_AT {
            (true, (60_000.0 / (TAU * r_mm)).min(1000.0))
        } else {
            (false, 200.0)
        };
        assert_eq!(t.out.active, active, "tick {k}");
        check_cells(k, t, n, r_mm, 1000.0, 0x7FFF);
        let v = if active { 60_000 } else { 0 };
        assert_eq!(t.plc.input(CellId::AkrrActV), v, "tick {k}");
    }
    // KŘR really changed the speed in between.
    let kr_rpm = trace[END_AT - 1].out.speed_rpm;
    assert!((kr_rpm - 200.0).abs() > 10.0, "{kr_rpm}");
}
