//! The open status and alarm streams: how many a caller may hold (`api.max_streams`, of which
//! `api.reserved_streams` only operators and admins) and their end at shutdown.

use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

use tonic::Status;

use crate::runtime::config::Role;

/// Stream slots in use and the shutdown signal every stream task watches.
pub(super) struct StreamBudget {
    streams: Arc<AtomicUsize>,
    observer_streams: Arc<AtomicUsize>,
    max_streams: usize,
    reserved_streams: usize,
    /// Set once the daemon shuts down: every open stream sends its last message and ends.
    closing: tokio::sync::watch::Sender<bool>,
}

impl StreamBudget {
    /// `reserved_streams` is kept below `max_streams`, so an observer always has one slot.
    pub(super) fn new(max_streams: usize, reserved_streams: usize) -> StreamBudget {
        StreamBudget {
            streams: Arc::new(AtomicUsize::new(0)),
            observer_streams: Arc::new(AtomicUsize::new(0)),
            max_streams,
            reserved_streams: reserved_streams.min(max_streams - 1),
            closing: tokio::sync::watch::Sender::new(false),
        }
    }

    /// Takes one stream slot for a caller of `role`, or RESOURCE_EXHAUSTED. Observers
    /// (tokenless loopback clients, dashboards) hold at most `max_streams - reserved_streams`
    /// streams, so they cannot lock the operator's status out; operators and admins may use
    /// every slot.
    pub(super) fn slot(&self, role: Role) -> Result<StreamSlot, Status> {
        let observer = role < Role::Operator;
        let total = self.streams.fetch_add(1, Ordering::AcqRel);
        let observers = if observer {
            self.observer_streams.fetch_add(1, Ordering::AcqRel)
        } else {
            0
        };
        let observer_limit = self.max_streams - self.reserved_streams;
        let slot = StreamSlot {
            total: self.streams.clone(),
            observers: observer.then(|| self.observer_streams.clone()),
        };
        let refusal = if total >= self.max_streams {
            format!(
                "{total} streams are open, the limit is {} (api.max_streams)",
                self.max_streams
            )
        } else if observer && observers >= observer_limit {
            format!(
                "{observers} observer streams are open, the limit for observers is \
                 {observer_limit}: {} of api.max_streams ({}) are reserved for operator and \
                 admin callers (api.reserved_streams)",
                self.reserved_streams, self.max_streams
            )
        } else {
            return Ok(slot);
        };
        drop(slot);
        tracing::warn!(role = role.name(), "stream refused: {refusal}");
        Err(Status::resource_exhausted(refusal))
    }

    /// Ends every open stream (shutdown).
    pub(super) fn close(&self) {
        self.closing.send_replace(true);
    }

    /// Resolves once [`StreamBudget::close`] was called (at once if it already was).
    pub(super) fn closing(&self) -> impl std::future::Future<Output = ()> + Send + 'static {
        let mut rx = self.closing.subscribe();
        async move {
            let _ = rx.wait_for(|c| *c).await;
        }
    }

    /// Open status and alarm streams.
    pub(super) fn open(&self) -> usize {
        self.streams.load(Ordering::Acquire)
    }
}

/// Releases a stream slot when the stream task ends.
pub(super) struct StreamSlot {
    total: Arc<AtomicUsize>,
    /// Set for an observer's stream.
    observers: Option<Arc<AtomicUsize>>,
}

impl Drop for StreamSlot {
    fn drop(&mut self) {
        self.total.fetch_sub(1, Ordering::AcqRel);
        if let Some(o) = &self.observers {
            o.fetch_sub(1, Ordering::AcqRel);
        }
    }
}
