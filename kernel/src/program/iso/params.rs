//! The parameters of an ISO program: numbered #1..#5602 (#1..#30 local to a subroutine
//! call), named `#<local>` (per call) and `#<_global>`.

use super::ast::ParamRef;

/// Highest numbered parameter (LinuxCNC 2.9).
pub const MAX_NUMBERED: usize = 5602;

/// The parameter store, with one frame of locals per active subroutine call.
#[derive(Clone, Debug, Default)]
pub struct Params {}

impl Params {
    pub fn new() -> Self {
        Params {}
    }

    /// Value of a resolved parameter, `None` when unset (reading it is an error for a named
    /// one and 0 for a numbered one, as in LinuxCNC).
    pub fn get_numbered(&self, _n: usize) -> f64 {
        0.0
    }

    pub fn set_numbered(&mut self, _n: usize, _v: f64) {}

    pub fn get_named(&self, _name: &str) -> Option<f64> {
        None
    }

    pub fn set_named(&mut self, _name: &str, _v: f64) {}

    /// A subroutine call: a new frame whose #1..#30 are `args` (the rest 0).
    pub fn push_frame(&mut self, _args: &[f64]) {}

    /// Its return: the caller's #1..#30 and locals back.
    pub fn pop_frame(&mut self) {}

    /// The call depth (0 in the main program).
    pub fn depth(&self) -> usize {
        0
    }
}

/// A reference resolved to its target (the number of `#[#1+2]` evaluated).
#[derive(Clone, Debug, PartialEq)]
pub enum Target {
    Numbered(usize),
    Named(String),
}

#[allow(dead_code)]
fn _uses(_: &ParamRef) {}
