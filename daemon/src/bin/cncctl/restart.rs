//! `start --from-block N`: restart the selected program from a block (docs/operator.md
//! "Restart from a block"). The approach is shown first (the daemon's own trajectory of the
//! restart, without moving) and runs only once confirmed: `--yes`, or `y` typed at the
//! prompt.

use std::io::{BufRead, IsTerminal, Write};
use std::process::ExitCode;

use proto::v1 as pb;

use crate::connect::Clients;
use crate::error::CliError;
use crate::machine::Started;
use crate::render::show;
use crate::trajectory::trajectory;

pub async fn command(c: &mut Clients, n: u32, yes: bool, j: bool) -> Result<ExitCode, CliError> {
    let planned = trajectory(&mut c.trajectory, Default::default(), Some(n), None).await?;
    let approach = planned.approach.map(|a| a.describe()).unwrap_or_default();
    if !j {
        println!("restart from block N{n}: {approach}");
    }
    if !yes && !confirmed()? {
        return Err(CliError::NotConfirmed);
    }
    let req = pb::StartRequest {
        from_block: Some(n),
    };
    let job = c.machine.start(req).await?.into_inner().job;
    show(j, &Started { job, mdi: false })
}

/// Asks on a terminal; anything but `y`/`yes` (or no terminal) is a no.
fn confirmed() -> Result<bool, CliError> {
    let stdin = std::io::stdin();
    if !stdin.is_terminal() {
        return Ok(false);
    }
    print!("run the approach and the program from there? [y/N] ");
    std::io::stdout().flush().map_err(CliError::Output)?;
    let mut answer = String::new();
    stdin
        .lock()
        .read_line(&mut answer)
        .map_err(CliError::Output)?;
    Ok(matches!(answer.trim(), "y" | "Y" | "yes"))
}
