//! Issue #14 acceptance: for every constant the controller reads
//! (`kernel::machine::CONSTANTS_READ`, checked in the kernel against what `MachineSetup`
//! decodes) a test changes it through `SetConstants` on a running daemon (gRPC, as `cncctl
//! constants set` does) and shows its effect on what the next start runs: the planned
//! trajectory (`GetTrajectory`, the job's setup and pipeline), the diagnostics and paths of
//! the pass, the spindle, the G24 window, the preview pages. [`COVERAGE`] names the test of
//! each constant; `every_constant_read_has_a_daemon_test` fails when a constant is read that
//! has none. `SetConstants` is refused while a job runs, so a running job never sees a change
//! (`a_running_job_keeps_its_constants`).

mod api_common;

use api_common::*;
use daemon::runtime::config::Role;
use daemon::runtime::rt::MachineState;
use proto::v1 as pb;
use proto::v1::constants_client::ConstantsClient;
use proto::v1::machine_client::MachineClient;
use proto::v1::preview_client::PreviewClient;
use proto::v1::trajectory_client::TrajectoryClient;
use tonic::Code;
use tonic::transport::Channel;

/// Each constant read (ranges of `CONSTANTS_READ`) and the daemon-level tests that change it
/// through `SetConstants`: (first, last, test file, test function). A constant whose decades
/// mean different things has a case per decade in its test (see the cases' names).
const COVERAGE: &[(u16, u16, &str, &str)] = &[
    (
        0,
        5,
        "pipeline_doors",
        "axis_codes_need_a_restart_and_are_not_used_before",
    ),
    (
        6,
        6,
        "pipeline_doors",
        "r6_g24_window_reaches_the_rt_thread_at_the_next_start",
    ),
    (7, 7, HERE, "r7_g24_window_of_axes_4_to_6_at_the_next_start"),
    (
        39,
        39,
        "pipeline_doors",
        "planner_and_interpreter_constants_take_effect_at_the_next_pass",
    ),
    (52, 52, HERE, "planner_constants_change_the_next_trajectory"),
    (
        55,
        55,
        "pipeline_doors",
        "r55_is_one_tolerance_for_interpreter_and_compensation",
    ),
    (
        67,
        67,
        "pipeline_doors",
        "r67_controlling_axis_changes_at_the_next_start",
    ),
    (
        95,
        95,
        "pipeline_doors",
        "every_door_gives_the_verdict_of_validation",
    ),
    (
        97,
        97,
        "pipeline_doors",
        "planner_and_interpreter_constants_take_effect_at_the_next_pass",
    ),
    (
        232,
        232,
        HERE,
        "planner_constants_change_the_next_trajectory",
    ),
    (234, 234, HERE, "r234_moves_the_compensated_corner"),
    (
        236,
        237,
        HERE,
        "planner_constants_change_the_next_trajectory",
    ),
    (325, 325, HERE, "r325_refines_the_arc_r55_refuses"),
    (
        329,
        329,
        "pipeline_doors",
        "s_units_r329_reach_kr_and_the_spindle_at_the_next_start",
    ),
    (
        338,
        338,
        HERE,
        "planner_constants_change_the_next_trajectory",
    ),
    (
        339,
        339,
        "pipeline_doors",
        "start_refuses_what_the_constants_in_force_refuse",
    ),
    (
        382,
        385,
        HERE,
        "planner_constants_change_the_next_trajectory",
    ),
    (387, 387, HERE, "r387_pages_the_next_preview"),
    (
        395,
        395,
        HERE,
        "planner_constants_change_the_next_trajectory",
    ),
    (
        397,
        397,
        "pipeline_doors",
        "planner_and_interpreter_constants_take_effect_at_the_next_pass",
    ),
    (406, 432, HERE, "dynamic_sets_change_the_next_trajectory"),
    (
        580,
        580,
        HERE,
        "r580_old_kr_ignores_the_g76_limit_at_the_next_start",
    ),
    (764, 765, HERE, "r764_r765_reports_appear_at_the_next_pass"),
];

const HERE: &str = "constants_next_start";

fn source_of(file: &str) -> &'static str {
    match file {
        HERE => include_str!("constants_next_start.rs"),
        "pipeline_doors" => include_str!("pipeline_doors.rs"),
        _ => panic!("unknown test file {file}"),
    }
}

#[test]
fn every_constant_read_has_a_daemon_test() {
    for r in kernel::machine::constants_read() {
        let tests: Vec<_> = COVERAGE
            .iter()
            .filter(|(a, b, _, _)| (*a..=*b).contains(&r))
            .collect();
        assert!(
            !tests.is_empty(),
            "R{r} is read but has no daemon-level test"
        );
        for (_, _, file, test) in tests {
            let src = source_of(file);
            let at = src
                .find(&format!("async fn {test}()"))
                .unwrap_or_else(|| panic!("R{r}: {file}.rs has no test {test}"));
            // A daemon-level test: it runs in tokio, on a daemon.
            assert!(
                src[..at]
                    .trim_end()
                    .ends_with("#[tokio::test(flavor = \"multi_thread\", worker_threads = 2)]"),
                "{test} is not a daemon test"
            );
        }
    }
    // And nothing in the table is stale.
    for (a, b, _, _) in COVERAGE {
        for r in *a..=*b {
            assert!(
                kernel::machine::constants_read().any(|x| x == r),
                "R{r} is covered but not read"
            );
        }
    }
}

/// The offset table: D1 radius 3, D2 radius 5, D3 radius 2, D4 radius 1.
const TABLE: &str = "$KOR\n01: R=3.0\n02: R=5.0\n03: R=2.0\n04: R=1.0\n";

struct Api {
    m: MachineClient<Channel>,
    p: PreviewClient<Channel>,
    k: ConstantsClient<Channel>,
    t: TrajectoryClient<Channel>,
}

impl Api {
    async fn new(ch: Channel) -> Self {
        Api {
            m: MachineClient::new(ch.clone()),
            p: PreviewClient::new(ch.clone()),
            k: ConstantsClient::new(ch.clone()),
            t: TrajectoryClient::new(ch),
        }
    }

    /// `SetConstants`, as `cncctl constants set R..=..` sends it.
    async fn set(&mut self, values: &[(u16, f64)]) -> Result<pb::SetConstantsReply, tonic::Status> {
        let values: Vec<(u32, f64)> = values.iter().map(|&(r, v)| (u32::from(r), v)).collect();
        self.k
            .set_constants(constant_values(&values))
            .await
            .map(|r| r.into_inner())
    }

    /// Puts `numbers` back to their defaults.
    async fn reset(&mut self, numbers: impl IntoIterator<Item = u16>) {
        let v: Vec<(u16, f64)> = numbers
            .into_iter()
            .map(|r| (r, kernel::constants::default_of(r) as f64 / 1000.0))
            .collect();
        self.set(&v).await.unwrap();
    }

    /// Planned machining time of `text` under the constants in force, s.
    async fn planned_s(&mut self, text: &str) -> f64 {
        let mut s = self
            .t
            .get_trajectory(pb::TrajectoryRequest {
                text: text.into(),
                ..Default::default()
            })
            .await
            .unwrap()
            .into_inner();
        while let Some(c) = s.message().await.unwrap() {
            if c.last {
                return c.total_s;
            }
        }
        panic!("the trajectory has no last chunk")
    }

    async fn validate(&mut self, text: &str) -> pb::ValidateProgramReply {
        validate(&mut self.m, text).await
    }

    async fn preview(&mut self, text: &str) -> pb::PreviewData {
        preview_data(&mut self.p, text, true).await.unwrap()
    }

    /// Loads and starts `text`; returns the job.
    async fn start(&mut self, text: &str) -> u32 {
        load_and_start(&mut self.m, "c.nc", text).await
    }

    /// Loads, starts and runs `text` to its end without alarm.
    async fn run(&mut self, d: &Daemon, text: &str) {
        let job = self.start(text).await;
        wait_job_finished(&d.ctl, job).await;
        assert!(d.ctl.alarm().is_none(), "{:?}", d.ctl.alarm());
    }
}

async fn daemon() -> (Daemon, Api) {
    let d = start(config(Role::Admin)).await;
    d.ctl.replace_offsets_file(TABLE, None).unwrap();
    let api = Api::new(d.channel().await).await;
    (d, api)
}

/// A planner constant, its new value and a program whose planned time it changes; `pre`
/// is in force before and after (e.g. the parabolic profile a jerk setting needs).
struct PlanCase {
    what: String,
    pre: Vec<(u16, f64)>,
    set: Vec<(u16, f64)>,
    program: String,
}

fn case(what: &str, pre: &[(u16, f64)], set: &[(u16, f64)], program: &str) -> PlanCase {
    PlanCase {
        what: what.into(),
        pre: pre.to_vec(),
        set: set.to_vec(),
        program: program.into(),
    }
}

/// The programs end where they start (X0 Y0): the runs leave the machine there. `{I}` is
/// replaced by the dynamic set's selection (`I2` ...).
const LONG_LINE: &str = "N10 G1 X80 F6000\nN20 X0\n";
const RAPID: &str = "N10 G0 X80\nN20 X0\n";
/// Short blocks with small turns under G23 (continuity).
const ZIGZAG: &str = "N10 G23 {I} G1 X2 Y0.1 F6000\nN20 X4 Y0\nN30 X6 Y0.1\nN40 X8 Y0\nN50 X10 Y0.1\nN60 X12 Y0\nN70 X14 Y0.1\nN80 X16 Y0\nN90 G24 X0\n";
/// Very short blocks, nearly collinear, under G23.
const SHORT_BLOCKS: &str = "N10 G23 {I} G1 X0.3 Y0.001 F6000\nN20 X0.6 Y0\nN30 X0.9 Y0.001\nN40 X1.2 Y0\nN50 X1.5 Y0.001\nN60 X1.8 Y0\nN70 X2.1 Y0.001\nN80 X20 Y0\nN90 G24 X0\n";
/// Forty 0.3 mm blocks in a shallow zig-zag: many corners that merging (R383) removes.
fn zigzag_blocks() -> String {
    let mut p = String::from("N10 G23 {I} G1 X0.3 Y0.01 F6000\n");
    for k in 2..=40 {
        let y = if k % 2 == 0 { 0.0 } else { 0.01 };
        p.push_str(&format!("N{} X{:.1} Y{y}\n", k * 10, 0.3 * k as f64));
    }
    p.push_str("N500 X20 Y0\nN510 G24 X0\n");
    p
}
/// A fast arc under G23.
const ARC: &str = "N10 G23 {I} G1 X10 Y0 F6000\nN20 G3 X10 Y20 I0 J10\nN30 G1 X0 Y20\nN40 G24 Y0\n";

/// `program` in dynamic set `set` (1..4; 1 is the default).
fn in_set(program: &str, set: u16) -> String {
    let i = if set == 1 {
        String::new()
    } else {
        format!("I{set}")
    };
    program.replace("{I}", &i)
}

/// R338 = 0.020: 2.R338 = 2, the parabolic profile the jerk settings (P) apply to.
const PARABOLIC: (u16, f64) = (338, 0.02);

fn plan_cases() -> Vec<PlanCase> {
    let p = |t| in_set(t, 1);
    vec![
        case("R52 acceleration to a stop", &[], &[(52, 50.0)], LONG_LINE),
        case(
            "R236 continuous acceleration",
            &[],
            &[(236, 50.0)],
            &p(ZIGZAG),
        ),
        case("R237 rapid acceleration", &[], &[(237, 50.0)], RAPID),
        case("2.R338 = 2 parabolic profile", &[], &[PARABOLIC], LONG_LINE),
        // (R395 keeps the speeds of the manual's criteria through a short block: with R384
        // Lm 8 µm the zig-zag's turns have them, 40 mm/s.)
        case(
            "R395 1 ms rise limit",
            &[(384, 0.008)],
            &[(395, 0.001)],
            &p(ZIGZAG),
        ),
        case(
            "R232 d5..8 old centripetal 50 %",
            &[],
            &[(232, 500.0)],
            &p(ARC),
        ),
        case(
            "R382 break length 1 mm",
            &[],
            &[(382, 1.0)],
            &p(SHORT_BLOCKS),
        ),
        case(
            "R383 merge length 1 mm",
            &[],
            &[(383, 1.0)],
            &p(&zigzag_blocks()),
        ),
        // (R384 is the criterion of the junctions' turns: the arc's junctions are tangent,
        // and within an arc the chord criterion R232 holds.)
        case("R384 d1..4 accuracy 1 um", &[], &[(384, 0.001)], &p(ZIGZAG)),
        case(
            "R385 overload 20 mm/s2",
            &[],
            &[(385, 0.02)],
            &p(SHORT_BLOCKS),
        ),
        case(
            "R385 d8 reference length",
            &[(385, 0.02)],
            &[(385, 10000.02)],
            &p(SHORT_BLOCKS),
        ),
        case(
            "R430..R432 rapid set A",
            &[],
            &[(430, 0.001), (432, 0.05)],
            RAPID,
        ),
        case(
            "R431 rapid set P",
            &[PARABOLIC, (430, 0.001)],
            &[(431, 1.0)],
            RAPID,
        ),
    ]
}

/// Each value of each dynamic set (R406 + 6k: control word; +1 P, +2 A, +3 accuracy and
/// drop, +4 overload, +5 centripetal), in a program that selects the set.
fn dynamic_set_cases() -> Vec<PlanCase> {
    let mut v = Vec::new();
    for set in 1..=4u16 {
        let base = 406 + 6 * (set - 1);
        // Sets 2..4 complete from set 1: set 1 is switched on for them.
        let mut on = vec![(406, 0.001)];
        if set > 1 {
            on.push((base, 0.001));
        }
        let what = |w: &str| format!("set {set} R{}: {w}", base);
        let mut pre_p = on.clone();
        pre_p.push(PARABOLIC);
        v.push(case(
            &what("P jerk"),
            &pre_p,
            &[(base + 1, 1.0)],
            &in_set(ZIGZAG, set),
        ));
        v.push(case(
            &what("A"),
            &on,
            &[(base + 2, 0.05)],
            &in_set(ZIGZAG, set),
        ));
        v.push(case(
            &what("accuracy"),
            &on,
            &[(base + 3, 0.001)],
            &in_set(ZIGZAG, set),
        ));
        v.push(case(
            &what("overload"),
            &on,
            &[(base + 4, 0.02)],
            &in_set(SHORT_BLOCKS, set),
        ));
        v.push(case(
            &what("centripetal"),
            &on,
            &[(base + 5, 10000.1)],
            &in_set(ARC, set),
        ));
        // The control word itself: switching the set off drops its A.
        let mut with_a = on.clone();
        with_a.push((base + 2, 0.05));
        v.push(case(
            &what("control word off"),
            &with_a,
            &[(base, 0.0)],
            &in_set(ZIGZAG, set),
        ));
    }
    v
}

/// Every constant a case may change, reset before each case.
fn plan_constants(cases: &[PlanCase]) -> Vec<u16> {
    let mut v: Vec<u16> = cases
        .iter()
        .flat_map(|c| c.set.iter().chain(&c.pre).map(|s| s.0))
        .collect();
    v.sort();
    v.dedup();
    v
}

/// Runs shorter than this are run on the machine after the change, s.
const RUN_IF_SHORTER_S: f64 = 6.0;

/// For each case: the planned time under `pre`, then with the case's constants (set through
/// the API) — they differ — and the next start runs to its end under them.
async fn check_plan_cases(d: &Daemon, api: &mut Api, cases: &[PlanCase]) -> Vec<u16> {
    let all = plan_constants(cases);
    let mut shown = Vec::new();
    for c in cases {
        api.reset(all.iter().copied()).await;
        if !c.pre.is_empty() {
            api.set(&c.pre).await.unwrap();
        }
        let before = api.planned_s(&c.program).await;
        let r = api.set(&c.set).await.unwrap();
        assert!(r.restart_required.is_empty(), "{}", c.what);
        let after = api.planned_s(&c.program).await;
        eprintln!("{}: {before:.3} s → {after:.3} s", c.what);
        assert!(
            (after - before).abs() > 0.008,
            "{}: {before} s → {after} s",
            c.what
        );
        if after < RUN_IF_SHORTER_S {
            api.run(d, &c.program).await;
        }
        shown.extend(c.set.iter().map(|s| s.0));
    }
    api.reset(all).await;
    shown.sort();
    shown.dedup();
    shown
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn planner_constants_change_the_next_trajectory() {
    let (d, mut api) = daemon().await;
    let shown = check_plan_cases(&d, &mut api, &plan_cases()).await;
    for r in [
        52, 232, 236, 237, 338, 382, 383, 384, 385, 395, 430, 431, 432,
    ] {
        assert!(shown.contains(&r), "R{r}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn dynamic_sets_change_the_next_trajectory() {
    let (d, mut api) = daemon().await;
    let shown = check_plan_cases(&d, &mut api, &dynamic_set_cases()).await;
    assert_eq!(shown, (406..=429).collect::<Vec<_>>());
}

fn warnings_at(v: &[pb::Diagnostic], block: u32) -> usize {
    v.iter()
        .filter(|d| d.severity == pb::Severity::Warning as i32 && d.block == Some(block))
        .count()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn r764_r765_reports_appear_at_the_next_pass() {
    let (d, mut api) = daemon().await;
    // R764 (SPEC §4.5): the last working block before a rapid (N40, 2 mm < 150 % of the
    // 5 mm radius) whose equidistant runs backwards. 7.R764 = 1 reports it.
    let exit = "N10 G0 X-10 Y0\nN20 D2 G41 G1 X0 Y0 F500\nN30 X20 Y0\nN40 X20 Y2\nN50 G0 X20 Y50\nN60 G40 G0 X0 Y0\n";
    // R765: the equidistant of a -165° corner lies farther than 300 % of the 1 mm radius from
    // the programmed corner (N30→N40). 7.R765 = 1 reports it at N40.
    let position = "N10 G0 X-10 Y0\nN20 D4 G41 G1 X0 Y0 F500\nN30 X20 Y0\nN40 X0.682 Y-5.176\nN50 G40 X0 Y-20\nN60 G0 X0 Y0\n";
    for (r, text, block) in [(764u16, exit, 40u32), (765, position, 40)] {
        let v = api.validate(text).await;
        assert!(v.valid, "R{r}: {v:?}");
        // (R764's block also gets the whole-run gouge check's warning, with or without it.)
        let before = warnings_at(&v.diagnostics, block);
        api.set(&[(r, 1000.0)]).await.unwrap();
        let v = api.validate(text).await;
        assert!(v.valid, "R{r}: {v:?}");
        assert_eq!(
            warnings_at(&v.diagnostics, block),
            before + 1,
            "R{r}: {v:?}"
        );
        // The run of the next start is the one that pass planned: it ends without alarm.
        api.run(&d, text).await;
        api.reset([r]).await;
    }
}

/// End point of the compensated block `n` in the preview data.
fn compensated_end(p: &pb::PreviewData, n: u32) -> Vec<f64> {
    p.compensated
        .iter()
        .rfind(|e| e.block == Some(n))
        .unwrap_or_else(|| panic!("no N{n}: {p:?}"))
        .end_mm
        .clone()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn r234_moves_the_compensated_corner() {
    let (d, mut api) = daemon().await;
    // A 0.5° inside corner at N30 (SPEC §4.4): above R234 the intersection of the
    // equidistants, below it the point on the mean normal.
    let text = "N10 G0 X-10 Y0\nN20 D3 G41 G1 X0 Y0 F500\nN30 X10 Y0\nN40 X20 Y0.087\nN50 G40 X30 Y0\nN60 G0 X0 Y0\n";
    api.set(&[(234, 0.0)]).await.unwrap();
    let exact = compensated_end(&api.preview(text).await, 30);
    api.set(&[(234, 0.8)]).await.unwrap();
    let normal = compensated_end(&api.preview(text).await, 30);
    // Intersection: on y = 2; the point on the mean normal lies below it, 2·(1 − cos(a/2)).
    assert!((exact[1] - 2.0).abs() < 1e-6, "{exact:?}");
    assert!(exact[1] - normal[1] > 1e-5, "{normal:?} {exact:?}");
    api.run(&d, text).await;
}

/// An arc whose end point is 3 µm off its circle.
const OFF_CENTRE: &str = "N10 G3 X10 Y10 I0.003 J10 F1000\nN20 G0 X0 Y0\n";

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn r325_refines_the_arc_r55_refuses() {
    let (d, mut api) = daemon().await;
    api.set(&[(55, 0.0)]).await.unwrap();
    let v = api.validate(OFF_CENTRE).await;
    assert!(!v.valid, "{v:?}");
    // 8.R325 = 1, limit 10 µm: the preprocessor moves the centre ($63 is on in the daemon).
    api.set(&[(325, 10000.010)]).await.unwrap();
    let v = api.validate(OFF_CENTRE).await;
    assert!(v.valid, "{v:?}");
    assert_eq!(v.refinements.len(), 1, "{v:?}");
    api.run(&d, OFF_CENTRE).await;
    // Limit 1 µm: too small for 3 µm, refused again at the next pass and start.
    api.set(&[(325, 10000.001)]).await.unwrap();
    assert!(!api.validate(OFF_CENTRE).await.valid);
    let e = api.m.start(pb::StartRequest::default()).await.unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn r387_pages_the_next_preview() {
    let (_d, mut api) = daemon().await;
    let mut text = String::new();
    for i in 0..10 {
        text.push_str(&format!(
            "N{} G1 X{} Y{} F1000\n",
            10 * (i + 1),
            i % 3,
            i % 2
        ));
    }
    let pages = async |api: &mut Api| {
        api.p
            .get_preview(pb::GetPreviewRequest {
                text: text.clone(),
                ..Default::default()
            })
            .await
            .unwrap()
            .into_inner()
            .pages
    };
    assert_eq!(pages(&mut api).await, 1);
    // R387 = 0.004: 4 blocks a page (the digit string, docs: R387 is read as its digits).
    api.set(&[(387, 0.004)]).await.unwrap();
    assert_eq!(pages(&mut api).await, 3);
}

/// A program in KŘR at r = 50 mm under a G76 limit of 200 rpm, held in N30 (a slow move). X is a
/// radius on this mill (`radius_input = "radius"`, the default since diameter programming, #17).
const G76_PROGRAM: &str = "N10 G0 X50 Y40\nN15 G76 S200\nN20 M3 G96 S900\nN30 G1 X49 F6\n";

/// The spindle speed while `G76_PROGRAM` is in N30; the job is stopped afterwards.
async fn g76_spindle_rpm(d: &Daemon, api: &mut Api) -> f64 {
    let job = api.start(G76_PROGRAM).await;
    let st = d.ctl.clone();
    wait_until("KŘR in N30", || {
        let s = st.snapshot();
        s.progress.job == job && s.progress.block_n == Some(30) && s.spindle.kr.spindle_rpm > 0.0
    })
    .await;
    // 50 ticks into N30 (10 s long): KŘR has settled on this job's speed.
    let t0 = d.ctl.snapshot().tick.sequence;
    wait_until("50 ticks", || st.snapshot().tick.sequence > t0 + 50).await;
    let s = d.ctl.snapshot();
    assert_eq!((s.progress.job, s.progress.block_n), (job, Some(30)));
    let rpm = s.spindle.kr.spindle_rpm;
    api.m.stop(pb::StopRequest {}).await.unwrap();
    wait_state(&d.ctl, MachineState::Idle).await;
    rpm
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn r580_old_kr_ignores_the_g76_limit_at_the_next_start() {
    let (d, mut api) = daemon().await;
    // Version 2 (R580 = 1, the default): 90 m/min at r = 50 mm would be 286.5 rpm; G76 caps.
    assert!((g76_spindle_rpm(&d, &mut api).await - 200.0).abs() < 1e-6);
    // R580 = 0: old KŘR has no limit (SPEC §6): the next start turns at 286.5 rpm.
    api.set(&[(580, 0.0)]).await.unwrap();
    let rpm = g76_spindle_rpm(&d, &mut api).await;
    let expect = 90_000.0 / (2.0 * std::f64::consts::PI * 50.0);
    assert!((rpm - expect).abs() < 1.0, "{rpm}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_running_job_keeps_its_constants() {
    let (d, mut api) = daemon().await;
    // 5 s at F600.
    let job = api.start("N10 G1 X50 F600\nN20 G0 X0\n").await;
    let st = d.ctl.clone();
    wait_until("running", || {
        let s = st.snapshot();
        s.progress.job == job && s.state == MachineState::Running
    })
    .await;
    let e = api.set(&[(52, 50.0)]).await.unwrap_err();
    assert_eq!(e.code(), Code::FailedPrecondition);
    assert_eq!(d.ctl.constants().get(52), 500.0, "nothing saved");
    assert_eq!(d.ctl.constants_in_force().get(52), 500.0);
    wait_job_finished(&d.ctl, job).await;
}

/// Axis 4 (U) lags on [`api_common::LaggingBus`]: its window is R7.
const LAGGING: usize = 3;

/// A daemon with axes X, Y, Z, U on [`api_common::LaggingBus`] (U lags), served on a Unix
/// socket (local trust, admin; loopback TCP only observes).
async fn four_axis_lagging_daemon() -> (std::sync::Arc<daemon::runtime::controller::Controller>, Api)
{
    use daemon::runtime::config::AxisConfig;
    let mut cfg = config(Role::Admin);
    cfg.axes.push(AxisConfig {
        node_id: Some(4),
        ..AxisConfig::new('U')
    });
    let (ctl, ch) = lagging_daemon(cfg, LAGGING).await;
    (ctl, Api::new(ch).await)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn r7_g24_window_of_axes_4_to_6_at_the_next_start() {
    let (ctl, mut api) = four_axis_lagging_daemon().await;
    // R7 = 0.1 mm: U's 0.05 mm lag counts as arrived; G24 goes on and the job ends. R6 (axes
    // 1..3) stays at its 10 µm default: R7 is the window U reads.
    api.set(&[(7, 0.1)]).await.unwrap();
    let job = api.start("N10 G24 G1 U5 F3000\nN20 U10\n").await;
    wait_job_finished(&ctl, job).await;
    // R7 = 0.01 mm, in force at the next start: G24 waits at the end of N10 for ever.
    api.set(&[(7, 0.01)]).await.unwrap();
    let job = api.start("N10 G24 G1 U15 F3000\nN20 U20\n").await;
    assert_g24_waits_at_the_end_of_n10(&ctl, &mut api.m, job, LAGGING, 15.0).await;
}

/// Junction classes of `text` in the preview data.
async fn junction_classes(api: &mut Api, text: &str) -> Vec<i32> {
    api.preview(text)
        .await
        .junctions
        .iter()
        .map(|j| j.class)
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn r384_speed_drop_classifies_the_next_junctions() {
    let (d, mut api) = daemon().await;
    let drop = pb::JunctionClass::SpeedDrop as i32;
    let text = in_set(ZIGZAG, 1);
    api.reset([384]).await;
    let before = junction_classes(&mut api, &text).await;
    assert!(!before.contains(&drop), "{before:?}");
    // R384 d5..6 = 99 %: a smooth junction slower than 99 % of the feed is a speed drop
    // (SPEC §7.5, red in the preview).
    api.set(&[(384, 990.0)]).await.unwrap();
    let after = junction_classes(&mut api, &text).await;
    assert!(after.contains(&drop), "{after:?}");
    api.run(&d, &text).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn r232_chord_error_slows_the_next_arc() {
    // Axes of 10 m/s²: the chord error of 1 µm per tick, not the centripetal acceleration,
    // limits a 10 mm arc at 6 m/min (v ≤ √(8·R·e)/T = 70.7 mm/s).
    let mut cfg = config(Role::Admin);
    for a in &mut cfg.axes {
        a.max_accel_mm_s2 = 10_000.0;
    }
    let d = start(cfg).await;
    let mut api = Api::new(d.channel().await).await;
    let text = in_set(ARC, 1);
    api.reset([232]).await;
    let before = api.planned_s(&text).await;
    api.set(&[(232, 0.001)]).await.unwrap();
    let after = api.planned_s(&text).await;
    assert!(after > before + 0.008, "{before} s → {after} s");
    api.run(&d, &text).await;
}
