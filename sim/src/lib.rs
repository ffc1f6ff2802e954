//! Simulated drives: the in-process simulated bus (the daemon's default machine), CiA 402
//! drives and CiA 401 I/O modules behind CANopen ([`can_node`], [`cia401_module`], binary
//! `sim-can`), and drives behind the serial protocol ([`serial_drive`], binary `sim-serial`).

pub mod bus;
pub mod can_node;
pub mod cia401_module;
pub mod cia402_drive;
pub mod control;
pub mod drive;
pub mod drive_io;
pub mod homing;
pub mod io;
pub mod pdo_objects;
pub mod probe;
pub mod serial_drive;

pub use bus::{SimBus, SpindleLoad};
pub use drive::{SimDrive, SimDriveParams};
