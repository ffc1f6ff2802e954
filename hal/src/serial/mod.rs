//! Drive link over a serial port: COBS-framed, CRC-checked exchanges, one per tick.
//! The protocol is specified in `hal/SERIAL_PROTOCOL.md`.

pub mod bus;
pub mod frame;
pub mod message;

pub use bus::{SerialAxis, SerialBus, SerialConfig, SerialSpindle};
