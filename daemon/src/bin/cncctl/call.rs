//! One call and its answer printed: what the per-service modules do for every call that
//! answers once (streams and uploads keep their own loops). The connection is made once in
//! `main`; a refusal becomes [`CliError::Rpc`], printed with every diagnostic it carries.

use std::process::ExitCode;

use crate::error::CliError;
use crate::render::{Done, Render, show};

/// How a command ends: its exit code, or why it failed.
pub type Reply = Result<ExitCode, CliError>;

/// A unary call's answer, as a tonic client returns it.
type Answer<T> = Result<tonic::Response<T>, tonic::Status>;

/// Awaits `answer` and prints it.
pub async fn call<T: Render>(j: bool, answer: impl Future<Output = Answer<T>>) -> Reply {
    call_as(j, answer, |r| r).await
}

/// Awaits `answer` and prints what `view` makes of it (the answer with what the command
/// knows besides, e.g. the program's name).
pub async fn call_as<T, R: Render>(
    j: bool,
    answer: impl Future<Output = Answer<T>>,
    view: impl FnOnce(T) -> R,
) -> Reply {
    let r = answer.await?.into_inner();
    show(j, &view(r))
}

/// Awaits a call that answers nothing but success and prints [`Done`].
pub async fn call_done<T>(j: bool, answer: impl Future<Output = Answer<T>>) -> Reply {
    call_as(j, answer, |_| Done).await
}
