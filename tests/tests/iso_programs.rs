//! The ISO / RS274-NGC dialect through the daemon (docs/language.md "ISO programs"): the dry
//! run `cncctl interpret --json` with the work offset and the tool length applied, a CAM-style
//! program uploaded as `.ngc` run end to end on the simulated machine (preview, restart from a
//! block), the machine's default dialect for a name without extension, and the work offsets
//! file (cncctl edits, hand edits, a program's `G10 L2` never reaching it). The daemon starts on
//! the simulated machine with a TAB0.REK in its storage directory.

mod api_common;
mod operator_support;

use std::path::Path;
use std::process::Command;

use api_common::{Daemon, config, diagnostics, named_program, start, status_now, wait_until};
use daemon::runtime::config::Role;
use daemon::runtime::rt::MachineState;
use kernel::offsets::work_file::WorkEdit;
use operator_support::{Cncd, MILL_TOML, bin, save_by_rename, temp_dir, wait_for};
use proto::v1 as pb;
use proto::v1::machine_client::MachineClient;
use proto::v1::preview_client::PreviewClient;
use proto::v1::programs_client::ProgramsClient;
use proto::v1::trajectory_client::TrajectoryClient;
use serde_json::Value;
use tonic::Code;
use tonic::transport::Channel;

/// The machine constants of the test mill (the daemon reads them from its storage dir).
const REK: &str = "; ISO test mill\nR052=500\nR055=0.010\nR237=500\n";

/// A small ISO program: units, work offset, tool change and length, a helical arc, a drilling
/// cycle and a dwell.
const SMALL: &str = "%\n\
(dry run: work offset and tool length)\n\
G21 G90 G54 G17\n\
T1 M6\n\
G43 H1\n\
S1200 M3\n\
G0 X0 Y0 Z5\n\
G1 Z-1 F200\n\
G2 X10 Y0 Z-2 I5 J0 F300\n\
G81 X20 Y10 Z-3 R2 F100\n\
G80\n\
G4 P0.5\n\
G0 Z10\n\
M30\n\
%\n";

/// A program as CAM post-processors write it (block numbers, G53 retracts, G43 on the
/// approach, a contour with arcs, a drilling cycle).
const CAM: &str = "%\n\
(PROGRAM 1001)\n\
(T1 D=6. CR=0. - ZMIN=-2. - FLAT END MILL)\n\
N10 G90 G94 G17 G91.1\n\
N15 G21\n\
N20 G53 G0 Z0.\n\
(2D CONTOUR1)\n\
N25 T1 M6\n\
N30 S5000 M3\n\
N35 G54\n\
N40 G0 X-5. Y-5.\n\
N45 G43 Z15. H1\n\
N50 G0 Z5.\n\
N55 G1 Z-2. F300.\n\
N60 G1 X40. F800.\n\
N65 G3 X50. Y5. I0. J10.\n\
N70 G1 Y30.\n\
N75 G3 X40. Y40. I-10. J0.\n\
N80 G1 X-5.\n\
N85 Y-5.\n\
N90 G0 Z15.\n\
(DRILL1)\n\
N95 G81 X10. Y10. Z-3. R2. F150.\n\
N100 X20.\n\
N105 G80\n\
N110 G0 Z15.\n\
N115 M5\n\
N120 G53 G0 Z0.\n\
N125 M30\n\
%\n";

/// `cncctl ARGS` against `d`: success, standard output, standard error (apart: the dry run
/// prints its moves on one and its messages on the other).
fn cncctl(d: &Cncd, args: &[&str]) -> (bool, String, String) {
    let out = Command::new(bin("cncctl"))
        .arg("--addr")
        .arg(d.addr())
        .args(args)
        .current_dir(&d.cwd)
        .env_remove("CNCCTL_ADDR")
        .env("CNCD_RUNTIME_DIR", &d.runtime)
        .output()
        .unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// `cncctl ARGS` that must succeed: its standard output.
fn ok(d: &Cncd, args: &[&str]) -> String {
    let (ok, out, err) = cncctl(d, args);
    assert!(ok, "cncctl {args:?}: {out}\n{err}\n{}", d.log());
    out
}

/// `cncd` in a fresh directory with TAB0.REK in its storage dir and `extra` configuration.
fn cncd(name: &str, extra: &str) -> Cncd {
    let cwd = temp_dir(name);
    std::fs::create_dir_all(cwd.join("data")).unwrap();
    std::fs::write(cwd.join("data/TAB0.REK"), REK).unwrap();
    Cncd::start(&cwd, &format!("{MILL_TOML}{extra}"))
}

/// The JSON lines of standard output.
fn json_lines(out: &str) -> Vec<Value> {
    out.lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{l}: {e}")))
        .collect()
}

/// An expected move: kind, end X Y Z, source line, and what else it says (`feed_mm_min`,
/// `centre`, `dir`, `seconds` as JSON).
struct Expect(&'static str, [f64; 3], u32, &'static str);

fn assert_moves(got: &[Value], want: &[Expect]) {
    assert_eq!(got.len(), want.len(), "{got:#?}");
    let mut seq = -1i64;
    for (g, Expect(kind, end, line, extra)) in got.iter().zip(want) {
        assert_eq!(g["kind"], *kind, "{g}");
        for (axis, v) in ["X", "Y", "Z"].iter().zip(end) {
            let e = g["end"][axis].as_f64().unwrap();
            assert!((e - v).abs() < 1e-9, "{g}: {axis} {e} != {v}");
        }
        assert_eq!(g["line"], *line, "{g}");
        assert!(g["seq"].as_i64().unwrap() > seq, "{g}: seq goes up");
        seq = g["seq"].as_i64().unwrap();
        let extra: Value = serde_json::from_str(&format!("{{{extra}}}")).unwrap();
        for (k, v) in extra.as_object().unwrap() {
            assert_eq!(&g[k], v, "{g}: {k}");
        }
        if *kind == "rapid" || *kind == "dwell" {
            assert!(g.get("feed_mm_min").is_none(), "{g}");
        }
    }
}

/// (a) The dry run of a small ISO program: every move in machine coordinates, G54 (X100 Y50
/// Z-20) and the length of tool 1 (Z 30) applied: machine Z = program Z + 10.
#[test]
fn interpret_prints_the_moves_with_the_work_offset_and_the_tool_length() {
    let d = cncd("iso_interpret", "");
    ok(&d, &["offset-set", "1", "--l3", "30"]);
    ok(&d, &["work-offset-set", "G54", "X100", "Y50", "Z-20"]);
    std::fs::write(d.cwd.join("prog.ngc"), SMALL).unwrap();
    let (ok_, out, err) = cncctl(&d, &["--json", "interpret", "prog.ngc"]);
    assert!(ok_ && err.is_empty(), "{out}\n{err}");
    let moves = json_lines(&out);
    assert_moves(
        &moves,
        &[
            Expect("rapid", [100.0, 50.0, 15.0], 7, ""),
            Expect("feed", [100.0, 50.0, 9.0], 8, r#""feed_mm_min":200"#),
            Expect(
                "arc",
                [110.0, 50.0, 8.0],
                9,
                r#""centre":{"X":105,"Y":50},"plane":"G17","dir":"cw","feed_mm_min":300"#,
            ),
            // G81 (G99, LinuxCNC's power-on retract): to R at the start, over the hole,
            // down at feed, back to R.
            Expect("rapid", [110.0, 50.0, 12.0], 10, ""),
            Expect("rapid", [120.0, 60.0, 12.0], 10, ""),
            Expect("feed", [120.0, 60.0, 7.0], 10, r#""feed_mm_min":100"#),
            Expect("rapid", [120.0, 60.0, 12.0], 10, ""),
            Expect("dwell", [120.0, 60.0, 12.0], 12, r#""seconds":0.5"#),
            Expect("rapid", [120.0, 60.0, 20.0], 13, ""),
        ],
    );
    // For people: a table, one row a move, and the count.
    let table = ok(&d, &["interpret", "prog.ngc"]);
    assert!(table.lines().next().unwrap().contains("(iso)"), "{table}");
    assert!(table.contains("arc cw") && table.contains("centre X105.000 Y50.000 G17"));
    assert!(table.trim_end().ends_with("9 moves"), "{table}");
    // An error: the moves before it on stdout, the coded message on stderr, exit 1.
    std::fs::write(d.cwd.join("bad.ngc"), "G0 X1\nG1 X2 F100\nG33 X5 K1\n").unwrap();
    let (ok_, out, err) = cncctl(&d, &["--json", "interpret", "bad.ngc"]);
    assert!(!ok_, "{out}");
    assert_eq!(json_lines(&out).len(), 2, "{out}");
    assert!(err.contains("error [iso_unsupported]: line 3:"), "{err}");
    // The CNC836 reading of an ISO text is refused; --dialect iso reads it.
    std::fs::write(d.cwd.join("P2"), "#1 = 5\nG1 X#1 F100\nM30\n").unwrap();
    let (ok_, out, err) = cncctl(&d, &["validate", "P2"]);
    assert!(!ok_, "{out}{err}");
    let out = ok(&d, &["--json", "interpret", "P2", "--dialect", "iso"]);
    // G54 X100 is in force (set above); Y and Z are not programmed and stay.
    assert_eq!(json_lines(&out)[0]["end"]["X"], 105.0, "{out}");
    let (ok_, _, err) = cncctl(&d, &["interpret", "P2", "--dialect", "fanuc"]);
    assert!(!ok_ && err.contains("\"fanuc\""), "{err}");
}

/// (c) `[program] dialect = "iso"`: a program without extension is ISO (load, the library's
/// listing, the dry run), and MDI reads ISO.
#[test]
fn the_machine_default_dialect_makes_an_extensionless_program_iso() {
    let d = cncd("iso_default", "\n[program]\ndialect = \"iso\"\n");
    std::fs::write(d.cwd.join("P1001"), "#1 = 5\nG1 X[#1 * 2] F600\nM30\n").unwrap();
    ok(&d, &["load", "P1001"]);
    let v: Value = serde_json::from_str(ok(&d, &["--json", "programs"]).trim()).unwrap();
    assert_eq!(v["programs"][0]["name"], "P1001", "{v}");
    assert_eq!(v["programs"][0]["dialect"], "iso", "{v}");
    let out = ok(&d, &["--json", "interpret", "--stored", "P1001"]);
    assert_eq!(json_lines(&out)[0]["end"]["X"], 10.0, "{out}");
    // A CNC836 program now needs its dialect named.
    std::fs::write(d.cwd.join("old"), "N10 G1 X1 F100\nN20 G92 D1 R0=2\n").unwrap();
    let (ok_, out, err) = cncctl(&d, &["validate", "old"]);
    assert!(!ok_, "{out}{err}");
    ok(&d, &["validate", "old", "--dialect", "cnc836"]);
    // MDI: the machine's dialect.
    ok(&d, &["mdi", "G0 X[1 + 2]"]);
    wait_for("the MDI move", || {
        let s: Value = serde_json::from_str(ok(&d, &["--json", "status"]).trim()).unwrap();
        s["state"] == "idle" && s["axes"][0]["commanded_mm"] == 3.0
    });
}

/// The work offsets file of `d`.
fn work_file(d: &Cncd) -> String {
    std::fs::read_to_string(d.data.join("WORK.OFS")).unwrap()
}

/// The offsets of system `k` (0 = G54) as `cncctl --json work-offsets` lists them.
fn listed(d: &Cncd, k: usize) -> Vec<f64> {
    let v: Value = serde_json::from_str(ok(d, &["--json", "work-offsets"]).trim()).unwrap();
    assert_eq!(v["active_at_start"], "G54");
    (v["systems"][k]["offset_mm"].as_array().unwrap().iter())
        .map(|x| x.as_f64().unwrap())
        .collect()
}

/// (d) The work offsets live in their file: `work-offset-set` writes it, a hand edit is seen
/// and kept by the next edit, one that does not load raises an alarm and refuses edits, and a
/// program's `G10 L2` changes its own run only.
#[test]
fn work_offsets_are_the_file_and_a_program_never_writes_it() {
    let d = cncd("iso_work", "");
    ok(&d, &["work-offset-set", "G55", "X10", "Y-2.5"]);
    assert!(
        work_file(&d).ends_with("G55 X10.000 Y-2.500\n"),
        "{}",
        work_file(&d)
    );
    assert_eq!(listed(&d, 1), [10.0, -2.5, 0.0]);
    // A hand edit is seen, and the next edit goes on top of it.
    let path = d.data.join("WORK.OFS");
    save_by_rename(&path, &format!("{}G56 Z7 ; by hand\n", work_file(&d)));
    assert_eq!(listed(&d, 2), [0.0, 0.0, 7.0]);
    ok(&d, &["work-offset-set", "G55", "Z1"]);
    let text = work_file(&d);
    assert!(text.contains("G55 X10.000 Y-2.500 Z1.000\n"), "{text}");
    assert!(text.contains("G56 Z7 ; by hand\n"), "{text}");
    // A program's G10 L2 P2 sets G55 for its own run: the dry run and a real run see it, the
    // file does not change, and the next run starts from the file again.
    let prog = "G10 L2 P2 X99\nG55 G0 X0 Y0 Z0\nM30\n";
    std::fs::write(d.cwd.join("g10.ngc"), prog).unwrap();
    let out = ok(&d, &["--json", "interpret", "g10.ngc"]);
    assert_eq!(json_lines(&out)[0]["end"]["X"], 99.0, "{out}");
    ok(&d, &["run", "g10.ngc", "--quiet"]);
    let s: Value = serde_json::from_str(ok(&d, &["--json", "status"]).trim()).unwrap();
    assert_eq!(s["axes"][0]["commanded_mm"], 99.0, "{s}");
    assert_eq!(work_file(&d), text, "G10 must not touch the file");
    assert_eq!(listed(&d, 1), [10.0, -2.5, 1.0]);
    std::fs::write(d.cwd.join("g55.ngc"), "G55 G0 X0\nM30\n").unwrap();
    let out = ok(&d, &["--json", "interpret", "g55.ngc"]);
    assert_eq!(json_lines(&out)[0]["end"]["X"], 10.0, "{out}");
    // A hand edit that does not load: an alarm naming the file, edits refused, file kept.
    save_by_rename(&path, "G54 Q1\n");
    wait_for("the work offsets alarm", || {
        ok(&d, &["alarms"]).contains("work_offsets_file")
    });
    let (ok_, out, err) = cncctl(&d, &["work-offset-set", "G54", "X1"]);
    assert!(!ok_ && err.contains("storage_file_invalid"), "{out}{err}");
    assert_eq!(work_file(&d), "G54 Q1\n");
    let (ok_, _, err) = cncctl(&d, &["work-offset-set", "G60", "X1"]);
    assert!(!ok_ && err.contains("G60"), "{err}");
}

// ---- (b) through the gRPC API, on the in-process daemon ----

/// The in-process daemon (simulated machine) with TAB0.REK, tool 1 of length Z 30 and G54 at
/// X100 Y50 Z-20.
async fn daemon() -> Daemon {
    let cfg = config(Role::Admin);
    std::fs::create_dir_all(&cfg.storage.dir).unwrap();
    std::fs::write(cfg.storage.dir.join("TAB0.REK"), REK).unwrap();
    let d = start(cfg).await;
    d.ctl
        .replace_offsets_file("$KOR\n01: R=3.0 Z=30.0\n", None)
        .unwrap();
    let mut values = [None; kernel::MAX_AXES];
    values[..3].copy_from_slice(&[Some(100.0), Some(50.0), Some(-20.0)]);
    d.ctl
        .edit_work_offset(&WorkEdit { system: 0, values })
        .unwrap();
    d
}

/// The dry run asked for by `req`: its moves and its messages.
async fn interpret(
    ch: Channel,
    req: pb::InterpretRequest,
) -> (Vec<pb::InterpretedMove>, Vec<pb::Diagnostic>) {
    let mut s = ProgramsClient::new(ch)
        .interpret(req)
        .await
        .unwrap()
        .into_inner();
    let (mut moves, mut diags) = (Vec::new(), Vec::new());
    while let Some(c) = s.message().await.unwrap() {
        moves.extend(c.moves);
        if c.last {
            diags = c.diagnostics;
        }
    }
    (moves, diags)
}

/// The setpoints (first 3 axes) and block numbers of the selected program's trajectory.
async fn trajectory(ch: Channel, from_block: Option<u32>) -> Vec<([f64; 3], Option<u32>)> {
    let req = pb::TrajectoryRequest {
        from_block,
        ..Default::default()
    };
    let mut s = TrajectoryClient::new(ch)
        .get_trajectory(req)
        .await
        .unwrap()
        .into_inner();
    let mut out = Vec::new();
    while let Some(c) = s.message().await.unwrap() {
        for k in c.ticks {
            let p = &k.position_mm;
            out.push(([p[0], p[1], p[2]], k.block));
        }
    }
    out
}

/// Runs job `job` to its end, resuming at its program stops (M6 is a manual tool change).
async fn run_to_end(d: &Daemon, m: &mut MachineClient<Channel>, job: u32) {
    loop {
        wait_until("the job to end or stop", || {
            let s = d.ctl.snapshot();
            s.progress.finished_job == job
                || s.progress.aborted_job == job
                || (s.state == MachineState::Hold && s.progress.program_stop)
        })
        .await;
        let s = d.ctl.snapshot();
        assert_ne!(s.progress.aborted_job, job, "{s:?}");
        if s.progress.finished_job == job {
            wait_until("idle", || d.ctl.snapshot().state == MachineState::Idle).await;
            return;
        }
        m.resume(pb::ResumeRequest {}).await.unwrap();
        wait_until("the resume", || !d.ctl.snapshot().progress.program_stop).await;
    }
}

/// Where the axes are commanded, within 1 µm of `end`.
fn assert_at(d: &Daemon, end: &[f64], what: &str) {
    let at = d.ctl.snapshot().axes.commanded;
    for (i, e) in end.iter().enumerate().take(3) {
        assert!(
            (at[i] - e).abs() <= 1e-3,
            "{what}: axis {i} at {} not {e}",
            at[i]
        );
    }
}

fn dist_to_segment(p: [f64; 3], a: [f64; 3], b: [f64; 3]) -> f64 {
    let ab: Vec<f64> = (0..3).map(|i| b[i] - a[i]).collect();
    let len2: f64 = ab.iter().map(|v| v * v).sum();
    let t = if len2 > 0.0 {
        ((0..3).map(|i| ab[i] * (p[i] - a[i])).sum::<f64>() / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (0..3)
        .map(|i| (a[i] + t * ab[i] - p[i]).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// (b) A CAM-style program uploaded as `part.ngc`: ISO by its name, its preview is the dry
/// run's motion, it runs to the dry run's last end, and a restart in the middle follows the
/// uninterrupted path to the same end.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_cam_program_runs_end_to_end_and_restarts_in_the_middle() {
    let d = daemon().await;
    let mut m = MachineClient::new(d.channel().await);
    m.load_program(named_program("part.ngc", CAM))
        .await
        .unwrap();
    let list = ProgramsClient::new(d.channel().await)
        .list(pb::LibraryListRequest {})
        .await
        .unwrap()
        .into_inner();
    assert_eq!(list.programs[0].dialect, "iso", "{list:?}");
    let named = pb::InterpretRequest {
        name: "part.ngc".into(),
        ..Default::default()
    };
    let (moves, diags) = interpret(d.channel().await, named).await;
    assert!(
        diags
            .iter()
            .all(|x| x.severity != pb::Severity::Error as i32),
        "{diags:?}"
    );
    let end = moves.last().unwrap().end_mm.clone();
    // G54 and the tool length: the contour's X-5 Y-5 at Z-2 is X95 Y45 Z8 on the machine.
    assert!(
        moves.iter().any(|x| x.end_mm[..3] == [95.0, 45.0, 8.0]),
        "{moves:?}"
    );
    // The preview draws the dry run's motion.
    let p = PreviewClient::new(d.channel().await)
        .get_preview_data(pb::PreviewDataRequest::default())
        .await
        .unwrap()
        .into_inner();
    let motion: Vec<&pb::InterpretedMove> = (moves.iter())
        .filter(|x| x.kind != pb::MoveKind::Dwell as i32)
        .collect();
    assert_eq!(p.programmed.len(), motion.len(), "{p:?}");
    for (e, x) in p.programmed.iter().zip(&motion) {
        let off = (0..3)
            .map(|i| (e.end_mm[i] - x.end_mm[i]).abs())
            .fold(0.0, f64::max);
        assert!(off < 1e-9 && e.line == x.line, "{e:?} {x:?}");
    }
    assert!(
        p.programmed
            .iter()
            .any(|e| e.kind == pb::PathKind::ArcCcw as i32)
    );
    // The whole run ends at the dry run's last end.
    let job = api_common::start_job(&mut m).await;
    run_to_end(&d, &mut m, job).await;
    assert_at(&d, &end, "after the run");
    // A restart from N70 (inside the contour): approach, then the uninterrupted path.
    let whole = trajectory(d.channel().await, None).await;
    let restart = trajectory(d.channel().await, Some(70)).await;
    let k = restart.iter().position(|(_, b)| b.is_some()).unwrap();
    let from = whole.iter().position(|(_, b)| *b == Some(70)).unwrap();
    let path: Vec<[f64; 3]> = whole[from.saturating_sub(2)..]
        .iter()
        .map(|(p, _)| *p)
        .collect();
    // (Where a corner is passed, the chord between two setpoints that straddle it cuts the
    // corner by up to a few µm, differently in each run: a setpoint also counts as on the
    // path where it lies on a programmed line.)
    let programmed: Vec<[f64; 3]> = moves
        .iter()
        .map(|x| [x.end_mm[0], x.end_mm[1], x.end_mm[2]])
        .collect();
    let off = |q: &[f64; 3], poly: &[[f64; 3]]| {
        poly.windows(2)
            .map(|w| dist_to_segment(*q, w[0], w[1]))
            .fold(f64::INFINITY, f64::min)
    };
    let worst = restart[k..]
        .iter()
        .map(|(q, _)| off(q, &path).min(off(q, &programmed)))
        .fold(0.0, f64::max);
    assert!(worst <= 1e-3, "{worst} mm off the uninterrupted path");
    let job = m
        .start(pb::StartRequest {
            from_block: Some(70),
        })
        .await
        .unwrap()
        .into_inner()
        .job;
    run_to_end(&d, &mut m, job).await;
    assert_at(&d, &end, "after the restart");
    assert_eq!(status_now(&mut m).await.program, "part.ngc");
}

/// The dialect field and the doors that read programs in chunks or one block: an unknown
/// dialect is refused with its code, `Programs.Validate` of an ISO loop (spooled: the lines
/// are read again), MDI in ISO.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn dialect_field_validation_and_mdi() {
    let d = daemon().await;
    let bad = pb::InterpretRequest {
        text: "G0 X1\n".into(),
        dialect: "fanuc".into(),
        ..Default::default()
    };
    let e = ProgramsClient::new(d.channel().await)
        .interpret(bad)
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument, "{e:?}");
    assert_eq!(diagnostics(&e)[0].code, "dialect_unknown");
    let mut m = MachineClient::new(d.channel().await);
    let mut req = named_program("x.ngc", "G0 X1\n");
    req.dialect = "heidenhain".into();
    let e = m.load_program(req).await.unwrap_err();
    assert_eq!(diagnostics(&e)[0].code, "dialect_unknown");
    // A loop validated from chunks: by its name, ISO.
    let text = "#1 = 0\no100 while [#1 LT 4]\nG1 X[#1] F500\n#1 = [#1 + 1]\no100 endwhile\nM30\n";
    let validate = |name: &str| {
        let chunks = vec![
            pb::ProgramChunk {
                name: name.into(),
                data: text.as_bytes()[..20].to_vec(),
                ..Default::default()
            },
            pb::ProgramChunk {
                data: text.as_bytes()[20..].to_vec(),
                ..Default::default()
            },
        ];
        let ch = d.channel();
        async move {
            ProgramsClient::new(ch.await)
                .validate(tokio_stream::iter(chunks))
                .await
                .unwrap()
                .into_inner()
        }
    };
    let v = validate("loop.ngc").await;
    assert!(v.valid && v.blocks >= 4, "{v:?}");
    let v = validate("loop.txt").await;
    assert!(!v.valid, "CNC836 has no #: {v:?}");
    // MDI: ISO when asked, an expression the CNC836 dialect refuses.
    let mdi = |dialect: &str| pb::MdiRequest {
        block: "G0 X[1 + 1]".into(),
        dialect: dialect.into(),
    };
    let e = m.mdi(mdi("")).await.unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument, "{e:?}");
    m.mdi(mdi("iso")).await.unwrap();
    wait_until("X102 (G54 X100)", || {
        let s = d.ctl.snapshot();
        s.state == MachineState::Idle && (s.axes.commanded[0] - 102.0).abs() < 1e-9
    })
    .await;
}

/// The config's `[program] dialect` accepts only what cncd reads (also `cncd --check-config`,
/// tests/tests/check_config.rs).
#[test]
fn unknown_default_dialect_is_refused() {
    let e = daemon::runtime::config::Config::parse(
        "[program]\ndialect = \"fanuc\"\n",
        Path::new("x.toml"),
    )
    .unwrap_err();
    assert!(e.to_string().contains("program.dialect"), "{e}");
}
