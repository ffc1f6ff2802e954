//! The parameters of an ISO program: numbered #1..#5602 (#1..#30 local to a subroutine
//! call), named `#<local>` (per call) and `#<_global>`.

use std::collections::BTreeMap;

use super::Fail;
use crate::diag::DiagCode;

/// Highest numbered parameter (LinuxCNC 2.9).
pub const MAX_NUMBERED: usize = 5602;

/// Parameters a subroutine call gives its own copy of (its arguments).
pub const CALL_LOCALS: usize = 30;

/// Numbered parameters a program cannot write (LinuxCNC 2.9: machine position, the loaded
/// tool's data, current position); the interpreter itself still writes them.
pub fn read_only(n: usize) -> bool {
    matches!(n, 5021..=5029 | 5400..=5413 | 5420..=5428)
}

/// What a call hides from its caller and gives back on return.
#[derive(Clone, Debug)]
struct Frame {
    args: [f64; CALL_LOCALS],
    locals: BTreeMap<String, f64>,
}

/// The parameter store, with one frame of locals per active subroutine call.
///
/// Maps are ordered ones: no hashing seeded from the OS in this sans-IO crate, and the
/// stores stay small.
#[derive(Clone, Debug)]
pub struct Params {
    /// Index 0 unused, so that `numbered[n]` is `#n`.
    numbered: Vec<f64>,
    globals: BTreeMap<String, f64>,
    /// Named locals of the running level (the main program or the innermost call).
    locals: BTreeMap<String, f64>,
    /// The callers' hidden state, innermost last.
    frames: Vec<Frame>,
}

impl Default for Params {
    fn default() -> Self {
        Self::new()
    }
}

impl Params {
    pub fn new() -> Self {
        Params {
            numbered: vec![0.0; MAX_NUMBERED + 1],
            globals: BTreeMap::new(),
            locals: BTreeMap::new(),
            frames: Vec::new(),
        }
    }

    /// `#n`; unset ones read 0 as in LinuxCNC. Outside 1..=5602 (which [`super::expr::target`]
    /// refuses) also 0.
    pub fn get_numbered(&self, n: usize) -> f64 {
        match n {
            1..=MAX_NUMBERED => self.numbered[n],
            _ => 0.0,
        }
    }

    /// Sets `#n`; outside 1..=5602 nothing happens (callers resolve numbers with
    /// [`super::expr::target`], which refuses those).
    pub fn set_numbered(&mut self, n: usize, v: f64) {
        if (1..=MAX_NUMBERED).contains(&n) {
            self.numbered[n] = v;
        }
    }

    /// A named parameter (lower-cased name), `None` when never set in its scope.
    pub fn get_named(&self, name: &str) -> Option<f64> {
        self.scope(name).get(name).copied()
    }

    pub fn set_named(&mut self, name: &str, v: f64) {
        let scope = if is_global(name) {
            &mut self.globals
        } else {
            &mut self.locals
        };
        match scope.get_mut(name) {
            Some(slot) => *slot = v,
            None => {
                scope.insert(name.to_string(), v);
            }
        }
    }

    fn scope(&self, name: &str) -> &BTreeMap<String, f64> {
        if is_global(name) {
            &self.globals
        } else {
            &self.locals
        }
    }

    /// The value of a resolved reference; an unset named one is an error (LinuxCNC).
    pub fn read(&self, t: &Target, at: usize) -> Result<f64, Fail> {
        match t {
            Target::Numbered(n) => Ok(self.get_numbered(*n)),
            Target::Named(name) => self.get_named(name).ok_or_else(|| {
                Fail::new(
                    at,
                    DiagCode::ParamUnassigned,
                    format!("#<{name}> is read before it was set"),
                )
            }),
        }
    }

    /// Writes a resolved reference (no read-only check: see [`super::expr::assign`]).
    pub fn write(&mut self, t: &Target, v: f64) {
        match t {
            Target::Numbered(n) => self.set_numbered(*n, v),
            Target::Named(name) => self.set_named(name, v),
        }
    }

    /// A subroutine call: a new frame whose #1..#30 are `args` (the rest 0; beyond 30
    /// ignored) and whose named locals start empty.
    pub fn push_frame(&mut self, args: &[f64]) {
        let mut saved = [0.0; CALL_LOCALS];
        saved.copy_from_slice(&self.numbered[1..=CALL_LOCALS]);
        self.frames.push(Frame {
            args: saved,
            locals: std::mem::take(&mut self.locals),
        });
        let mine = &mut self.numbered[1..=CALL_LOCALS];
        mine.fill(0.0);
        let n = args.len().min(CALL_LOCALS);
        mine[..n].copy_from_slice(&args[..n]);
    }

    /// Its return: the caller's #1..#30 and locals back. In the main program nothing happens.
    pub fn pop_frame(&mut self) {
        if let Some(f) = self.frames.pop() {
            self.numbered[1..=CALL_LOCALS].copy_from_slice(&f.args);
            self.locals = f.locals;
        }
    }

    /// The call depth (0 in the main program).
    pub fn depth(&self) -> usize {
        self.frames.len()
    }
}

/// `#<_name>` is global (LinuxCNC); everything else belongs to the running level.
fn is_global(name: &str) -> bool {
    name.starts_with('_')
}

/// A reference resolved to its target (the number of `#[#1+2]` evaluated).
#[derive(Clone, Debug, PartialEq)]
pub enum Target {
    Numbered(usize),
    Named(String),
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbered_unset_read_zero_and_out_of_range_is_harmless() {
        let mut p = Params::new();
        assert_eq!(p.get_numbered(100), 0.0);
        p.set_numbered(100, 2.5);
        p.set_numbered(MAX_NUMBERED, 7.0);
        assert_eq!(p.get_numbered(100), 2.5);
        assert_eq!(p.get_numbered(MAX_NUMBERED), 7.0);
        p.set_numbered(0, 1.0);
        p.set_numbered(MAX_NUMBERED + 1, 1.0);
        assert_eq!(p.get_numbered(0), 0.0);
        assert_eq!(p.get_numbered(MAX_NUMBERED + 1), 0.0);
        assert_eq!(p.get_numbered(usize::MAX), 0.0);
    }

    #[test]
    fn frames_hide_and_restore_args_and_locals() {
        let mut p = Params::new();
        p.set_numbered(1, 11.0);
        p.set_numbered(30, 30.0);
        p.set_numbered(31, 31.0);
        p.set_named("x", 1.0);
        p.set_named("_g", 5.0);
        p.push_frame(&[7.0, 8.0]);
        assert_eq!(p.depth(), 1);
        assert_eq!(p.get_numbered(1), 7.0);
        assert_eq!(p.get_numbered(2), 8.0);
        assert_eq!(p.get_numbered(3), 0.0);
        assert_eq!(p.get_numbered(30), 0.0);
        // #31.. are not call locals.
        assert_eq!(p.get_numbered(31), 31.0);
        assert_eq!(p.get_named("x"), None);
        assert_eq!(p.get_named("_g"), Some(5.0));
        p.set_named("x", 2.0);
        p.set_named("_g", 6.0);
        p.set_numbered(1, 99.0);
        p.set_numbered(31, 32.0);
        p.pop_frame();
        assert_eq!(p.depth(), 0);
        assert_eq!(p.get_numbered(1), 11.0);
        assert_eq!(p.get_numbered(30), 30.0);
        assert_eq!(p.get_numbered(31), 32.0);
        assert_eq!(p.get_named("x"), Some(1.0));
        assert_eq!(p.get_named("_g"), Some(6.0));
        // Popping the main level changes nothing.
        p.pop_frame();
        assert_eq!(p.get_numbered(1), 11.0);
        assert_eq!(p.depth(), 0);
    }

    #[test]
    fn nested_frames_and_too_many_args() {
        let mut p = Params::new();
        let args: Vec<f64> = (1..=40).map(f64::from).collect();
        p.push_frame(&args);
        assert_eq!(p.get_numbered(30), 30.0);
        assert_eq!(p.get_numbered(31), 0.0);
        p.set_named("a", 1.0);
        p.push_frame(&[]);
        assert_eq!(p.depth(), 2);
        assert_eq!(p.get_numbered(1), 0.0);
        assert_eq!(p.get_named("a"), None);
        p.pop_frame();
        assert_eq!(p.get_numbered(1), 1.0);
        assert_eq!(p.get_named("a"), Some(1.0));
    }

    #[test]
    fn read_unset_named_is_unassigned() {
        let mut p = Params::new();
        let t = Target::Named("abc".into());
        let e = p.read(&t, 4).unwrap_err();
        assert_eq!((e.at, e.code), (4, DiagCode::ParamUnassigned));
        assert!(e.message.contains("abc"));
        p.write(&t, 3.0);
        assert_eq!(p.read(&t, 4), Ok(3.0));
        p.write(&Target::Numbered(5), 2.0);
        assert_eq!(p.read(&Target::Numbered(5), 0), Ok(2.0));
    }

    #[test]
    fn read_only_numbers() {
        assert!(read_only(5021) && read_only(5413) && read_only(5428));
        assert!(!read_only(5220) && !read_only(5061) && !read_only(5414));
    }
}
