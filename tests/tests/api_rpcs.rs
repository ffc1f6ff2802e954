//! Every RPC of the API, through gRPC on the simulated machine: results, and each error code
//! (INVALID_ARGUMENT with block/line details, FAILED_PRECONDITION, NOT_FOUND,
//! RESOURCE_EXHAUSTED, DEADLINE_EXCEEDED).

mod api_common;

use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use api_common::*;
use daemon::runtime::config::Role;
use daemon::runtime::rt::MachineState;
use proto::v1 as pb;
use proto::v1::constants_client::ConstantsClient;
use proto::v1::machine_client::MachineClient;
use proto::v1::offsets_client::OffsetsClient;
use proto::v1::plc_client::PlcClient;
use proto::v1::preview_client::PreviewClient;
use tonic::Code;

const PROGRAM: &str = "\
N10 G0 X10 Y5
N20 G1 X30 F1500
N30 Y20 Z-2
N40 G0 X0 Y0 Z0
";

/// A program long enough to hold, resume and stop (about 8 s at F600).
const LONG: &str = "N10 G1 X80 F600\nN20 X0\n";

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn programs_validate_upload_select_list_start_and_status() {
    let d = start(config(Role::Admin)).await;
    let mut c = MachineClient::new(d.channel().await);

    // Validate only: every error with block and line, nothing selected.
    let v = validate(&mut c, "N10 G1 X10 F100\nN20 G7 X5\nN30 G1 Q5\n").await;
    assert!(!v.valid);
    let errors: Vec<_> = v
        .diagnostics
        .iter()
        .filter(|d| d.severity == pb::Severity::Error as i32)
        .collect();
    assert!(errors.len() >= 2, "{:?}", v.diagnostics);
    assert_eq!(errors[0].block, Some(20));
    assert_eq!(errors[0].line, 2);
    assert_eq!(errors[1].line, 3);
    let ok = validate(&mut c, PROGRAM).await;
    assert!(ok.valid);
    assert_eq!(ok.blocks, 4);

    // Upload with errors: INVALID_ARGUMENT with the diagnostics in the details.
    let e = c
        .upload_program(named_program("bad.nc", "N10 G1 X10 F100\nN20 G7\n"))
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument);
    let diags = diagnostics(&e);
    assert_eq!(diags[0].block, Some(20));
    assert_eq!(diags[0].line, 2);
    assert_eq!(diags[0].code, "unknown_g_function");
    assert!(
        e.message().contains("N20") || e.message().contains("line 2"),
        "{}",
        e.message()
    );

    // Upload stores without selecting; select unknown is NOT_FOUND.
    let up = c
        .upload_program(named_program("part.nc", PROGRAM))
        .await
        .unwrap()
        .into_inner();
    assert_eq!(up.blocks, 4);
    let list = list_programs(&mut c).await;
    assert_eq!(list.programs.len(), 1);
    assert_eq!(list.programs[0].name, "part.nc");
    assert_eq!(list.selected, "");
    let e = c.start(pb::StartRequest::default()).await.unwrap_err();
    assert_eq!(
        e.code(),
        Code::FailedPrecondition,
        "start without a program"
    );
    let e = c
        .select_program(pb::SelectProgramRequest {
            name: "nope.nc".into(),
            dialect: String::new(),
        })
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::NotFound);
    c.select_program(pb::SelectProgramRequest {
        name: "part.nc".into(),
        dialect: String::new(),
    })
    .await
    .unwrap();
    let list = list_programs(&mut c).await;
    assert_eq!(list.selected, "part.nc");

    // Start and follow the status stream to the end.
    let mut stream = c
        .stream_status(pb::StatusRequest { rate_hz: 100 })
        .await
        .unwrap()
        .into_inner();
    let job = start_job(&mut c).await;
    let e = c.start(pb::StartRequest::default()).await.unwrap_err();
    assert_eq!(e.code(), Code::FailedPrecondition, "start while running");
    let e = c
        .load_program(named_program("x", PROGRAM))
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::FailedPrecondition, "load while running");
    let mut saw_g1 = false;
    let mut saw_junction = false;
    let t0 = Instant::now();
    loop {
        let s = stream.message().await.unwrap().unwrap();
        assert!(t0.elapsed() < tests::PATIENCE, "did not finish");
        if s.job == job && s.state == pb::MachineState::Running as i32 {
            assert_eq!(s.program, "part.nc");
            assert_eq!(s.mode, pb::Mode::Auto as i32);
            assert_eq!(s.blocks_total, 4);
            assert!(s.kr.is_some());
            assert!(s.ticks.unwrap().ticks > 0);
            if s.block == Some(20) {
                assert!(
                    s.modal_g_codes.contains(&"G1".to_string()),
                    "{:?}",
                    s.modal_g_codes
                );
                assert!(s.modal_g_codes.contains(&"G17".to_string()));
                assert_eq!(s.feed_mode, "G94");
                assert_eq!(s.feed_programmed, 1500.0);
                assert_eq!(s.compensation.as_ref().unwrap().code, "G40");
                saw_g1 = true;
            }
            saw_junction |= s.junction != pb::JunctionClass::Unspecified as i32;
        }
        if s.finished_job == job {
            assert_eq!(s.percent, 100.0);
            break;
        }
    }
    assert!(saw_g1, "status never showed block N20");
    assert!(saw_junction, "status never classified a junction");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn hold_resume_stop_override_reset() {
    let d = start(config(Role::Admin)).await;
    let mut c = MachineClient::new(d.channel().await);
    c.load_program(named_program("long.nc", LONG))
        .await
        .unwrap();
    let e = c
        .set_override(pb::SetOverrideRequest { percent: 151.0 })
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument);
    let e = c.reset(pb::ResetRequest {}).await.unwrap_err();
    assert_eq!(e.code(), Code::FailedPrecondition, "reset without a fault");

    let job = start_job(&mut c).await;
    wait_state(&d.ctl, MachineState::Running).await;
    c.set_override(pb::SetOverrideRequest { percent: 50.0 })
        .await
        .unwrap();
    wait_until("override 50 %", || {
        d.ctl.snapshot().operator.feed_override_pct == 50.0
    })
    .await;
    c.hold(pb::HoldRequest {}).await.unwrap();
    wait_until("held at rest", || {
        let s = d.ctl.snapshot();
        s.state == MachineState::Hold && s.axes.path_v_mm_s == 0.0
    })
    .await;
    let x_held = d.ctl.snapshot().axes.commanded[0];
    tokio::time::sleep(Duration::from_millis(200)).await;
    assert_eq!(
        d.ctl.snapshot().axes.commanded[0],
        x_held,
        "moved while held"
    );
    c.resume(pb::ResumeRequest {}).await.unwrap();
    wait_until("moving again", || {
        d.ctl.snapshot().axes.commanded[0] > x_held
    })
    .await;
    c.stop(pb::StopRequest {}).await.unwrap();
    wait_until("stopped", || {
        let s = d.ctl.snapshot();
        s.progress.aborted_job == job && s.state == MachineState::Idle
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn mdi_runs_one_block_and_keeps_the_selected_program() {
    let d = start(config(Role::Admin)).await;
    let mut c = MachineClient::new(d.channel().await);
    c.load_program(named_program("part.nc", PROGRAM))
        .await
        .unwrap();
    for bad in ["", "G1 X1 F100\nG1 X2", "G7 X1"] {
        let e = c.mdi(mdi_block(bad)).await.unwrap_err();
        assert_eq!(e.code(), Code::InvalidArgument, "{bad:?}");
    }
    let job = start_mdi(&mut c, "G1 X5 Y2 F3000").await;
    let mut stream = status_stream(&mut c).await;
    let s = stream.message().await.unwrap().unwrap();
    assert_eq!(s.mode, pb::Mode::Mdi as i32);
    assert_eq!(s.program, "MDI");
    wait_job_finished(&d.ctl, job).await;
    let s = d.ctl.snapshot();
    assert!((s.axes.commanded[0] - 5.0).abs() < 1e-6 && (s.axes.commanded[1] - 2.0).abs() < 1e-6);
    let list = list_programs(&mut c).await;
    assert_eq!(list.selected, "part.nc");
    // MDI while running is a wrong state.
    c.start(pb::StartRequest::default()).await.unwrap();
    let e = c.mdi(mdi_block("G1 X1 F100")).await.unwrap_err();
    assert_eq!(e.code(), Code::FailedPrecondition);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn single_block_holds_at_every_block() {
    let d = start(config(Role::Admin)).await;
    let mut c = MachineClient::new(d.channel().await);
    c.load_program(named_program(
        "sb.nc",
        "N10 G1 X5 F3000\nN20 G23 X10\nN30 X15\n",
    ))
    .await
    .unwrap();
    c.set_single_block(pb::SetSingleBlockRequest { enabled: true })
        .await
        .unwrap();
    let job = start_job(&mut c).await;
    let mut stops = Vec::new();
    for _ in 0..2 {
        wait_until("single-block hold", || {
            let s = d.ctl.snapshot();
            s.state == MachineState::Hold && s.axes.path_v_mm_s == 0.0
        })
        .await;
        let s = d.ctl.snapshot();
        assert!(s.operator.single_block);
        stops.push(s.axes.commanded[0]);
        c.resume(pb::ResumeRequest {}).await.unwrap();
        // (The next block may run and hold again between two polls on a busy machine: moved
        // on from this stop is left too.)
        let here = *stops.last().unwrap();
        // The reply comes once the resume is taken.
        let s = d.ctl.snapshot();
        assert!(s.state != MachineState::Hold || s.axes.commanded[0] > here + 1e-6);
        wait_until("left the hold", || {
            let s = d.ctl.snapshot();
            s.state != MachineState::Hold || s.axes.commanded[0] > here + 1e-6
        })
        .await;
    }
    wait_job_finished(&d.ctl, job).await;
    // Holds land exactly at the block ends (5 and 10).
    assert!((stops[0] - 5.0).abs() < 1e-6, "{stops:?}");
    assert!((stops[1] - 10.0).abs() < 1e-6, "{stops:?}");
    assert!((d.ctl.snapshot().axes.commanded[0] - 15.0).abs() < 1e-6);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn status_stream_rate_limits_and_deadline() {
    let mut cfg = config(Role::Admin);
    cfg.api.max_streams = 2;
    let d = start(cfg).await;
    let mut c = MachineClient::new(d.channel().await);
    let e = c
        .stream_status(pb::StatusRequest { rate_hz: 251 })
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument);
    let mut s1 = c
        .stream_status(pb::StatusRequest { rate_hz: 250 })
        .await
        .unwrap()
        .into_inner();
    let _s2 = c
        .stream_alarms(pb::StreamAlarmsRequest { skip_history: true })
        .await
        .unwrap()
        .into_inner();
    let e = c
        .stream_status(pb::StatusRequest { rate_hz: 10 })
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::ResourceExhausted);
    // 250 Hz is delivered.
    let t0 = Instant::now();
    let mut n = 0;
    while t0.elapsed() < Duration::from_secs(2) {
        s1.message().await.unwrap().unwrap();
        n += 1;
    }
    let rate = n as f64 / t0.elapsed().as_secs_f64();
    // Slower than asked only when the machine running the tests is loaded (missed ticks are
    // skipped): the bound is a liveness check, not a timing.
    assert!(rate > 60.0, "250 Hz stream delivered {rate:.0} Hz");
    // A closed stream frees its slot.
    drop(s1);
    wait_until("slot freed", || true).await;
    let t0 = Instant::now();
    loop {
        match c.stream_status(pb::StatusRequest { rate_hz: 10 }).await {
            Ok(_) => break,
            Err(e) => {
                assert_eq!(e.code(), Code::ResourceExhausted);
                assert!(t0.elapsed() < tests::PATIENCE, "slot never freed");
                tokio::time::sleep(Duration::from_millis(20)).await;
            }
        }
    }
    // Deadlines: a 1 µs deadline on a large program ends the call at once.
    let big: String = (0..200_000)
        .map(|i| format!("G1 X{} F1000\n", i % 100))
        .collect();
    let mut r = tonic::Request::new(pb::ValidateProgramRequest {
        text: big,
        dialect: String::new(),
    });
    r.set_timeout(Duration::from_micros(1));
    let e = c.validate_program(r).await.unwrap_err();
    // tonic reports its own expired deadline as CANCELLED ("Timeout expired"); other gRPC
    // stacks say DEADLINE_EXCEEDED. Either way the call ends at the deadline, not after the
    // work.
    assert!(
        matches!(e.code(), Code::DeadlineExceeded | Code::Cancelled),
        "{e:?}"
    );
}

async fn health(ch: &tonic::transport::Channel, svc: &str) -> i32 {
    use tonic_health::pb::HealthCheckRequest;
    use tonic_health::pb::health_client::HealthClient;
    HealthClient::new(ch.clone())
        .check(HealthCheckRequest {
            service: svc.into(),
        })
        .await
        .unwrap()
        .into_inner()
        .status
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn alarms_stream_with_history_and_health_follows_faults() {
    use tonic_health::pb::health_check_response::ServingStatus;
    let d = start(config(Role::Admin)).await;
    let ch = d.channel().await;
    let mut c = MachineClient::new(ch.clone());
    assert_eq!(health(&ch, "").await, ServingStatus::Serving as i32);
    assert_eq!(
        health(&ch, "cnc.v1.Machine").await,
        ServingStatus::Serving as i32
    );

    d.fault.store(true, Ordering::Relaxed);
    wait_state(&d.ctl, MachineState::Fault).await;
    let t0 = Instant::now();
    while health(&ch, "").await != ServingStatus::NotServing as i32 {
        assert!(t0.elapsed() < tests::PATIENCE, "health still SERVING");
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    // The alarm is in status.
    wait_until("active alarm", || true).await;
    let mut st = status_stream(&mut c).await;
    let t0 = Instant::now();
    loop {
        let s = st.message().await.unwrap().unwrap();
        if !s.active_alarms.is_empty() {
            assert!(
                s.active_alarms[0].message.contains("axis X"),
                "{:?}",
                s.active_alarms
            );
            assert_eq!(s.active_alarms[0].source, "drive");
            break;
        }
        assert!(t0.elapsed() < tests::PATIENCE);
    }
    drop(st);
    c.reset(pb::ResetRequest {}).await.unwrap();
    wait_state(&d.ctl, MachineState::Idle).await;
    let t0 = Instant::now();
    while health(&ch, "").await != ServingStatus::Serving as i32 {
        assert!(t0.elapsed() < tests::PATIENCE, "health not back");
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    // The alarm watcher (a task polling the controller) records the clear a moment after the
    // reset: once no alarm is active in the status, the history holds it.
    let mut st = status_stream(&mut c).await;
    let t0 = Instant::now();
    while !st
        .message()
        .await
        .unwrap()
        .unwrap()
        .active_alarms
        .is_empty()
    {
        assert!(t0.elapsed() < tests::PATIENCE, "alarm still active");
    }
    drop(st);
    // A stream opened afterwards gets the history: raised, then cleared.
    let mut a = c
        .stream_alarms(pb::StreamAlarmsRequest {
            skip_history: false,
        })
        .await
        .unwrap()
        .into_inner();
    let e1 = a.message().await.unwrap().unwrap();
    let e2 = a.message().await.unwrap().unwrap();
    assert!(e1.from_history && e1.active);
    assert!(e2.from_history && !e2.active);
    assert_eq!(e1.alarm.unwrap().id, e2.alarm.unwrap().id);
    // And live events after it.
    d.fault.store(true, Ordering::Relaxed);
    let e3 = tokio::time::timeout(tests::PATIENCE, a.message())
        .await
        .expect("no live alarm")
        .unwrap()
        .unwrap();
    assert!(e3.active && !e3.from_history);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn reflection_lists_the_services() {
    let d = start(config(Role::Admin)).await;
    let names = reflected_services!(v1, d.channel().await);
    for s in [
        "cnc.v1.Machine",
        "cnc.v1.Offsets",
        "cnc.v1.Plc",
        "cnc.v1.Constants",
        "cnc.v1.Preview",
        "grpc.health.v1.Health",
    ] {
        assert!(names.contains(&s.to_string()), "{s} missing from {names:?}");
    }
}

/// The offset entries in use (non-zero), as the API lists them.
async fn offsets_in_use(o: &mut OffsetsClient<tonic::transport::Channel>) -> pb::GetOffsetsReply {
    o.get_offsets(pb::GetOffsetsRequest {
        include_zero: false,
    })
    .await
    .unwrap()
    .into_inner()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn offsets_read_edit_replace_reload_and_g92_marking() {
    let d = start(config(Role::Admin)).await;
    let ch = d.channel().await;
    let mut o = OffsetsClient::new(ch.clone());
    let mut c = MachineClient::new(ch);
    let t = o
        .get_offsets(pb::GetOffsetsRequest { include_zero: true })
        .await
        .unwrap()
        .into_inner();
    assert_eq!(t.entries.len(), 99);
    assert_eq!(
        t.labels,
        ["R", "X", "Y", "Z", "4"],
        "3-axis mill: ordinal 4 has no axis"
    );

    // Operator edit: file and memory.
    let e = o
        .set_offset(pb::SetOffsetRequest {
            entry: 7,
            radius_mm: Some(2.5),
            length3_mm: Some(-10.25),
            ..Default::default()
        })
        .await
        .unwrap()
        .into_inner();
    assert_eq!(e.radius_mm, 2.5);
    assert_eq!(e.length_mm, [0.0, 0.0, -10.25, 0.0]);
    assert!(!e.changed_by_program);
    let file = o
        .get_offsets_file(pb::GetOffsetsFileRequest {})
        .await
        .unwrap()
        .into_inner()
        .text;
    assert!(file.contains("07: R=2.5"), "{file}");
    for bad in [
        pb::SetOffsetRequest {
            entry: 100,
            radius_mm: Some(1.0),
            ..Default::default()
        },
        pb::SetOffsetRequest {
            entry: 0,
            radius_mm: Some(1.0),
            ..Default::default()
        },
        pb::SetOffsetRequest {
            entry: 3,
            radius_mm: Some(1e6),
            ..Default::default()
        },
        pb::SetOffsetRequest {
            entry: 3,
            ..Default::default()
        },
    ] {
        let e = o.set_offset(bad).await.unwrap_err();
        assert_eq!(e.code(), Code::InvalidArgument, "{bad:?}");
    }

    // A program's G92 changes memory only: marked as changed by the program.
    let job = load_and_start(&mut c, "g92.nc", "N10 G92 D12 R0=4.0\nN20 G1 X1 F1000\n").await;
    wait_job_finished(&d.ctl, job).await;
    let t = offsets_in_use(&mut o).await;
    let e12 = t.entries.iter().find(|e| e.entry == 12).expect("entry 12");
    assert_eq!(e12.radius_mm, 4.0);
    assert!(e12.changed_by_program);
    let e7 = t.entries.iter().find(|e| e.entry == 7).unwrap();
    assert!(!e7.changed_by_program);

    // A refused file changes nothing.
    let e = o
        .replace_offsets_file(pb::OffsetsFile {
            text: "$KOR\n01: R=1.0\n01: R=2.0\n".into(),
            revision: String::new(),
        })
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument);
    assert_eq!(diagnostics(&e)[0].line, 3);
    let same = o
        .get_offsets_file(pb::GetOffsetsFileRequest {})
        .await
        .unwrap()
        .into_inner()
        .text;
    assert_eq!(same, file);

    // Reload drops the G92 change.
    let r = o
        .reload_offsets(pb::ReloadOffsetsRequest {})
        .await
        .unwrap()
        .into_inner();
    assert_eq!(r.entries, 1);
    let t = offsets_in_use(&mut o).await;
    assert!(t.entries.iter().all(|e| e.entry != 12));

    // Replace the whole file.
    let r = o
        .replace_offsets_file(pb::OffsetsFile {
            text: "tools\n$KOR\n01: R=1.0 Z=50\n02: R=0.5\n".into(),
            revision: String::new(),
        })
        .await
        .unwrap()
        .into_inner();
    assert_eq!(r.entries, 2);
    let t = offsets_in_use(&mut o).await;
    assert_eq!(t.entries.len(), 2);
    assert_eq!(t.entries[0].length_mm[2], 50.0);

    // Reload while a program runs: wrong state.
    load_and_start(&mut c, "long.nc", LONG).await;
    wait_state(&d.ctl, MachineState::Running).await;
    let e = o
        .reload_offsets(pb::ReloadOffsetsRequest {})
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::FailedPrecondition);
}

fn by_name(n: &str) -> pb::CellRef {
    pb::CellRef {
        cell: Some(pb::cell_ref::Cell::Name(n.into())),
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn plc_cells_by_name_and_address_with_units() {
    let d = start(config(Role::Admin)).await;
    let mut p = PlcClient::new(d.channel().await);
    let all = p
        .list_cells(pb::ListCellsRequest {})
        .await
        .unwrap()
        .into_inner();
    assert_eq!(all.cells.len(), 19);
    let v = &all.cells[0];
    assert_eq!((v.name.as_str(), v.address), ("AKRR_ACT_V", 0xA178));
    assert_eq!(v.unit, "mm/min");
    assert_eq!(v.access, pb::CellAccess::ReadOnly as i32);

    let w = p
        .write_cell(pb::WriteCellRequest {
            cell: Some(by_name("dynam_set")),
            value: 2,
        })
        .await
        .unwrap()
        .into_inner();
    assert_eq!((w.name.as_str(), w.value), ("DYNAM_SET", 2));
    let w = p
        .write_cell(pb::WriteCellRequest {
            cell: Some(pb::CellRef {
                cell: Some(pb::cell_ref::Cell::Address(0xA19C)),
            }),
            value: 90_000,
        })
        .await
        .unwrap()
        .into_inner();
    assert_eq!(w.name, "AKRR_V");
    // WriteCell returns once the RT thread has the value: in force from that tick on.
    assert_eq!(d.ctl.snapshot().plc.dynam_set(), 3);
    let r = p
        .read_cells(pb::ReadCellsRequest {
            cells: vec![
                by_name("AKRR_V"),
                pb::CellRef {
                    cell: Some(pb::cell_ref::Cell::Address(0xA1B0)),
                },
                by_name("AKRR_CNTR"),
            ],
        })
        .await
        .unwrap()
        .into_inner();
    let vals: Vec<(String, i64, String)> = r
        .cells
        .into_iter()
        .map(|c| (c.name, c.value, c.unit))
        .collect();
    assert_eq!(
        vals,
        [
            ("AKRR_V".into(), 90_000, "mm/min".into()),
            ("DYNAM_SET".into(), 2, "index".into()),
            ("AKRR_CNTR".into(), 0, "bits".into())
        ]
    );

    for (cell, value) in [
        (by_name("AKRR_ACT_S"), 1),
        (by_name("DYNAM_SET"), 4),
        (by_name("AKRR_SPEED"), 1),
        (
            pb::CellRef {
                cell: Some(pb::cell_ref::Cell::Address(0xA17A)),
            },
            1,
        ),
        (pb::CellRef { cell: None }, 1),
    ] {
        let e = p
            .write_cell(pb::WriteCellRequest {
                cell: Some(cell.clone()),
                value,
            })
            .await
            .unwrap_err();
        assert_eq!(e.code(), Code::InvalidArgument, "{cell:?}");
    }
    let e = p
        .read_cells(pb::ReadCellsRequest {
            cells: vec![by_name("NOPE")],
        })
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument);
    // The refused writes changed nothing.
    assert_eq!(d.ctl.snapshot().plc.read_by_name("DYNAM_SET"), Ok(2));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn constants_read_decades_write_and_refusals() {
    let d = start(config(Role::Admin)).await;
    let ch = d.channel().await;
    let mut k = ConstantsClient::new(ch.clone());
    let mut c = MachineClient::new(ch);
    let r = k
        .get_constants(pb::GetConstantsRequest { numbers: vec![95] })
        .await
        .unwrap()
        .into_inner();
    let r95 = &r.constants[0];
    assert_eq!(r95.number, 95);
    assert_eq!(r95.decades[7], 1, "8.R95 = 1");
    assert!(r95.is_default);
    let all = k
        .get_constants(pb::GetConstantsRequest { numbers: vec![] })
        .await
        .unwrap()
        .into_inner();
    assert!(all.constants.iter().any(|c| c.number == 39));

    let e = k
        .get_constants(pb::GetConstantsRequest {
            numbers: vec![1000],
        })
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument);
    for (n, v) in [(1000, 1.0), (39, 1e6), (39, f64::NAN)] {
        let e = k
            .set_constants(constant_values(&[(n, v)]))
            .await
            .unwrap_err();
        assert_eq!(e.code(), Code::InvalidArgument, "R{n}={v}");
    }
    let r = k
        .set_constants(constant_values(&[(39, 45.0), (2, 3.0)]))
        .await
        .unwrap()
        .into_inner();
    assert_eq!(r.restart_required, [2]);
    let r = k
        .get_constants(pb::GetConstantsRequest { numbers: vec![39] })
        .await
        .unwrap()
        .into_inner();
    assert_eq!(r.constants[0].value, 45.0);
    assert_eq!(r.constants[0].text, "00045.000");
    assert!(!r.constants[0].is_default);
    assert_eq!(r.constants[0].decades[3], 5, "units digit is decade 4");

    // Running: FAILED_PRECONDITION, nothing changes.
    load_and_start(&mut c, "long.nc", LONG).await;
    wait_state(&d.ctl, MachineState::Running).await;
    let e = k
        .set_constants(constant_values(&[(39, 30.0)]))
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::FailedPrecondition);
    assert_eq!(d.ctl.constants().get(39), 45.0);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn preview_data_paths_and_junctions() {
    let d = start(config(Role::Admin)).await;
    let ch = d.channel().await;
    let mut p = PreviewClient::new(ch.clone());
    let e = preview_data(&mut p, "", true).await.unwrap_err();
    assert_eq!(e.code(), Code::FailedPrecondition, "nothing selected");
    let e = preview_data(&mut p, "N10 G1 X10 F100\nN20 G7\n", true)
        .await
        .unwrap_err();
    assert_eq!(e.code(), Code::InvalidArgument);
    assert_eq!(diagnostics(&e)[0].block, Some(20));

    let text = "N10 G92 D1 R0=2\nN20 G0 X-10 Y0\nN30 G41 D1 G1 X0 Y0 F1000\nN40 Y20\nN50 G23 X20\nN60 Y0\nN70 G40 G0 X30 Y-10\n";
    let data = preview_data(&mut p, text, true).await.unwrap();
    assert_eq!(data.axes, ["X", "Y", "Z"]);
    assert_eq!(data.programmed.len(), 6);
    let n40p = data
        .programmed
        .iter()
        .find(|e| e.block == Some(40))
        .unwrap();
    let n40c = data
        .compensated
        .iter()
        .find(|e| e.block == Some(40))
        .unwrap();
    assert_eq!(n40p.start_mm[0], 0.0);
    assert!(
        (n40c.start_mm[0] + 2.0).abs() < 1e-6,
        "G41 r=2: tool left of +Y is at X-2: {n40c:?}"
    );
    assert!(!data.junctions.is_empty());
    assert!(
        data.junctions
            .iter()
            .any(|j| j.class == pb::JunctionClass::Stop as i32)
    );
    // Without junctions: paths only.
    let data = preview_data(&mut p, text, false).await.unwrap();
    assert!(data.junctions.is_empty());
}

/// A velocity plot's work grows with the motion's duration, not with its text: it stops at
/// `[api] velocity_plot_max_h` with a `preview_plot_cut` note (here 10 s of a rapid that
/// would run for hours), two asked at once both answer (one after the other), and a plot
/// within the bound has no note.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn velocity_plot_stops_at_its_bound_of_machining_time() {
    let mut cfg = config(Role::Admin);
    cfg.api.velocity_plot_max_h = 10.0 / 3600.0;
    let d = start(cfg).await;
    let p = PreviewClient::new(d.channel().await);
    let req = |text: &str| pb::GetPreviewRequest {
        text: text.into(),
        format: pb::ImageFormat::Svg as i32,
        velocity: true,
        ..Default::default()
    };
    let far = req("N10 G0 X0 Y0\nN20 G0 Y8888888\n");
    let (mut p1, mut p2) = (p.clone(), p.clone());
    let (a, b) = tokio::join!(p1.get_preview(far.clone()), p2.get_preview(far.clone()));
    for r in [a, b] {
        let r = r.expect("a cut plot is an answer").into_inner();
        let cut: Vec<_> = r
            .diagnostics
            .iter()
            .filter(|d| d.code == "preview_plot_cut")
            .collect();
        assert_eq!(cut.len(), 1, "{:?}", r.diagnostics);
        assert_eq!(cut[0].block, Some(20));
        assert_eq!(cut[0].severity, pb::Severity::Info as i32);
        let svg = String::from_utf8(r.image).unwrap();
        assert!(svg.contains(".. 10.00 s"), "the plot ends at the bound");
    }
    let near = p1
        .get_preview(req("N10 G0 X0 Y0\nN20 G1 Y10 F600\n"))
        .await
        .unwrap()
        .into_inner();
    assert!(
        near.diagnostics
            .iter()
            .all(|d| d.code != "preview_plot_cut")
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn preview_picture_svg_png_velocity_and_refusals() {
    let d = start(config(Role::Admin)).await;
    let mut p = PreviewClient::new(d.channel().await);
    let text = "N10 G0 X0 Y0\nN20 G1 X10 F600\nN30 Y10\nN40 G23 X20\nN50 Y20\n";
    let req =
        |format: pb::ImageFormat, plane: &str, page: u32, velocity: bool| pb::GetPreviewRequest {
            text: text.into(),
            format: format as i32,
            plane: plane.into(),
            page,
            velocity,
            width_px: 0,
            height_px: 0,
            dialect: String::new(),
        };
    let svg = p
        .get_preview(req(pb::ImageFormat::Svg, "", 0, false))
        .await
        .unwrap()
        .into_inner();
    assert!(svg.image.starts_with(b"<svg"));
    assert_eq!((svg.page, svg.pages), (1, 1));
    // G98 blocks stop at their ends: N20 (and N10, a rapid) are red.
    assert!(
        svg.red
            .iter()
            .any(|r| r.block == Some(20) && r.class == pb::JunctionClass::Stop as i32),
        "{:?}",
        svg.red
    );
    assert_eq!(svg.red_junctions as usize, svg.red.len());
    let png = p
        .get_preview(req(pb::ImageFormat::Png, "xz", 1, false))
        .await
        .unwrap()
        .into_inner();
    assert!(png.image.starts_with(b"\x89PNG"));
    let v = p
        .get_preview(req(pb::ImageFormat::Svg, "xy", 1, true))
        .await
        .unwrap()
        .into_inner();
    assert!(
        String::from_utf8(v.image)
            .unwrap()
            .contains("class=\"speed\"")
    );
    for (plane, page) in [("ab", 1), ("xy", 9)] {
        let e = p
            .get_preview(req(pb::ImageFormat::Svg, plane, page, false))
            .await
            .unwrap_err();
        assert_eq!(e.code(), Code::InvalidArgument, "{plane} {page}");
    }
    let mut bad = req(pb::ImageFormat::Svg, "", 1, false);
    bad.text = "N10 G7\n".into();
    let e = p.get_preview(bad).await.unwrap_err();
    assert_eq!(diagnostics(&e)[0].block, Some(10));
}
