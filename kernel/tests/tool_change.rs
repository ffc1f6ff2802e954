//! The tool change of the CNC836 dialect (issue #47, docs/language.md "Tool change"): `T<n>`
//! names the tool, `M6` holds for it and selects `D n` and `& n`; where M6 cannot be.

use kernel::DiagCode;
use kernel::block::{BlockKind, Comp, ProgramStop, SpindleDir};
use kernel::offsets::OffsetEntry;
use kernel::program::{Setup, compile};

fn setup() -> Setup {
    let mut s = Setup::new(&['X', 'Y', 'Z']);
    for (n, r, z) in [(1, 3.0, 10.0), (2, 5.0, 25.5)] {
        let e = OffsetEntry {
            radius_mm: r,
            length_mm: [0.0, 0.0, z, 0.0],
        };
        s.offsets.set_entry(n, e).unwrap();
    }
    s
}

#[test]
fn t_and_m6_hold_and_put_the_tools_entries_in_force() {
    let text = "N10 G0 X0 Y0 Z50 M3 S1000\nN20 T1 M6\nN30 M3 S1000\nN40 G1 Z0 F500\n\
                N50 G41 G1 X10 Y0\nN60 G40 G1 X20\nN70 T2\nN80 M6\nN90 G1 Z0\nN100 M30\n";
    let c = compile(text, &setup());
    assert!(!c.has_errors(), "{:?}", c.diagnostics);
    let changes: Vec<_> = c
        .blocks
        .iter()
        .filter_map(|b| match ProgramStop::of_block(b) {
            ProgramStop::ToolChange { tool } => Some((b.n, tool, b.spindle.dir)),
            _ => None,
        })
        .collect();
    assert_eq!(
        changes,
        [
            (Some(20), 1, SpindleDir::Stopped),
            (Some(80), 2, SpindleDir::Stopped)
        ]
    );
    let by_n = |n: u32| c.blocks.iter().find(|b| b.n == Some(n)).unwrap();
    let z_end = |n: u32| by_n(n).motion().unwrap().1[2];
    // & 1 after the first change: Z0 is at machine 10; D 1 under G41: radius 3.
    assert_eq!(z_end(40), 10.0);
    assert_eq!(
        by_n(50).comp,
        Comp::Left {
            d: 1,
            radius_mm: 3.0
        }
    );
    // After the second: & 2.
    assert_eq!(z_end(90), 25.5);
    assert!(matches!(by_n(80).kind, BlockKind::ToolChange { tool: 2 }));
}

#[test]
fn m6_where_it_cannot_be_is_refused() {
    let code = |text: &str| {
        let c = compile(text, &setup());
        c.diagnostics.iter().find(|d| d.is_error()).map(|d| d.code)
    };
    assert_eq!(
        code("T1 M6 G1 X5 F100\n"),
        Some(DiagCode::ToolChangeNotAlone)
    );
    assert_eq!(
        code("D1 G41 G1 X5 F100\nT2 M6\n"),
        Some(DiagCode::ToolChangeUnderComp)
    );
    assert_eq!(code("T100 M6\n"), Some(DiagCode::WordOutOfRange));
    // T alone changes nothing yet; T0 M6 empties the spindle (D0, &0).
    assert_eq!(code("T2\nT0 M6\nG1 X1 F100\n"), None);
}

/// Plans `text` and runs it in the interpolator until the first program stop; the tool it
/// names and the block it holds in, or `None` when the program ran to its end.
fn first_stop(text: &str) -> Option<(Option<u8>, Option<u32>)> {
    use kernel::interp::{InterpState, Interpolator};
    use kernel::plan::{Planner, PlannerConfig};
    let c = compile(text, &setup());
    assert!(!c.has_errors(), "{:?}", c.diagnostics);
    let mut pl = Planner::new(PlannerConfig::uniform(3, 200.0, 1500.0), 1);
    let mut segs = vec![];
    for b in &c.blocks {
        pl.push(b).unwrap();
        segs.extend(std::iter::from_fn(|| pl.poll()));
    }
    pl.finish();
    segs.extend(std::iter::from_fn(|| pl.poll()));
    let mut ip = Interpolator::new(3, kernel::units::AxesMm::default());
    for seg in segs {
        ip.push(seg).unwrap();
    }
    for _ in 0..100_000 {
        ip.set_in_position(true);
        let out = ip.tick();
        if ip.at_program_stop() {
            return Some((ip.tool_change(), out.n));
        }
        if out.state == InterpState::Idle {
            return None;
        }
    }
    panic!("neither a stop nor the end");
}

#[test]
fn a_stop_with_no_motion_after_it_holds() {
    // `T3 M6` alone (MDI), M0 before M30 after the last motion (held at the end of that
    // motion), M0 on a move of length 0.
    assert_eq!(first_stop("N10 T3 M6\n"), Some((Some(3), Some(10))));
    assert_eq!(
        first_stop("N10 G1 X10 F1000\nN20 M0\nN30 M30\n"),
        Some((None, Some(10)))
    );
    assert_eq!(
        first_stop("N10 G1 X0 F1000 M0\nN20 M30\n"),
        Some((None, Some(10)))
    );
    assert_eq!(first_stop("N10 G1 X10 F1000\nN20 M30\n"), None);
}
