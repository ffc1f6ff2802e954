//! `grpc.health.v1` follows the machine's state.

use std::sync::Arc;
use std::time::Duration;

use tonic_health::ServingStatus;
use tonic_health::server::HealthReporter;

use crate::runtime::controller::Controller;
use crate::runtime::rt::MachineState;

/// Keeps `grpc.health.v1` in step with the machine: NOT_SERVING while faulted (or when the
/// real-time thread has ended), SERVING otherwise.
pub(super) async fn health_watch(ctl: Arc<Controller>, reporter: HealthReporter) {
    let names = [
        "",
        "cnc.v1.Machine",
        "cnc.v1.Offsets",
        "cnc.v1.Plc",
        "cnc.v1.Constants",
        "cnc.v1.Preview",
        "cnc.v1.Trajectory",
        "cnc.v1.Programs",
    ];
    let mut last = None;
    let mut every = tokio::time::interval(Duration::from_millis(20));
    loop {
        every.tick().await;
        let s = ctl.snapshot().state;
        let serving = if matches!(s, MachineState::Fault | MachineState::Shutdown) {
            ServingStatus::NotServing
        } else {
            ServingStatus::Serving
        };
        if last != Some(serving) {
            for n in names {
                reporter.set_service_status(n, serving).await;
            }
            last = Some(serving);
        }
    }
}
