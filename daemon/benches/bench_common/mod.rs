//! What the API benches share: their knobs from the environment, the runtime they run on, and
//! the daemon's API served the way `cncd` serves it locally.

pub mod cyclic;

use std::future::Future;
use std::time::{Duration, Instant};

use daemon::runtime::controller::Controller;
use daemon::runtime::rt::MachineState;
use daemon::runtime::server;

/// The number in the environment variable `name` (a bench knob), else `default`.
pub fn env_number<T: std::str::FromStr>(name: &str, default: T) -> T {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// Runs `bench` on a multi-threaded tokio runtime with two workers (the target's two cores).
pub fn run<F: Future>(bench: F) -> F::Output {
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("tokio runtime");
    rt.block_on(bench)
}

/// Serves the API of `ctl` on its Unix socket, as `cncctl` and the shop's HMI reach cncd
/// (loopback TCP is observer-only), and waits until the drives are enabled (a hang bound of
/// 10 s). Returns the address for tonic, `unix:/path`. (`program_upload` runs the `cncd`
/// binary instead.)
#[allow(dead_code)]
pub async fn serve_unix(ctl: &std::sync::Arc<Controller>) -> String {
    let sock = ctl.config().storage.dir.join("cncd.sock");
    let listeners = server::Listeners {
        unix: Some(server::bind_unix(&sock, 0o600, None).expect("API socket")),
        ..server::Listeners::default()
    };
    tokio::spawn(server::serve_listeners(
        ctl.clone(),
        listeners,
        std::future::pending(),
    ));
    let t0 = Instant::now();
    while ctl.snapshot().state != MachineState::Idle {
        assert!(t0.elapsed() < Duration::from_secs(10), "drives not enabled");
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    format!("unix:{}", sock.display())
}

/// Loads and starts, over `ch` (an operator's channel), a program of `strokes` 100 mm strokes
/// in X at 50 mm/s (Y stepping, and Z with `with_z`) that keeps the machine moving through a
/// bench: the RT thread interpolates all along.
#[allow(dead_code)]
pub async fn start_strokes(ch: tonic::transport::Channel, strokes: usize, with_z: bool) {
    use proto::v1 as pb;
    let mut text = String::from("N1 G1 F3000 X0 Y0\n");
    for i in 0..strokes {
        let x = if i % 2 == 0 { 100 } else { 0 };
        let z = if with_z {
            format!(" Z{}", i % 3)
        } else {
            String::new()
        };
        text.push_str(&format!("N{} X{x} Y{}{z}\n", i + 2, i % 7));
    }
    let mut m = proto::v1::machine_client::MachineClient::new(ch);
    m.load_program(pb::LoadProgramRequest {
        name: "bench.nc".into(),
        text,
        dialect: String::new(),
    })
    .await
    .expect("bench program loads");
    m.start(pb::StartRequest::default())
        .await
        .expect("bench program starts");
}

/// One unary read of the API, the service by `i` (three in turn): PLC cells, the offset
/// table, the program list.
#[allow(dead_code)]
pub async fn unary_read(ch: tonic::transport::Channel, i: u64) -> bool {
    use proto::v1 as pb;
    match i % 3 {
        0 => proto::v1::plc_client::PlcClient::new(ch)
            .list_cells(pb::ListCellsRequest {})
            .await
            .is_ok(),
        1 => proto::v1::offsets_client::OffsetsClient::new(ch)
            .get_offsets(pb::GetOffsetsRequest::default())
            .await
            .is_ok(),
        _ => proto::v1::machine_client::MachineClient::new(ch)
            .list_programs(pb::ListProgramsRequest {})
            .await
            .is_ok(),
    }
}
