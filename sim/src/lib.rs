//! Simulated drives and the in-process simulated bus, the daemon's default machine.

pub mod bus;
pub mod drive;

pub use bus::SimBus;
pub use drive::{SimDrive, SimDriveParams};
