//! Safe machine operation (issue #15) through the gRPC API on the simulated machine, in virtual
//! time: program end and stops (M2/M30, M0/M1, optional stop), Stop stops the spindle,
//! FAILED_PRECONDITION for commands that cannot apply, soft limits, fault reaction.

use std::sync::Arc;
use std::time::{Duration, Instant};

mod api_common;

use api_common::{mdi_block, named_program, start_job};
use daemon::runtime::config::Config;
use daemon::runtime::controller::{ClockKind, Controller};
use daemon::runtime::rt::{MachineState, Snapshot};
use proto::v1 as pb;
use proto::v1::machine_client::MachineClient;
use tests::{Recording, RecordingBus, SpindleRecording, wait_job_finished, wait_state};
use tonic::Code;
use tonic::transport::Channel;

struct Daemon {
    c: MachineClient<Channel>,
    ctl: Arc<Controller>,
    record: Recording,
    spindle: SpindleRecording,
}

/// A daemon on the simulated bus built from `cfg` (as `cncd` builds it), virtual clock.
async fn daemon(cfg: Config) -> Daemon {
    let params = sim::SimDriveParams {
        kv_per_s: cfg.sim.kv_per_s,
        following_window_mm: cfg.sim.following_window_mm,
        ..Default::default()
    };
    let start: Vec<f64> = cfg.axes.iter().map(|a| a.home_mm).collect();
    let (bus, record, spindle) = RecordingBus::with_spindle(sim::SimBus::new(params, &start));
    let ctl = Controller::start_with_bus(cfg, ClockKind::Monotonic, Box::new(bus)).unwrap();
    // The Unix socket: tokenless loopback TCP is observer-only.
    let addr = tests::serve_unix(&ctl).await;
    let c = MachineClient::connect(addr.clone()).await.unwrap();
    wait_state(&ctl, MachineState::Idle).await;
    Daemon {
        c,
        ctl,
        record,
        spindle,
    }
}

async fn wait_for(ctl: &Controller, what: &str, mut f: impl FnMut(&Snapshot) -> bool) {
    let t0 = Instant::now();
    loop {
        let s = ctl.snapshot();
        if f(&s) {
            return;
        }
        assert!(t0.elapsed() < tests::PATIENCE, "{what}: {s:?}");
        tokio::time::sleep(Duration::from_millis(2)).await;
    }
}

async fn load(
    c: &mut MachineClient<Channel>,
    text: &str,
) -> Result<pb::LoadProgramReply, tonic::Status> {
    c.load_program(named_program("t.nc", text))
        .await
        .map(|r| r.into_inner())
}

/// The soft limit `text` passes, from the diagnostics of its refused load.
async fn soft_limit_refusal(c: &mut MachineClient<Channel>, text: &str) -> pb::SoftLimitHit {
    let e = load(c, text).await.unwrap_err();
    diagnostics(&e)
        .into_iter()
        .find_map(|d| d.soft_limit)
        .unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn m30_ends_the_program_and_the_spindle_stops() {
    let mut d = daemon(tests::test_config()).await;
    let text = "N10 S1000 M3\nN20 G1 X10 F3000\nN30 M30\nN40 G1 X50\n";
    let loaded = load(&mut d.c, text).await.unwrap();
    assert_eq!(loaded.blocks, 3, "blocks after M30 are not part of the run");
    let job = start_job(&mut d.c).await;
    wait_job_finished(&d.ctl, job).await;
    let s = d.ctl.snapshot();
    assert!((s.axes.commanded[0] - 10.0).abs() < 1e-9, "N40 ran: {s:?}");
    assert!(
        d.spindle.lock().unwrap().iter().any(|&r| r > 900.0),
        "the spindle never ran"
    );
    wait_for(&d.ctl, "spindle stopped at M30", |s| s.spindle.rpm == 0.0).await;
    // M2 does the same.
    load(&mut d.c, "N10 S500 M3\nN20 G1 X20 F3000\nN30 M2\nN40 X0\n")
        .await
        .unwrap();
    let job = start_job(&mut d.c).await;
    wait_job_finished(&d.ctl, job).await;
    assert!((d.ctl.snapshot().axes.commanded[0] - 20.0).abs() < 1e-9);
    wait_for(&d.ctl, "spindle stopped at M2", |s| s.spindle.rpm == 0.0).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn m0_stops_until_resume_and_m1_only_with_optional_stop() {
    let mut d = daemon(tests::test_config()).await;
    let text = "N10 G1 X10 F3000\nN20 M0\nN30 X20\nN40 M1\nN50 X30\n";
    load(&mut d.c, text).await.unwrap();
    // Optional stop off: M0 stops, M1 does not.
    let job = start_job(&mut d.c).await;
    wait_for(&d.ctl, "held at M0", |s| {
        s.state == MachineState::Hold && s.progress.program_stop
    })
    .await;
    let s = d.ctl.snapshot();
    assert!(
        (s.axes.commanded[0] - 10.0).abs() < 1e-9,
        "stopped off the M0 point: {s:?}"
    );
    let st = api_common::status_now(&mut d.c).await;
    assert!(st.program_stop && !st.optional_stop);
    // At rest it stays there.
    let seq = s.tick.sequence;
    wait_for(&d.ctl, "time passes", |s| s.tick.sequence > seq + 200).await;
    assert_eq!(d.ctl.snapshot().axes.commanded[0], s.axes.commanded[0]);
    d.c.resume(pb::ResumeRequest {}).await.unwrap();
    wait_job_finished(&d.ctl, job).await;
    assert!((d.ctl.snapshot().axes.commanded[0] - 30.0).abs() < 1e-9);

    // Optional stop on: M0 and M1 both stop; Start continues like Resume.
    d.c.set_optional_stop(pb::SetOptionalStopRequest { on: true })
        .await
        .unwrap();
    load(&mut d.c, "N10 G0 X0\nN20 G1 X10 F3000 M1\nN30 X20\n")
        .await
        .unwrap();
    let job = start_job(&mut d.c).await;
    wait_for(&d.ctl, "held at M1", |s| {
        s.state == MachineState::Hold && s.progress.program_stop
    })
    .await;
    assert!((d.ctl.snapshot().axes.commanded[0] - 10.0).abs() < 1e-9);
    assert!(api_common::status_now(&mut d.c).await.optional_stop);
    let again = start_job(&mut d.c).await;
    assert_eq!(again, job, "Start at a program stop continues the job");
    wait_job_finished(&d.ctl, job).await;
    assert!((d.ctl.snapshot().axes.commanded[0] - 20.0).abs() < 1e-9);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn stop_stops_the_spindle_and_wrong_states_are_refused() {
    let mut d = daemon(tests::test_config()).await;
    // Idle: hold and resume cannot apply.
    let e = d.c.hold(pb::HoldRequest {}).await.unwrap_err();
    assert_eq!(e.code(), Code::FailedPrecondition, "hold when idle");
    let e = d.c.resume(pb::ResumeRequest {}).await.unwrap_err();
    assert_eq!(e.code(), Code::FailedPrecondition, "resume when idle");

    // Long enough that it is still cutting when the test looks (virtual time runs fast).
    load(&mut d.c, "N10 S1000 M3\nN20 G1 X1000000 F600\n")
        .await
        .unwrap();
    let job = start_job(&mut d.c).await;
    wait_for(&d.ctl, "cutting with the spindle on", |s| {
        s.state == MachineState::Running && s.spindle.rpm > 900.0 && s.axes.commanded[0] > 1.0
    })
    .await;
    d.c.stop(pb::StopRequest {}).await.unwrap();
    wait_for(&d.ctl, "stopped", |s| {
        s.progress.aborted_job == job && s.state == MachineState::Idle
    })
    .await;
    wait_for(&d.ctl, "spindle stopped after Stop", |s| {
        s.spindle.rpm == 0.0
    })
    .await;
    // Resume after a stop has nothing to continue.
    let e = d.c.resume(pb::ResumeRequest {}).await.unwrap_err();
    assert_eq!(e.code(), Code::FailedPrecondition, "resume after stop");
    // Stop is never refused (it also stops a spindle on an idle machine).
    d.c.stop(pb::StopRequest {}).await.unwrap();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn soft_limits_refuse_programs_and_mdi_with_the_offsets_in_force() {
    let mut cfg = tests::test_config();
    cfg.axes[0].soft_min_mm = Some(-10.0);
    cfg.axes[0].soft_max_mm = Some(100.0);
    cfg.axes[2].soft_min_mm = Some(-50.0);
    cfg.axes[2].soft_max_mm = Some(0.0);
    let mut d = daemon(cfg).await;
    // Inside: runs. Y has no limits (documented): far away is fine.
    load(&mut d.c, "N10 G0 X100 Y99999 Z0\nN20 G0 X0 Y0\n")
        .await
        .unwrap();

    let e = load(&mut d.c, "N10 G0 X50\nN20 G1 X123456789012 F1000\n")
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument);
    let diags = diagnostics(&e);
    let hit = diags
        .iter()
        .find_map(|d| d.soft_limit.clone().map(|h| (d.clone(), h)));
    let (diag, hit) = hit.expect("a soft-limit diagnostic");
    assert_eq!((diag.block, diag.line), (Some(20), 2));
    assert_eq!(hit.axis, "X");
    assert!(hit.upper && hit.limit_mm == 100.0 && hit.position_mm > 1e11);

    // 100 km of G91 moves: refused at the block that leaves the travel.
    let e = load(&mut d.c, "N10 G91 G1 X60 F5000\nN20 X60\nN30 X60\n")
        .await
        .unwrap_err();
    let diags = diagnostics(&e);
    let d20 = diags.iter().find(|d| d.soft_limit.is_some()).unwrap();
    assert_eq!(d20.block, Some(20));

    // An arc bulging past the limit between two end points inside it.
    let hit = soft_limit_refusal(&mut d.c, "N10 G0 X0 Y40\nN20 G3 X0 Y0 I0 J-20 F1000\n").await;
    assert!(
        !hit.upper && (hit.position_mm + 20.0).abs() < 1e-6,
        "{hit:?}"
    );

    // With the length offset of entry 1 (Z +30) in force, Z-25 programmed is Z+5 on the
    // machine: beyond Z max 0. Without the offset it runs.
    load(&mut d.c, "N10 G1 Z-25 F1000\n").await.unwrap();
    let hit = soft_limit_refusal(&mut d.c, "N5 G92 D1 R3=30\nN10 G1 Z-25 F1000 &1\n").await;
    assert_eq!(hit.axis, "Z");
    assert!((hit.position_mm - 5.0).abs() < 1e-9 && hit.upper);

    // MDI is refused the same way and nothing moves.
    let e =
        d.c.mdi(mdi_block("G0 X-5000 Y99999 Z-3000"))
            .await
            .unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument);
    assert!(diagnostics(&e).iter().any(|d| d.soft_limit.is_some()));
    assert_eq!(d.ctl.snapshot().axes.commanded[0], 0.0);

    // Status shows the limits per axis; an axis without limits has none.
    let st = api_common::status_now(&mut d.c).await;
    assert_eq!(st.axes[0].soft_min_mm, Some(-10.0));
    assert_eq!(st.axes[0].soft_max_mm, Some(100.0));
    assert_eq!(st.axes[1].soft_min_mm, None);
    let _ = &d.record;
}

fn diagnostics(s: &tonic::Status) -> Vec<pb::Diagnostic> {
    use prost::Message;
    pb::Diagnostics::decode(s.details()).unwrap().items
}

/// Records the drives' actual positions of every tick (the tool position the fault test
/// measures the deviation from the path with, independently of the daemon's own figure).
struct FeedbackBus {
    inner: sim::SimBus,
    actual: Arc<std::sync::Mutex<Vec<[f64; hal::MAX_AXES]>>>,
    states: Arc<std::sync::Mutex<[hal::DriveState; hal::MAX_AXES]>>,
}

impl hal::DriveBus for FeedbackBus {
    fn name(&self) -> &str {
        "sim"
    }
    fn axes(&self) -> usize {
        self.inner.axes()
    }
    fn has_spindle(&self) -> bool {
        true
    }
    fn cycle(
        &mut self,
        cmd: &hal::CycleCommand,
        fb: &mut hal::CycleFeedback,
    ) -> Result<(), hal::BusFault> {
        let r = self.inner.cycle(cmd, fb);
        let mut p = [0.0; hal::MAX_AXES];
        for (i, a) in fb.axes.iter().enumerate() {
            p[i] = a.position_mm;
        }
        self.actual.lock().unwrap().push(p);
        let mut st = self.states.lock().unwrap();
        for (i, a) in fb.axes.iter().enumerate() {
            st[i] = a.state;
        }
        r
    }
    fn enable(&mut self) {
        self.inner.enable()
    }
    fn reset(&mut self) {
        self.inner.reset()
    }
    fn safe_state(&mut self) {
        self.inner.safe_state()
    }
}

/// Distance of (x, y) from the line through the origin and (1000, 200).
fn off_line_mm(p: &[f64; hal::MAX_AXES]) -> f64 {
    (p[0] * 200.0 - p[1] * 1000.0).abs() / 1000f64.hypot(200.0)
}

/// Issue #15: with a 5 mm following window, `N20 G1 X1000 Y200 F12000` makes X fault (its
/// following error passes 5 mm at about 150 mm/s). Before: the RT thread braked along the path
/// while X stood still, Y ran on 5.3 mm and the tool ended 5.19 mm off the line. Now every
/// healthy axis brakes on its own at its stop deceleration: Y stops after its following error
/// plus v²/2a.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn fault_stops_every_axis_on_its_own_and_reports_the_path_deviation() {
    let mut cfg = tests::test_config();
    cfg.sim.following_window_mm = 5.0;
    let params = sim::SimDriveParams {
        kv_per_s: cfg.sim.kv_per_s,
        following_window_mm: cfg.sim.following_window_mm,
        ..Default::default()
    };
    let actual = Arc::new(std::sync::Mutex::new(Vec::new()));
    let states = Arc::new(std::sync::Mutex::new(Default::default()));
    let bus = FeedbackBus {
        inner: sim::SimBus::new(params, &[0.0, 0.0, 0.0]),
        actual: actual.clone(),
        states: states.clone(),
    };
    let ctl = Controller::start_with_bus(cfg.clone(), ClockKind::Monotonic, Box::new(bus)).unwrap();
    // The Unix socket: tokenless loopback TCP is observer-only.
    let addr = tests::serve_unix(&ctl).await;
    let mut c = MachineClient::connect(addr.clone()).await.unwrap();
    wait_state(&ctl, MachineState::Idle).await;
    load(&mut c, "N10 S1000 M3\nN20 G1 X1000 Y200 F12000\n")
        .await
        .unwrap();
    let job = start_job(&mut c).await;
    wait_for(&ctl, "fault", |s| s.state == MachineState::Fault).await;
    // Wait until the drives are at rest: 250 ticks without any change of the actual position.
    let t0 = Instant::now();
    loop {
        let n = actual.lock().unwrap().len();
        {
            let a = actual.lock().unwrap();
            if n > 300 && a[n - 250..].iter().all(|p| p == &a[n - 1]) {
                break;
            }
        }
        assert!(t0.elapsed() < tests::PATIENCE, "never at rest");
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    let s = ctl.snapshot();
    assert_eq!(s.progress.aborted_job, job);
    let f = s.alarm.fault.expect("a fault");
    assert_eq!((f.axis, f.node), (Some(0), Some(1)));
    assert_eq!(f.reason, hal::FaultReason::FollowingError);
    let worst = actual
        .lock()
        .unwrap()
        .iter()
        .map(off_line_mm)
        .fold(0.0, f64::max);
    eprintln!(
        "fault stop: tool left the programmed line by {worst:.3} mm (status says {:.3} mm)",
        s.alarm.fault_path_deviation_mm
    );
    // The alarm names axis, node and reason.
    let st = api_common::status_now(&mut c).await;
    assert!(
        st.alarm.contains("axis X") && st.alarm.contains("node 1"),
        "{}",
        st.alarm
    );
    assert!(
        (st.fault_path_deviation_mm - worst).abs() < 1e-6,
        "{} vs {worst}",
        st.fault_path_deviation_mm
    );
    // Y at the fault: about 38 mm/s, 1.27 mm following error; braking at 800 mm/s² takes
    // 0.9 mm more: the tool ends about 2.2 mm off the line (5.19 mm before).
    assert!(worst < 2.4, "deviation {worst} mm");
    // The spindle stops at once; the healthy drives are switched off once at rest.
    assert_eq!(s.spindle.rpm, 0.0);
    wait_for(&ctl, "drives in their safe state", |_| {
        let st = states.lock().unwrap();
        st[0] == hal::DriveState::Fault
            && st[1] == hal::DriveState::Disabled
            && st[2] == hal::DriveState::Disabled
    })
    .await;
    // Reset re-enables the drives where they stand; the machine runs again.
    c.reset(pb::ResetRequest {}).await.unwrap();
    wait_state(&ctl, MachineState::Idle).await;
    let here = ctl.snapshot().axes.commanded;
    let job = ctl
        .start_text(
            "mdi",
            "G91 G1 X-10 F1000",
            ctl.default_dialect(),
            false,
            true,
        )
        .unwrap()
        .0;
    wait_job_finished(&ctl, job).await;
    assert!((ctl.snapshot().axes.commanded[0] - (here[0] - 10.0)).abs() < 1e-9);
}

/// A jog request stream kept open by the test: drop the sender to end it.
async fn jog_stream(
    c: &MachineClient<Channel>,
    axis: &str,
    direction: i32,
    speed_mm_min: f64,
) -> (
    tokio::sync::mpsc::Sender<pb::JogRequest>,
    tokio::task::JoinHandle<Result<tonic::Response<pb::JogReply>, tonic::Status>>,
) {
    let (tx, rx) = tokio::sync::mpsc::channel(4);
    let msg = pb::JogRequest {
        axis: axis.into(),
        direction,
        speed_mm_min,
    };
    tx.send(msg).await.unwrap();
    let mut c = c.clone();
    let call =
        tokio::spawn(async move { c.jog(tokio_stream::wrappers::ReceiverStream::new(rx)).await });
    (tx, call)
}

/// The final braking of axis `axis`: the distance travelled from the last tick before the
/// speed starts falling for good to the end of the recording, and that speed (mm/s).
/// Measured from where the final braking starts, not from the fastest tick: a client starved
/// on a loaded machine may renew its jog late, so the axis may slow down and speed up again
/// before the end (each brake still within its distance), and from the fastest tick that
/// dip would count as braking.
fn final_braking(points: &[[f64; hal::MAX_AXES]], axis: usize) -> (f64, f64) {
    let v: Vec<f64> = speeds(points, axis).collect();
    // Back from the end over the ticks at rest, then up the braking ramp while the speed
    // strictly rises (braking at a takes a·Ts = 3.2 mm/s off per tick).
    let mut k = v.len() - 1;
    while k > 0 && v[k] < 1e-9 {
        k -= 1;
    }
    while k > 0 && v[k - 1] > v[k] + 1e-9 {
        k -= 1;
    }
    let end = points.last().unwrap()[axis];
    ((end - points[k + 1][axis]).abs(), v[k])
}

/// The fastest tick of axis `axis` in the recording (mm/s).
fn top_speed(points: &[[f64; hal::MAX_AXES]], axis: usize) -> f64 {
    speeds(points, axis).fold(0.0, f64::max)
}

/// The speed of axis `axis` over each 4 ms tick of the recording (mm/s).
fn speeds(points: &[[f64; hal::MAX_AXES]], axis: usize) -> impl Iterator<Item = f64> + '_ {
    points
        .windows(2)
        .map(move |w| ((w[1][axis] - w[0][axis]) / 0.004).abs())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn jog_steps_and_continuous_jog_rest_on_the_soft_limit() {
    let mut cfg = tests::test_config();
    cfg.axes[0].soft_min_mm = Some(-1.0);
    cfg.axes[0].soft_max_mm = Some(2.0);
    let mut d = daemon(cfg).await;
    let step = |axis: &str, step_mm: f64| pb::JogStepRequest {
        axis: axis.into(),
        step_mm,
        speed_mm_min: 600.0,
    };
    let r = d.c.jog_step(step("X", 0.1)).await.unwrap().into_inner();
    assert_eq!(r.target_mm, 0.1);
    wait_for(&d.ctl, "step done", |s| {
        s.state == MachineState::Idle && s.axes.commanded[0] == 0.1
    })
    .await;
    // A step past the soft limit is refused before motion (issue #31); one to it runs.
    let e = d.c.jog_step(step("X", -5.0)).await.unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument, "{e:?}");
    assert!(e.message().starts_with("jog_beyond_travel"), "{e:?}");
    assert_eq!(d.ctl.snapshot().axes.commanded[0], 0.1);
    let r = d.c.jog_step(step("X", -1.1)).await.unwrap().into_inner();
    assert!((r.target_mm + 1.0).abs() < 1e-12, "{}", r.target_mm);
    // The reply comes once the step is taken: a status after it shows the jog, never the idle
    // machine from before it.
    let s = d.ctl.snapshot();
    assert!(
        s.state == MachineState::Jog || s.axes.commanded[0] == r.target_mm,
        "{:?} at {}",
        s.state,
        s.axes.commanded[0]
    );
    wait_for(&d.ctl, "step to the limit done", |s| {
        s.state == MachineState::Idle && (s.axes.commanded[0] + 1.0).abs() < 1e-12
    })
    .await;
    let e = d.c.jog_step(step("Q", 1.0)).await.unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument);

    // Continuous jog toward the limit: decelerates to rest exactly on it, never beyond.
    d.record.lock().unwrap().clear();
    let (tx, call) = jog_stream(&d.c, "x", 1, 1000.0).await;
    // (The jog lasts 0.2 s: its end is waited for, not its Jog state, which a busy machine's
    // polls may miss.)
    wait_for(&d.ctl, "at rest on the limit", |s| {
        s.state == MachineState::Idle && s.axes.commanded[0] == 2.0
    })
    .await;
    assert!(d.record.lock().unwrap().iter().all(|p| p[0] <= 2.0));
    drop(tx);
    call.await.unwrap().unwrap();
    // Jogging while a program runs is refused.
    load(&mut d.c, "N10 G1 Y1000000 F600\n").await.unwrap();
    start_job(&mut d.c).await;
    wait_for(&d.ctl, "running", |s| s.state == MachineState::Running).await;
    let e = d.c.jog_step(step("X", -0.5)).await.unwrap_err();
    assert_eq!(e.code(), Code::FailedPrecondition);
    d.c.stop(pb::StopRequest {}).await.unwrap();
}

/// The dead-man: a client that goes away mid-jog (its connection dropped) leaves the axis at
/// rest within its braking distance from where braking started.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn jog_stops_when_the_client_goes_away() {
    let d = daemon(tests::test_config()).await;
    let addr_client = d.c.clone();
    let (tx, call) = jog_stream(&addr_client, "X", -1, 6000.0).await;
    wait_for(&d.ctl, "jogging", |s| {
        s.state == MachineState::Jog && s.axes.commanded[0] < -5.0
    })
    .await;
    // The client vanishes: its task and connection are dropped without ending the stream.
    call.abort();
    drop(tx);
    drop(addr_client);
    wait_for(&d.ctl, "at rest", |s| s.state == MachineState::Idle).await;
    let points = d.record.lock().unwrap().clone();
    let (dist, v) = final_braking(&points, 0);
    let a = 800.0;
    assert!(v > 50.0, "never jogged fast: {v}");
    assert!(top_speed(&points, 0) <= 100.0 + 1e-6);
    assert!(
        dist <= v * v / (2.0 * a) + v * 0.004 + 1e-9,
        "braked over {dist} mm from {v} mm/s"
    );
    let s = d.ctl.snapshot();
    let last = points.last().unwrap()[0];
    assert_eq!(s.axes.commanded[0], last, "at rest");
}

/// Path of a workspace binary of this build.
fn bin(name: &str) -> std::path::PathBuf {
    tests::workspace_bin(name)
}

/// `cncctl jog X+ --speed 1000` killed (SIGKILL) mid-jog: the axis comes to rest on its own.
/// Real time here (cncctl renews every 100 ms of wall clock); the bound does not depend on
/// how late anything runs: after the last renewal the lease (0.5 s) plus the braking distance.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cncctl_jog_killed_mid_jog_leaves_the_axis_at_rest() {
    let cncctl = bin("cncctl");
    let (bus, record) = RecordingBus::new(sim::SimBus::new(
        sim::SimDriveParams::default(),
        &[0.0, 0.0, 0.0],
    ));
    let ctl = Controller::start_with_bus(tests::test_config(), ClockKind::Monotonic, Box::new(bus))
        .unwrap();
    // The Unix socket: tokenless loopback TCP is observer-only.
    let addr = tests::serve_unix(&ctl).await;
    wait_state(&ctl, MachineState::Idle).await;
    let mut child = std::process::Command::new(&cncctl)
        .args(["--addr", &addr, "jog", "Y+", "--speed", "1000"])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    wait_for(&ctl, "jogging Y", |s| {
        s.state == MachineState::Jog && s.axes.commanded[1] > 1.0
    })
    .await;
    child.kill().unwrap();
    let y_killed = ctl.snapshot().axes.commanded[1];
    child.wait().unwrap();
    wait_for(&ctl, "at rest", |s| s.state == MachineState::Idle).await;
    let v = 1000.0 / 60.0;
    let y = ctl.snapshot().axes.commanded[1];
    assert!(
        y >= y_killed && y - y_killed <= v * 0.5 + v * v / 1600.0 + 1e-6,
        "{y_killed} -> {y}"
    );
    let points = record.lock().unwrap().clone();
    let (dist, vb) = final_braking(&points, 1);
    assert!(top_speed(&points, 1) <= v + 1e-6);
    assert!(vb > 0.0, "no braking recorded");
    assert!(
        dist <= vb * vb / 1600.0 + vb * 0.004 + 1e-9,
        "{dist} from {vb} mm/s"
    );
    ctl.shutdown();
}

/// Homing on the simulated machine's home switches (built from the configuration as `cncd`
/// builds it): refusals before, the configured order, the reference taken at the switch.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn homing_in_order_and_refusals_before_it() {
    use daemon::runtime::config::HomingMode;
    let mut cfg = tests::test_config();
    for (i, order, dir, switch) in [(0, 2, -1, -5.0), (2, 1, 1, 3.0)] {
        let a = &mut cfg.axes[i];
        a.homing = HomingMode::Required;
        a.home_order = Some(order);
        a.homing_direction = dir;
        a.sim_home_switch_mm = Some(switch);
        a.homing_speed_mm_min = Some(600.0);
        a.reference_mm = 0.0;
    }
    let ctl = Controller::start(cfg, ClockKind::Monotonic).unwrap();
    // The Unix socket: tokenless loopback TCP is observer-only.
    let addr = tests::serve_unix(&ctl).await;
    let mut c = MachineClient::connect(addr.clone()).await.unwrap();
    wait_state(&ctl, MachineState::Idle).await;

    // Not homed: programs, MDI and continuous jogs are refused; steps are allowed.
    let st = api_common::status_now(&mut c).await;
    let homed: Vec<bool> = st.axes.iter().map(|a| a.homed).collect();
    assert_eq!(homed, [false, true, false], "Y needs no homing");
    load(&mut c, "N10 G1 X1 F1000\n").await.unwrap();
    let e = c.start(pb::StartRequest::default()).await.unwrap_err();
    assert_eq!(e.code(), Code::FailedPrecondition);
    let e = c.mdi(mdi_block("G1 X1 F1000")).await.unwrap_err();
    assert_eq!(e.code(), Code::FailedPrecondition);
    let (tx, call) = jog_stream(&c, "X", 1, 600.0).await;
    drop(tx);
    assert_eq!(
        call.await.unwrap().unwrap_err().code(),
        Code::FailedPrecondition
    );

    // Watch the order: Z moves before X.
    let mut rx = ctl.subscribe();
    let watcher = tokio::spawn(async move {
        let mut first_x = None;
        let mut first_z = None;
        let mut n = 0u64;
        while rx.changed().await.is_ok() {
            let s = *rx.borrow_and_update();
            n += 1;
            if s.axes.commanded[2] != 0.0 && first_z.is_none() {
                first_z = Some(n);
            }
            if s.axes.commanded[0] != 0.0 && first_x.is_none() {
                first_x = Some(n);
            }
            if s.axes.homed & 0b101 == 0b101 {
                return (first_z, first_x);
            }
        }
        (first_z, first_x)
    });
    let r = c
        .home(pb::HomeRequest {
            axes: String::new(),
        })
        .await
        .unwrap()
        .into_inner();
    assert_eq!(r.homed, "ZX", "configured order");
    let (first_z, first_x) = watcher.await.unwrap();
    assert!(first_z.unwrap() < first_x.unwrap(), "Z homes before X");
    let s = ctl.snapshot();
    assert_eq!(s.axes.homed & 0b101, 0b101);
    // The switch position became the reference: the axis stands at 0 plus its overshoot in
    // the search direction: the following error when the drive met the switch (10 mm/s at
    // kv 30/s: 0.33 mm) and the braking distance (0.0625 mm at 800 mm/s²).
    let over = 10.0 / 30.0 + 0.0625 + 10.0 * 0.004;
    assert!(
        s.axes.commanded[0] <= 0.0 && s.axes.commanded[0] > -over,
        "{s:?}"
    );
    assert!(
        s.axes.commanded[2] >= 0.0 && s.axes.commanded[2] < over,
        "{s:?}"
    );
    // The drive settles on its setpoint in the new coordinates (no jump, no offset).
    let x = s.axes.commanded[0];
    wait_for(&ctl, "X settled at the reference", |s| {
        s.axes.commanded[0] == x && (s.axes.actual[0] - x).abs() < 1e-3
    })
    .await;
    let st = api_common::status_now(&mut c).await;
    assert!(st.axes.iter().all(|a| a.homed));

    // Homed: the program runs.
    load(&mut c, "N10 G1 X1 Z-1 F1000\n").await.unwrap();
    let job = start_job(&mut c).await;
    wait_job_finished(&ctl, job).await;
    // A reference run stopped by the operator (here Y, which has no switch) is ABORTED.
    let mut c2 = c.clone();
    let run = tokio::spawn(async move { c2.home(pb::HomeRequest { axes: "Y".into() }).await });
    wait_for(&ctl, "homing Y", |s| s.state == MachineState::Homing).await;
    c.stop(pb::StopRequest {}).await.unwrap();
    assert_eq!(run.await.unwrap().unwrap_err().code(), Code::Aborted);
    ctl.shutdown();
}

/// An M0 in the last block(s) of a program (issue #15 leftover): the program stops there until
/// Resume and only then ends; alone, before M30, with the motion, before or after a technology
/// block. (A program of M0 without any motion is not covered: it does not stop yet.)
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn m0_just_before_the_program_end_stops_until_resume() {
    let mut d = daemon(tests::test_config()).await;
    let programs = [
        ("N10 G1 X10 F3000\nN20 M0\n", 10.0),
        ("N10 G1 X20 F3000 M0\n", 20.0),
        ("N10 G1 X30 F3000\nN20 M0\nN30 M30\n", 30.0),
        ("N10 G1 X40 F3000\nN20 M0\nN30 M5\n", 40.0),
        ("N10 G1 X35 F3000\nN20 M5\nN30 M0\n", 35.0),
    ];
    for (text, x) in programs {
        load(&mut d.c, text).await.unwrap();
        let job = start_job(&mut d.c).await;
        wait_for(&d.ctl, text, |s| {
            s.state == MachineState::Hold && s.progress.program_stop
        })
        .await;
        let s = d.ctl.snapshot();
        assert!((s.axes.commanded[0] - x).abs() < 1e-9, "{text}: {s:?}");
        // It stays at the stop: the job has not ended.
        let seq = s.tick.sequence;
        wait_for(&d.ctl, "time passes", |s| s.tick.sequence > seq + 100).await;
        let s = d.ctl.snapshot();
        assert!(
            s.state == MachineState::Hold && s.progress.finished_job != job,
            "{text}: {s:?}"
        );
        d.c.resume(pb::ResumeRequest {}).await.unwrap();
        wait_job_finished(&d.ctl, job).await;
        wait_state(&d.ctl, MachineState::Idle).await;
    }
}
