//! Sample programs of the repository run end to end on the simulated machine (virtual time).

use std::time::{Duration, Instant};

use daemon::runtime::controller::{ClockKind, Controller};
use daemon::runtime::rt::MachineState;
use tests::RecordingBus;

fn run_to_end(ctl: &Controller, name: &str, text: &str) {
    let t0 = Instant::now();
    while ctl.snapshot().state != MachineState::Idle {
        assert!(
            t0.elapsed() < Duration::from_secs(10),
            "{:?}",
            ctl.snapshot()
        );
        std::thread::sleep(Duration::from_millis(2));
    }
    ctl.load_program(name, text)
        .unwrap_or_else(|e| panic!("{name}: {e:?}"));
    let job = ctl.start_program().unwrap();
    loop {
        let s = ctl.snapshot();
        if s.finished_job == job {
            return;
        }
        assert_ne!(s.aborted_job, job, "{name} aborted: {s:?}");
        assert!(
            t0.elapsed() < Duration::from_secs(120),
            "{name} hangs: {s:?}"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// MIKROPROG template (issue #4): a 10 mm cutter (D1 = 5 mm, written by G92 in the program)
/// runs outside the contour; the tool centre on the first side (N50, X0 from Y0 to Y20, moving
/// +Y with G41) is 5 mm to the left of it, at X-5.
#[test]
fn mikroprog_template_runs_compensated() {
    let text = std::fs::read_to_string("../programs/mikroprog_template.nc").unwrap();
    let mut cfg = tests::test_config();
    cfg.axes[0].home_mm = -30.0;
    let sim = sim::SimBus::new(sim::SimDriveParams::default(), &[-30.0, 0.0, 0.0]);
    let (bus, record) = RecordingBus::new(sim);
    let ctl = Controller::start_with_bus(cfg, ClockKind::Virtual, Box::new(bus)).unwrap();
    run_to_end(&ctl, "mikroprog_template.nc", &text);
    let s = ctl.snapshot();
    assert!((s.commanded[0] + 30.0).abs() < 1e-9 && s.commanded[1].abs() < 1e-9);
    let points = record.lock().unwrap().clone();
    let side: Vec<&[f64; 6]> = points
        .iter()
        .filter(|p| p[1] > 2.0 && p[1] < 18.0 && p[0] < 0.0)
        .collect();
    assert!(side.len() > 10, "no setpoints along N50");
    for p in side {
        assert!(
            (p[0] + 5.0).abs() < 1e-6,
            "tool centre off the equidistant: {p:?}"
        );
    }
    // Nothing is ever commanded inside the template (0 < X < 80, 0 < Y < 40 well inside).
    assert!(
        !points
            .iter()
            .any(|p| p[0] > 5.0 && p[0] < 35.0 && p[1] > 5.0 && p[1] < 35.0),
        "the cutter entered the template"
    );
    // G92 D1 R0=5.0 wrote the memory table only (SPEC §3 c).
    let entry = ctl.offsets_memory().entry(1).copied().unwrap_or_default();
    assert_eq!(entry.values()[0], 5.0);
    assert!(
        !ctl.offsets_file_text().contains("01:"),
        "G92 must not touch the file"
    );
    ctl.shutdown();
}

/// The README's sample program.
#[test]
fn readme_sample_program_runs() {
    let text = std::fs::read_to_string("../programs/sample.nc").unwrap();
    let ctl = Controller::start(tests::test_config(), ClockKind::Virtual).unwrap();
    run_to_end(&ctl, "sample.nc", &text);
    let s = ctl.snapshot();
    assert_eq!(&s.commanded.0[..3], &[0.0, 0.0, 5.0]);
    ctl.shutdown();
}
