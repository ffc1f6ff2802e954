//! The controller daemon: the NC kernel (re-exported from the `kernel` crate) wired to IO.
pub use kernel;
pub mod mtconnect;
pub mod runtime;
