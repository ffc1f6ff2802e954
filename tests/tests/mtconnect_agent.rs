//! The MTConnect agent through HTTP while programs run on the simulated machine (issue #33):
//! positions and Execution follow the program, a `/sample` stream over a whole run has
//! contiguous sequences and ends where the status stream ends, a following error is a Fault
//! CONDITION on its axis until reset, a restart changes `instanceId`, tools are assets, and
//! bad requests get MTConnectError documents. The machine's I/O: the e-stop chain drives
//! EmergencyStop, the door DoorState, M8/M9 the coolant's PowerState, a limit switch is a Fault
//! of its axis's travel condition and an alarm input a Warning with its message. Every
//! document received is saved for the schema check of `tests/mtconnect/run.sh`.

mod mtconnect_common;

use daemon::runtime::config::{AlarmSeverity, InputConfig, InputFunction, IoSection};
use daemon::runtime::controller::Controller;
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
        dialect: String::new(),
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
    let cur = wait_current(&c, "/current", "the first values", |d| {
        known(d, &["exec", "avail", "x_cond"])
    })
    .await;
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
    // Actual, commanded, ACTUATOR and the travel condition (its limit switches).
    assert_eq!(x.obs.len(), 4);
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
        || o.id().ends_with("_travel")
        || ["ctrl_system", "ctrl_comms", "motion", "logic"].contains(&o.id())));
    // Reset takes once the healthy axes are at rest and the drives in their safe state; a
    // Reset that lands while the drives are still enabling is refused (no fault left).
    reset_to_idle(&d.ctl, &mut m).await;
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

/// Resets until the machine is idle (Reset takes once the axes are at rest and the drives in
/// their safe state; it is refused until the RT core has read a closed e-stop chain).
async fn reset_to_idle(ctl: &Controller, m: &mut MachineClient<tonic::transport::Channel>) {
    let t0 = std::time::Instant::now();
    while ctl.snapshot().state != MachineState::Idle {
        assert!(t0.elapsed() < tests::PATIENCE, "reset never took");
        if let Err(e) = m.reset(pb::ResetRequest {}).await {
            assert_eq!(e.code(), tonic::Code::FailedPrecondition, "{e:?}");
        }
        tokio::time::sleep(std::time::Duration::from_millis(200)).await;
    }
}

/// The active conditions (Warning, Fault) of `id` in a `/current`.
fn active<'a>(d: &'a Doc, id: &str) -> Vec<&'a Obs> {
    d.of(id)
        .into_iter()
        .filter(|o| o.element != "Normal")
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_e_stop_chain_drives_emergency_stop_and_the_door_door_state() {
    let d = start(tests::test_config(), MtconnectConfig::default()).await;
    let c = d.client("io_estop_door");
    let probe = parse(&c.get("/probe").await.body);
    for el in ["Door", "Systems", "Coolant"] {
        assert!(probe.elements.iter().any(|(n, _, _)| n == el), "no {el}");
    }
    let cur = wait_current(&c, "/current", "the I/O items", |d| {
        known(d, &["estop", "door_state", "ctrl_system"])
    })
    .await;
    assert_eq!(cur.one("estop").text, "ARMED");
    assert_eq!(cur.one("door_state").text, "CLOSED");
    assert_eq!(cur.one("ctrl_system").element, "Normal");

    // The chain opens: TRIGGERED, and the fault stop's Fault with its stable code.
    d.ctl.sim_set_input("estop", Some(false)).unwrap();
    let t = wait_current(&c, "/current", "EmergencyStop TRIGGERED", |d| {
        d.one("estop").text == "TRIGGERED" && !active(d, "ctrl_system").is_empty()
    })
    .await;
    let f = active(&t, "ctrl_system");
    assert_eq!(f.len(), 1, "{f:?}");
    assert_eq!(f[0].element, "Fault");
    assert_eq!(f[0].attrs["nativeCode"], "emergency_stop");
    assert!(f[0].text.contains("input estop"), "{f:?}");
    // Reset is refused while the chain is open: still TRIGGERED.
    let mut m = MachineClient::new(d.grpc.clone());
    let _ = m.reset(pb::ResetRequest {}).await;
    tokio::time::sleep(std::time::Duration::from_millis(300)).await;
    assert_eq!(
        parse(&c.get("/current").await.body).one("estop").text,
        "TRIGGERED"
    );
    // Closed again and reset: ARMED, the condition Normal with its code.
    d.ctl.sim_set_input("estop", Some(true)).unwrap();
    reset_to_idle(&d.ctl, &mut m).await;
    let a = wait_current(&c, "/current", "EmergencyStop ARMED", |d| {
        d.one("estop").text == "ARMED" && d.one("ctrl_system").element == "Normal"
    })
    .await;
    assert_eq!(a.one("ctrl_system").attrs["nativeCode"], "emergency_stop");

    // The door.
    d.ctl.sim_set_input("door", Some(false)).unwrap();
    let o = wait_current(&c, "/current?path=//Door", "DoorState OPEN", |d| {
        d.one("door_state").text == "OPEN"
    })
    .await;
    assert_eq!(o.one("door_state").element, "DoorState");
    assert_eq!(o.obs.len(), 1);
    d.ctl.sim_set_input("door", Some(true)).unwrap();
    wait_current(&c, "/current", "DoorState CLOSED", |d| {
        d.one("door_state").text == "CLOSED"
    })
    .await;
    // The history: TRIGGERED then ARMED, OPEN then CLOSED.
    let s = parse(
        &c.get("/sample?path=//DataItem%5B@type=%22EMERGENCY_STOP%22%5D%7C//Door&count=100")
            .await
            .body,
    );
    let seen: Vec<&str> = s.obs.iter().map(|o| o.text.as_str()).collect();
    for w in ["TRIGGERED", "ARMED", "OPEN", "CLOSED"] {
        assert!(seen.contains(&w), "{w}: {seen:?}");
    }
    d.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn m8_and_m9_switch_the_coolant() {
    let d = start(tests::test_config(), MtconnectConfig::default()).await;
    let c = d.client("io_coolant");
    let cur = wait_current(&c, "/current", "the I/O items", |d| {
        known(d, &["coolant_state"])
    })
    .await;
    assert_eq!(cur.one("coolant_state").text, "OFF");
    assert_eq!(cur.one("coolant_state").attrs["subType"], "CONTROL");
    let mut m = MachineClient::new(d.grpc.clone());
    for (block, want) in [("M8", "ON"), ("M9", "OFF")] {
        let job = m
            .mdi(pb::MdiRequest {
                block: block.into(),
                dialect: String::new(),
            })
            .await
            .unwrap_or_else(|e| panic!("{block}: {e:?}"))
            .into_inner()
            .job;
        tests::wait_job_finished(&d.ctl, job).await;
        let doc = wait_current(&c, "/current?path=//Coolant", block, |d| {
            d.one("coolant_state").text == want
        })
        .await;
        assert_eq!(doc.one("coolant_state").element, "PowerState");
    }
    d.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_limit_switch_is_a_fault_of_its_axis_travel_until_released() {
    let d = start(tests::test_config(), MtconnectConfig::default()).await;
    let c = d.client("io_limit");
    let cur = wait_current(&c, "/current", "the I/O items", |d| known(d, &["x_travel"])).await;
    assert_eq!(cur.one("x_travel").element, "Normal");
    assert_eq!(cur.one("x_travel").attrs["type"], "POSITION");
    d.ctl.sim_set_input("x_limit_pos", Some(true)).unwrap();
    let f = wait_current(&c, "/current", "the limit switch's Fault", |d| {
        active(d, "x_travel").iter().any(|o| o.element == "Fault")
    })
    .await;
    let x = active(&f, "x_travel");
    assert_eq!(x.len(), 1, "{x:?}");
    assert_eq!(x[0].attrs["nativeCode"], "limit_switch");
    assert_eq!(x[0].attrs["qualifier"], "HIGH");
    assert!(x[0].text.contains("x_limit_pos"), "{x:?}");
    // Not an ACTUATOR fault as well: one alarm, one condition.
    assert!(active(&f, "x_cond").is_empty());
    assert_eq!(f.one("y_travel").element, "Normal");
    // Reset acknowledges the switch still reached: a Warning until it releases.
    let mut m = MachineClient::new(d.grpc.clone());
    reset_to_idle(&d.ctl, &mut m).await;
    let w = wait_current(&c, "/current", "the acknowledged switch's Warning", |d| {
        active(d, "x_travel").iter().any(|o| o.element == "Warning")
    })
    .await;
    assert_eq!(
        active(&w, "x_travel")[0].attrs["nativeCode"],
        "limit_switch"
    );
    d.ctl.sim_set_input("x_limit_pos", None).unwrap();
    wait_current(&c, "/current", "Normal once released", |d| {
        d.one("x_travel").element == "Normal"
    })
    .await;
    d.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_alarm_input_is_a_condition_with_its_message() {
    let mut cfg = tests::test_config();
    let mut io = IoSection::sim_default(&cfg.axes);
    let alarm = |name: &str, message: &str, severity| InputConfig {
        name: name.into(),
        function: InputFunction::Alarm,
        message: Some(message.into()),
        severity,
        ..io.inputs[0].clone()
    };
    let air = alarm("air", "air pressure low", AlarmSeverity::Warning);
    let lube = alarm("lube", "lubrication empty", AlarmSeverity::Fault);
    io.inputs.extend([air, lube]);
    cfg.io = Some(io);
    let d = start(cfg, MtconnectConfig::default()).await;
    let c = d.client("io_alarm");
    let cur = wait_current(&c, "/current", "the I/O items", |d| {
        known(d, &["machine_alarms"])
    })
    .await;
    assert_eq!(cur.one("machine_alarms").element, "Normal");
    assert_eq!(cur.one("machine_alarms").attrs["type"], "SYSTEM");

    d.ctl.sim_set_input("air", Some(true)).unwrap();
    let w = wait_current(&c, "/current", "the air alarm's Warning", |d| {
        !active(d, "machine_alarms").is_empty()
    })
    .await;
    let a = active(&w, "machine_alarms");
    assert_eq!(a.len(), 1, "{a:?}");
    assert_eq!(a[0].element, "Warning");
    assert_eq!(a[0].attrs["nativeCode"], "air");
    assert_eq!(a[0].text, "air pressure low");
    // A warning stops nothing.
    assert_eq!(w.one("estop").text, "ARMED");
    assert_eq!(w.one("exec").text, "READY");

    // A fault-severity input: a Fault of its own, and the fault stop's `input_alarm`.
    d.ctl.sim_set_input("lube", Some(true)).unwrap();
    let f = wait_current(&c, "/current", "the lube alarm's Fault", |d| {
        active(d, "machine_alarms").len() == 2 && !active(d, "ctrl_system").is_empty()
    })
    .await;
    let lube = active(&f, "machine_alarms")
        .into_iter()
        .find(|o| o.attrs["nativeCode"] == "lube")
        .unwrap();
    assert_eq!(
        (lube.element.as_str(), lube.text.as_str()),
        ("Fault", "lubrication empty")
    );
    let stop = active(&f, "ctrl_system");
    assert_eq!(stop[0].attrs["nativeCode"], "input_alarm");
    assert!(stop[0].text.contains("lubrication empty"), "{stop:?}");

    // Inactive again: Normal with each code; Reset clears the fault stop.
    d.ctl.sim_set_input("air", None).unwrap();
    d.ctl.sim_set_input("lube", None).unwrap();
    let mut m = MachineClient::new(d.grpc.clone());
    reset_to_idle(&d.ctl, &mut m).await;
    wait_current(&c, "/current", "Normal", |d| {
        d.one("machine_alarms").element == "Normal" && d.one("ctrl_system").element == "Normal"
    })
    .await;
    let s = parse(
        &c.get("/sample?path=//DataItem%5B@id=%22machine_alarms%22%5D&count=100")
            .await
            .body,
    );
    let normals: Vec<&str> = s
        .obs
        .iter()
        .filter(|o| o.element == "Normal")
        .filter_map(|o| o.attrs.get("nativeCode").map(String::as_str))
        .collect();
    assert!(
        normals.contains(&"air") && normals.contains(&"lube"),
        "{normals:?}"
    );
    d.stop().await;
}

/// The agent has its first values of `ids` (a document fetched right after start may still
/// show UNAVAILABLE while the feed takes its first snapshot).
fn known(d: &Doc, ids: &[&str]) -> bool {
    ids.iter().all(|id| {
        d.of(id)
            .iter()
            .all(|o| o.text != "UNAVAILABLE" && o.element != "Unavailable")
    })
}
