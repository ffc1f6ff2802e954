//! Which language a program is read in (docs/language.md, "Which dialect a program is in"):
//! the API's `dialect` field when given, else the program's name, else `[program] dialect`.
//! cncd and cncctl decide it here, so `cncctl` sends what the daemon would choose.

use kernel::DiagCode;
use kernel::program::Dialect;

/// A `dialect` given over the API (or to cncctl) that cncd does not know.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error(
    "dialect {0:?} is not a program language cncd reads: cnc836 or iso (or leave it empty: \
     by the program's name, else the machine's [program] dialect)"
)]
pub struct UnknownDialect(pub String);

impl UnknownDialect {
    /// Stable code (`dialect_unknown`).
    pub fn code(&self) -> DiagCode {
        DiagCode::DialectUnknown
    }
}

/// A request's `dialect` field: `None` when empty (the name or the machine decides).
pub fn requested(field: &str) -> Result<Option<Dialect>, UnknownDialect> {
    if field.trim().is_empty() {
        return Ok(None);
    }
    Dialect::from_name(field)
        .map(Some)
        .ok_or_else(|| UnknownDialect(field.to_string()))
}

/// The dialect a program's name says, the machine's `default` where it says none
/// (`kernel::program::Dialect::of_file`: `*.ngc`, `*.tap`, `*.gcode` are ISO; `*.nc`, what
/// CNC836 programs are kept as, follows the default).
pub fn of_name(name: &str, default: Dialect) -> Dialect {
    Dialect::of_file(name, default)
}

/// The dialect of program `name`: `explicit` (the API's field, or what the library recorded
/// with it), else by its name ([`of_name`]).
pub fn of_program(explicit: Option<Dialect>, name: &str, default: Dialect) -> Dialect {
    explicit.unwrap_or_else(|| of_name(name, default))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn field_name_and_default_in_that_order() {
        assert_eq!(requested(""), Ok(None));
        assert_eq!(requested("ISO"), Ok(Some(Dialect::Iso)));
        assert_eq!(requested("cnc836"), Ok(Some(Dialect::Cnc836)));
        let e = requested("fanuc").unwrap_err();
        assert_eq!(e.code().as_str(), "dialect_unknown");
        assert!(e.to_string().contains("\"fanuc\""), "{e}");
        let c = Dialect::Cnc836;
        assert_eq!(of_name("part.ngc", c), Dialect::Iso);
        assert_eq!(of_name("PART.TAP", c), Dialect::Iso);
        assert_eq!(of_name("a.gcode", c), Dialect::Iso);
        assert_eq!(of_name("sample.nc", c), Dialect::Cnc836);
        assert_eq!(of_name("sample.nc", Dialect::Iso), Dialect::Iso);
        assert_eq!(of_name("P0001", Dialect::Iso), Dialect::Iso);
        assert_eq!(of_program(Some(c), "part.ngc", c), Dialect::Cnc836);
    }
}
