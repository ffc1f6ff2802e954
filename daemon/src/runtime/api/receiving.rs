//! An upload being received (issue #49): both upload doors (the streaming `Upload`, and
//! `UploadBegin` ... `UploadFinish`) start its validation with the first chunk, on a thread
//! of its own that reads the temporary file as the chunks are written (`runtime::arrival`),
//! so the verdict comes soon after the last chunk. The pass is the one every load makes
//! (`programs::prepare_by`, split over two threads by `split_pass`).
//!
//! At most [`ARRIVING_AT_ONCE`] uploads are validated as they arrive: each holds a thread
//! while it waits for its client, and a client may be slow. Beyond that an upload is validated
//! once its last chunk is in, as a whole, on the same kind of thread (it never waits then).

use std::io::BufReader;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

use tokio::sync::oneshot;
use tonic::Status;

use kernel::pipeline::Options;

use super::ApiState;
use super::programs::{Prepared, UploadName, prepare_by};
use crate::runtime::arrival::ArrivingReader;
use crate::runtime::controller::ControlError;
use crate::runtime::library::{FileLines, ProgramText, Upload};
use crate::runtime::program_text::READ_BUFFER_BYTES;
use crate::runtime::split_pass;

/// Uploads validated while they arrive, at most (the rest: after their last chunk).
pub const ARRIVING_AT_ONCE: usize = 2;

/// Validations running while their upload arrives.
static ARRIVING: AtomicUsize = AtomicUsize::new(0);

type Verdict = Result<Prepared, ControlError>;

/// Sees the blocks validated so far.
type Progress = Box<dyn FnMut(u32) + Send>;

/// An upload being received.
pub struct Receiving {
    pub up: Upload,
    name: UploadName,
    validation: Validation,
}

enum Validation {
    /// Running as the upload arrives.
    Arriving(oneshot::Receiver<Verdict>),
    /// To start once the upload is complete.
    AtTheEnd(Progress),
}

/// Starts receiving `up` (its name and the dialect chosen). `progress` sees the blocks
/// validated so far.
pub fn receiving(
    st: &Arc<ApiState>,
    name: UploadName,
    up: Upload,
    progress: impl FnMut(u32) + Send + 'static,
) -> Result<Receiving, Status> {
    let progress: Progress = Box::new(progress);
    // (The fuzz rig validates at the end, on its own thread: `fuzz_rig::inline_threads`.)
    let taken = !super::fuzz_rig::inline_threads()
        && ARRIVING
            .fetch_update(Ordering::AcqRel, Ordering::Acquire, |n| {
                (n < ARRIVING_AT_ONCE).then_some(n + 1)
            })
            .is_ok();
    let validation = if taken {
        Validation::Arriving(start(st, &name, &up, progress, Some(ArrivingSlot))?)
    } else {
        Validation::AtTheEnd(progress)
    };
    Ok(Receiving {
        up,
        name,
        validation,
    })
}

impl Receiving {
    /// Every byte has arrived: the upload, its name and the verdict on it.
    pub async fn verdict(
        self,
        st: &Arc<ApiState>,
    ) -> Result<(Upload, UploadName, Verdict), Status> {
        let Receiving {
            up,
            name,
            validation,
        } = self;
        up.complete();
        let verdict = match validation {
            Validation::Arriving(v) => v,
            Validation::AtTheEnd(progress) => start(st, &name, &up, progress, None)?,
        };
        let v = verdict
            .await
            .map_err(|_| Status::internal("the upload's validation ended without a verdict"))?;
        Ok((up, name, v))
    }

    /// An upload whose validation never comes (tests of what holds it).
    #[cfg(test)]
    pub fn without_validation(up: Upload) -> Receiving {
        Receiving {
            up,
            name: (String::new(), None),
            validation: Validation::AtTheEnd(Box::new(|_| {})),
        }
    }
}

/// One of the [`ARRIVING_AT_ONCE`] places, given back when its validation ends.
struct ArrivingSlot;

impl Drop for ArrivingSlot {
    fn drop(&mut self) {
        ARRIVING.fetch_sub(1, Ordering::AcqRel);
    }
}

/// The validation of `up` on a thread of its own, reading the file as it arrives.
fn start(
    st: &Arc<ApiState>,
    name: &UploadName,
    up: &Upload,
    progress: Progress,
    slot: Option<ArrivingSlot>,
) -> Result<oneshot::Receiver<Verdict>, Status> {
    // The temporary file is renamed into place by the commit: this handle stays the program.
    let file = Arc::new(up.reopen().map_err(|e| Status::internal(e.to_string()))?);
    let reader = ArrivingReader::new(file.clone(), up.arrival());
    let dialect = st.ctl.dialect_of(&name.0, name.1);
    let (tx, verdict) = oneshot::channel();
    let (s, n) = (st.clone(), name.0.clone());
    let validate = move || {
        let _slot = slot;
        let text = ProgramText::File(file);
        let r = prepare_by(&s, &n, text, dialect, progress, |setup, obs| {
            let buffered = BufReader::with_capacity(READ_BUFFER_BYTES, reader);
            let lines = FileLines::new(buffered).with_encoding(setup.program().encoding);
            split_pass::validate_lines(lines, setup, Options::default(), obs)
        });
        let _ = tx.send(r);
    };
    if super::fuzz_rig::inline_threads() {
        validate();
        return Ok(verdict);
    }
    std::thread::Builder::new()
        .name("cnc-upload".into())
        .stack_size(crate::runtime::rt::THREAD_STACK_BYTES)
        .spawn(validate)
        .map_err(|e| Status::internal(format!("no thread for the upload's validation: {e}")))?;
    Ok(verdict)
}
