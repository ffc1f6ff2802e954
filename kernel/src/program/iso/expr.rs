//! Evaluation of expressions and parameter references against [`Params`].

use super::Fail;
use super::ast::{Expr, ParamRef};
use super::params::{Params, Target};

/// The value of `e`; `at` locates errors (the word's byte offset).
pub fn eval(_e: &Expr, _p: &Params, _at: usize) -> Result<f64, Fail> {
    Ok(0.0)
}

/// Resolves a reference (evaluating a computed number) to its target.
pub fn target(_r: &ParamRef, _p: &Params, _at: usize) -> Result<Target, Fail> {
    Ok(Target::Numbered(0))
}
