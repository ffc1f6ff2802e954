//! The MTConnect agent through HTTP while programs run on the simulated machine (issue #33):
//! positions and Execution follow the program, a `/sample` stream over a whole run has
//! contiguous sequences and ends where the status stream ends, a following error is a Fault
//! CONDITION on its axis until reset, a restart changes `instanceId`, tools are assets, and
//! bad requests get MTConnectError documents. Every document received is saved for the
//! schema check of `tests/mtconnect/run.sh`.

mod mtconnect_common;

use daemon::runtime::mtconnect::MtconnectConfig;
use daemon::runtime::rt::MachineState;
use mtconnect_common::*;
use proto::v1 as pb;
use proto::v1::machine_client::MachineClient;
use proto::v1::offsets_client::OffsetsClient;

async fn load_and_start(m: &mut MachineClient<tonic::transport::Channel>, text: &str) -> u32 {
    m.load_program(pb::LoadProgramRequest {
        name: "part.nc".into(),
        text: text.into(),
    })
    .await
    .unwrap();
    m.start(pb::StartRequest::default())
        .await
        .unwrap()
        .into_inner()
        .job
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn probe_describes_the_machine_and_current_follows_a_program() {
    let d = start(tests::test_config(), MtconnectConfig::default()).await;
    let c = d.client("follows_a_program");
    let probe = c.get("/probe").await;
    assert_eq!(probe.status, 200);
    assert!(probe.content_type.contains("xml"));
    let p = parse(&probe.body);
    assert_eq!(p.root, "MTConnectDevices");
    for axis in ["X", "Y", "Z"] {
        assert!(
            p.elements
                .iter()
                .any(|(n, a, _)| n == "Linear" && a.get("name").map(String::as_str) == Some(axis)),
            "no Linear {axis}: {}",
            probe.body
        );
    }
    let cur = parse(&c.get("/current").await.body);
    assert_eq!(cur.one("exec").text, "READY");
    assert_eq!(cur.one("avail").text, "AVAILABLE");
    assert_eq!(cur.one("x_cond").element, "Normal");

    let mut m = MachineClient::new(d.grpc.clone());
    let job = load_and_start(&mut m, "N10 G1 X30 Y-20 F1500\nN20 G1 X60 Y0\n").await;
    let running = wait_current(&c, "/current", "Execution ACTIVE", |d| {
        d.one("exec").text == "ACTIVE"
    })
    .await;
    assert_eq!(running.one("program").text, "part.nc");
    tests::wait_job_finished(&d.ctl, job).await;
    let done = wait_current(&c, "/current", "Execution PROGRAM_COMPLETED", |d| {
        d.one("exec").text == "PROGRAM_COMPLETED" && (d.one("x_act").number() - 60.0).abs() < 0.01
    })
    .await;
    assert!(
        (done.one("y_act").number()).abs() < 0.01,
        "{:?}",
        done.one("y_act")
    );
    assert!((done.one("x_cmd").number() - 60.0).abs() < 1e-6);
    // A path filter: only X's data items.
    let x = parse(
        &c.get("/current?path=//Linear%5B@name=%22X%22%5D")
            .await
            .body,
    );
    assert!(
        x.obs.iter().all(|o| o.id().starts_with("x_")),
        "{:?}",
        x.obs
    );
    assert_eq!(x.obs.len(), 3);
    // `at`: the state as of an earlier sequence shows READY (before the start).
    let first = cur.header_u64("lastSequence");
    let then = parse(&c.get(&format!("/current?at={first}")).await.body);
    assert_eq!(then.one("exec").text, "READY");
    d.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_sample_stream_over_a_run_is_contiguous_and_ends_where_the_status_ends() {
    let d = start(tests::test_config(), MtconnectConfig::default()).await;
    let c = d.client("sample_stream");
    let from = parse(&c.get("/current").await.body).header_u64("nextSequence");
    let mut parts = c
        .stream(&format!(
            "/sample?from={from}&interval=50&heartbeat=500&count=1000"
        ))
        .await;
    let mut m = MachineClient::new(d.grpc.clone());
    let job = load_and_start(
        &mut m,
        "N10 G1 X25 Y15 Z-5 F2400\nN20 G1 X-10 Y40\nN30 G1 X5 Y5 Z0\n",
    )
    .await;
    let mut expected = from;
    let mut last = std::collections::HashMap::new();
    let mut saw_active = false;
    let mut completed = false;
    while !completed {
        let part = parts.next().await.expect("the stream ended");
        let mut doc = parse(&part);
        assert_eq!(doc.root, "MTConnectStreams", "{part}");
        // Documents group observations by component; the sequences of a part are contiguous.
        doc.obs.sort_by_key(Obs::sequence);
        for o in &doc.obs {
            assert_eq!(o.sequence(), expected, "a gap before {o:?}");
            expected += 1;
            match o.id() {
                id if id.ends_with("_act") => {
                    last.insert(id.to_string(), o.number());
                }
                "exec" if o.text == "ACTIVE" => saw_active = true,
                "exec" if o.text == "PROGRAM_COMPLETED" => completed = true,
                _ => {}
            }
        }
        assert_eq!(doc.header_u64("nextSequence"), expected, "nextSequence");
    }
    assert!(saw_active);
    tests::wait_job_finished(&d.ctl, job).await;
    // At rest (the drives settle on their setpoints after the job's end): the stream's last
    // positions are the status stream's.
    let mut status = m
        .stream_status(pb::StatusRequest { rate_hz: 50 })
        .await
        .unwrap()
        .into_inner();
    let settled = loop {
        let s = status.message().await.unwrap().unwrap();
        if s.axes
            .iter()
            .all(|a| (a.actual_mm - a.commanded_mm).abs() < 1e-7)
        {
            break s;
        }
    };
    let want: Vec<f64> = settled.axes.iter().map(|a| a.actual_mm).collect();
    let t0 = std::time::Instant::now();
    while ["x_act", "y_act", "z_act"]
        .iter()
        .zip(&want)
        .any(|(id, w)| (last[*id] - w).abs() > 1e-6)
    {
        assert!(
            t0.elapsed() < tests::PATIENCE,
            "stream {last:?}, status {want:?}"
        );
        let mut doc = parse(&parts.next().await.expect("the stream ended"));
        doc.obs.sort_by_key(Obs::sequence);
        for o in &doc.obs {
            assert_eq!(o.sequence(), expected);
            expected += 1;
            if o.id().ends_with("_act") {
                last.insert(o.id().to_string(), o.number());
            }
        }
    }
    let x_status = want[0];
    assert!((x_status - 5.0).abs() < 0.01, "{x_status}");
    d.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_following_error_is_a_fault_condition_on_its_axis_until_reset() {
    let mut cfg = tests::test_config();
    // As in daemon_safety: a 5 mm window that X leaves at about 150 mm/s.
    cfg.sim.following_window_mm = 5.0;
    let d = start(cfg, MtconnectConfig::default()).await;
    let c = d.client("following_error");
    let mut m = MachineClient::new(d.grpc.clone());
    load_and_start(&mut m, "N10 S1000 M3\nN20 G1 X1000 Y200 F12000\n").await;
    let f = wait_current(&c, "/current", "the Fault", |d| {
        d.of("x_cond").iter().any(|o| o.element == "Fault")
    })
    .await;
    let fault = f
        .of("x_cond")
        .into_iter()
        .find(|o| o.element == "Fault")
        .unwrap()
        .clone();
    assert_eq!(fault.attrs["nativeCode"], "following_error");
    assert_eq!(fault.attrs["type"], "ACTUATOR");
    assert!(fault.text.contains("axis X"), "{fault:?}");
    assert_eq!(f.one("y_cond").element, "Normal");
    assert_eq!(f.one("estop").text, "TRIGGERED");
    assert_eq!(f.one("exec").text, "STOPPED");
    // Only the fault's component when filtered by conditions.
    let conds = parse(
        &c.get("/current?path=//DataItem%5B@category=%22CONDITION%22%5D")
            .await
            .body,
    );
    assert!(conds.obs.iter().all(|o| o.id().ends_with("_cond")
        || ["ctrl_system", "ctrl_comms", "motion", "logic"].contains(&o.id())));
    // Reset takes once the healthy axes are at rest and the drives in their safe state.
    let t0 = std::time::Instant::now();
    while d.ctl.snapshot().state != MachineState::Idle {
        assert!(t0.elapsed() < tests::PATIENCE, "reset never took");
        m.reset(pb::ResetRequest {}).await.unwrap();
        tokio::time::sleep(std::time::Duration::from_millis(200)).await;
    }
    let n = wait_current(&c, "/current", "Normal after reset", |d| {
        d.one("x_cond").element == "Normal"
    })
    .await;
    assert_eq!(n.one("estop").text, "ARMED");
    // The history keeps both: the Fault and the Normal with its code.
    let s = parse(&c.get("/sample?path=//Linear%5B@name=%22X%22%5D//DataItem%5B@type=%22ACTUATOR%22%5D&count=100").await.body);
    let levels: Vec<&str> = s.obs.iter().map(|o| o.element.as_str()).collect();
    assert!(levels.ends_with(&["Fault", "Normal"]), "{levels:?}");
    d.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_restart_changes_the_instance_id_and_restarts_the_sequences() {
    let cfg = tests::test_config();
    let d = start(cfg.clone(), MtconnectConfig::default()).await;
    let c = d.client("restart");
    let h1 = parse(&c.get("/current").await.body).header;
    d.stop().await;
    let d = start(cfg, MtconnectConfig::default()).await;
    let c = d.client("restart");
    let h2 = parse(&c.get("/current").await.body).header;
    assert_ne!(h1["instanceId"], h2["instanceId"]);
    assert_eq!(h2["firstSequence"], "1");
    d.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_offset_table_is_tool_assets_and_a_change_is_asset_changed() {
    let d = start(tests::test_config(), MtconnectConfig::default()).await;
    let c = d.client("assets");
    let mut o = OffsetsClient::new(d.grpc.clone());
    o.set_offset(pb::SetOffsetRequest {
        entry: 3,
        radius_mm: Some(2.5),
        length3_mm: Some(120.0),
        ..Default::default()
    })
    .await
    .unwrap();
    let cur = wait_current(&c, "/current", "AssetChanged T03", |d| {
        d.one("asset_chg").text == "T03"
    })
    .await;
    assert_eq!(cur.one("asset_chg").attrs["assetType"], "CuttingTool");
    let a = parse(&c.get("/assets").await.body);
    assert_eq!(a.root, "MTConnectAssets");
    let tool = a
        .elements
        .iter()
        .find(|(n, _, _)| n == "CuttingTool")
        .expect("a CuttingTool");
    assert_eq!(tool.1["assetId"], "T03");
    let diameter = a
        .elements
        .iter()
        .find(|(n, _, _)| n == "CuttingDiameterMax")
        .unwrap();
    assert_eq!(diameter.2.trim(), "5");
    let length = a
        .elements
        .iter()
        .find(|(n, _, _)| n == "FunctionalLength")
        .unwrap();
    assert_eq!((length.1["code"].as_str(), length.2.trim()), ("LFZ", "120"));
    let one = c.get("/asset/T03").await;
    assert_eq!(one.status, 200);
    d.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_requests_get_mtconnect_error_documents() {
    let d = start(tests::test_config(), MtconnectConfig::default()).await;
    let c = d.client("errors");
    let next = parse(&c.get("/current").await.body).header_u64("nextSequence");
    let cases = [
        (format!("/sample?from={}", next + 1000), 400, "OUT_OF_RANGE"),
        ("/sample?count=0".to_string(), 400, "OUT_OF_RANGE"),
        ("/sample?count=many".to_string(), 400, "INVALID_REQUEST"),
        ("/current?at=0".to_string(), 400, "OUT_OF_RANGE"),
        ("/current?path=//Turret".to_string(), 400, "INVALID_PATH"),
        ("/current?path=Linear".to_string(), 400, "INVALID_PATH"),
        ("/current?frequency=1".to_string(), 400, "INVALID_REQUEST"),
        ("/lathe2/probe".to_string(), 404, "NO_DEVICE"),
        ("/cncd/status".to_string(), 404, "INVALID_URI"),
        ("/asset/T42".to_string(), 404, "ASSET_NOT_FOUND"),
    ];
    for (path, status, code) in cases {
        let r = c.get(&path).await;
        assert_eq!(r.status, status, "{path}: {}", r.body);
        let doc = parse(&r.body);
        assert_eq!(doc.root, "MTConnectError", "{path}");
        assert_eq!(doc.error_code.as_deref(), Some(code), "{path}: {}", r.body);
    }
    let r = c.request("POST", "/current").await;
    assert_eq!(parse(&r.body).error_code.as_deref(), Some("UNSUPPORTED"));
    // The device's own name is accepted.
    assert_eq!(c.get("/cncd/current").await.status, 200);
    d.stop().await;
}
