//! Simulated drives: the in-process simulated bus (the daemon's default machine), and CiA 402
//! drives behind CANopen ([`can_node`], binary `sim-can`) and behind the serial protocol
//! ([`serial_drive`], binary `sim-serial`).

pub mod bus;
pub mod can_node;
pub mod cia402_drive;
pub mod control;
pub mod drive;
pub mod homing;
pub mod io;
pub mod serial_drive;

pub use bus::{SimBus, SpindleLoad};
pub use drive::{SimDrive, SimDriveParams};
