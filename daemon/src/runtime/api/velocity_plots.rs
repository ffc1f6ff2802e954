//! The velocity plots `GetPreview` draws (`velocity = true`): their work grows with the
//! program's machining time rather than its text, so they are computed one at a time (a
//! second request waits, holding no thread) and stop at a bound of machining time
//! (`[api] velocity_plot_max_h`, 8 h by default; past it the reply carries
//! `preview_plot_cut`).

use std::sync::Arc;

use tokio::sync::{OwnedSemaphorePermit, Semaphore};
use tonic::Status;

pub struct VelocityPlots {
    one_at_a_time: Arc<Semaphore>,
    max_ticks: u64,
}

impl VelocityPlots {
    pub fn new(max_ticks: u64) -> Self {
        VelocityPlots {
            one_at_a_time: Arc::new(Semaphore::new(1)),
            max_ticks,
        }
    }

    /// Waits for the plot before to finish (the client's deadline still ends the wait). The
    /// plot's blocking work holds the turn: a client that goes away frees it only when that
    /// work ends.
    pub async fn turn(&self) -> Result<OwnedSemaphorePermit, Status> {
        self.one_at_a_time
            .clone()
            .acquire_owned()
            .await
            .map_err(|_| Status::unavailable("cncd is shutting down"))
    }

    /// Ticks a plot interpolates at most.
    pub fn max_ticks(&self) -> u64 {
        self.max_ticks
    }
}
