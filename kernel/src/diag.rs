//! Diagnostics: every error and warning the kernel produces, with where it comes from.

use std::fmt;

#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Severity {
    /// Informational message (e.g. an inserted arc reported because R339 is negative, SPEC §4.3).
    Info,
    /// The program may run, but the machinist should look (e.g. R397 equidistant check, SPEC §4.5).
    Warning,
    /// The program must not run.
    Error,
}

/// One message about a program, a table file or a configuration, located for a machinist:
/// block number `N` when the block has one, and always the 1-based source line and column.
#[derive(Clone, Debug, PartialEq)]
pub struct Diagnostic {
    pub severity: Severity,
    /// The `N` number of the block, if it was programmed.
    pub block: Option<u32>,
    /// 1-based line in the source text (0 when not tied to a line).
    pub line: u32,
    /// 1-based column in the line (0 when not tied to a column).
    pub column: u32,
    pub message: String,
    /// Set when the message is a soft-limit refusal (issue #15): which axis, where, which limit.
    pub limit: Option<crate::limits::LimitHit>,
}

impl Diagnostic {
    pub fn error(block: Option<u32>, line: u32, column: u32, message: impl Into<String>) -> Self {
        Diagnostic {
            severity: Severity::Error,
            block,
            line,
            column,
            message: message.into(),
            limit: None,
        }
    }

    pub fn warning(block: Option<u32>, line: u32, column: u32, message: impl Into<String>) -> Self {
        Diagnostic {
            severity: Severity::Warning,
            ..Self::error(block, line, column, message)
        }
    }

    pub fn info(block: Option<u32>, line: u32, column: u32, message: impl Into<String>) -> Self {
        Diagnostic {
            severity: Severity::Info,
            ..Self::error(block, line, column, message)
        }
    }

    pub fn is_error(&self) -> bool {
        self.severity == Severity::Error
    }
}

impl fmt::Display for Diagnostic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let sev = match self.severity {
            Severity::Info => "info",
            Severity::Warning => "warning",
            Severity::Error => "error",
        };
        write!(f, "{sev}")?;
        if let Some(n) = self.block {
            write!(f, " in block N{n}")?;
        }
        if self.line > 0 {
            write!(f, " (line {}, column {})", self.line, self.column)?;
        }
        write!(f, ": {}", self.message)
    }
}
