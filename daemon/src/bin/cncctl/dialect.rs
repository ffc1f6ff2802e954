//! The `dialect` field cncctl sends: the rule is the daemon's (`daemon::runtime::dialect`), so
//! a file's text sent without its name is read as the daemon would read it by that name.

use std::path::Path;

use daemon::runtime::dialect;
use kernel::program::Dialect;

use crate::error::CliError;

/// `--dialect` checked: "" when not given (the daemon decides).
pub fn flag(given: Option<&str>) -> Result<String, CliError> {
    match given {
        None => Ok(String::new()),
        Some(d) => Ok(dialect::requested(d)?.map_or("", Dialect::as_str).into()),
    }
}

/// For a call that sends `file`'s text without its name: `--dialect`, else "iso" when the
/// name says ISO, else "" (the machine's `[program] dialect`), as the daemon decides by name.
pub fn for_file(file: &Path, given: Option<&str>) -> Result<String, CliError> {
    if given.is_some() {
        return flag(given);
    }
    let name = file
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    // The machine's default is not known here: a name that says ISO says it whatever it is.
    Ok(match dialect::of_name(&name, Dialect::Cnc836) {
        Dialect::Iso => "iso".into(),
        Dialect::Cnc836 => String::new(),
    })
}

/// The dialect of a local preview (no daemon): `--dialect`, else by the name, else CNC836.
pub fn local(file: &Path, given: Option<&str>) -> Result<Dialect, CliError> {
    let d = for_file(file, given)?;
    Ok(Dialect::from_name(&d).unwrap_or_default())
}
