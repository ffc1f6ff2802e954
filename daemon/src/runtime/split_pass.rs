//! A validation pass over two threads (`kernel::pipeline::split`, issue #49): one interprets
//! the lines, the caller's compensates, plans and feeds the observer, with batches of the
//! interpreter's outputs between them through a bounded queue. The verdict and what the
//! observer sees are the serial pass's (the kernel's `pipeline_split` test holds it on every
//! corpus program); a million blocks validate in a little over half the time on two cores.
//!
//! A restart's pass, and a pass whose thread cannot be started, run serially.

use std::sync::mpsc::sync_channel;

use kernel::machine::MachineSetup;
use kernel::pipeline::split::{self, Checking, Interpreted, Interpreting};
use kernel::pipeline::{self, Observer, Options, Validation};
use kernel::program::Lines;

/// Outputs per hand-over (about 50 KB: in glibc's arena, below the threshold where every
/// buffer would be mapped and unmapped on its own).
const BATCH: usize = 128;

/// Batches on their way (beyond, the interpreter waits: memory stays bounded).
const QUEUED_BATCHES: usize = 4;

/// Texts below this size validate on the caller's thread (a thread costs more than it saves).
pub const SPLIT_MIN_BYTES: u64 = 256 << 10;

/// The pipeline's verdict on `lines` (as `kernel::pipeline::validate_lines_into`), the
/// interpreter on a thread of its own.
pub fn validate_lines<L: Lines + Send>(
    lines: L,
    setup: &MachineSetup,
    opts: Options,
    inner: &mut impl Observer,
) -> Validation {
    let front = match Interpreting::new(lines, setup, opts) {
        Ok(front) => front,
        Err(lines) => return pipeline::validate_lines_into(lines, setup, opts, inner),
    };
    let mut back = Checking::new(setup, opts, inner);
    let unstarted = std::thread::scope(|scope| {
        // The interpreter is handed over once its thread runs, so that it is still here to
        // run serially when the thread cannot be started.
        let (hand_over, take_over) = sync_channel::<Interpreting<L>>(1);
        let (to_back, from_front) = sync_channel::<Vec<Interpreted>>(QUEUED_BATCHES);
        let (give_back, spent) = sync_channel::<Vec<Interpreted>>(QUEUED_BATCHES + 2);
        let spawned = std::thread::Builder::new()
            .name("cnc-interp".into())
            .stack_size(crate::runtime::rt::THREAD_STACK_BYTES)
            .spawn_scoped(scope, move || {
                if let Ok(front) = take_over.recv() {
                    interpret(front, &to_back, &spent);
                }
            });
        if spawned.is_err() {
            return Some(front);
        }
        let _ = hand_over.send(front);
        for mut batch in from_front {
            batch.drain(..).for_each(|item| back.take(item));
            let _ = give_back.try_send(batch);
        }
        // (A panic of the interpreter's thread ends the queue early, and the scope panics
        // with it when it ends: a verdict on part of a program is never given.)
        None
    });
    match unstarted {
        Some(front) => split::run_here(front, back, BATCH),
        None => back.finish(),
    }
}

/// The interpreter's thread: batches until the program ends (or the pass is gone).
fn interpret<L: Lines>(
    mut front: Interpreting<L>,
    to_back: &std::sync::mpsc::SyncSender<Vec<Interpreted>>,
    spent: &std::sync::mpsc::Receiver<Vec<Interpreted>>,
) {
    loop {
        let mut batch = spent
            .try_recv()
            .unwrap_or_else(|_| Vec::with_capacity(BATCH));
        let mut more = true;
        while more && batch.len() < BATCH {
            more = front.next_into(&mut batch);
        }
        if to_back.send(batch).is_err() || !more {
            return;
        }
    }
}
