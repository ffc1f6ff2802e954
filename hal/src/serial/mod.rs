//! Drive link over a serial port: COBS-framed, CRC-checked exchanges, one per tick.
//! The protocol is specified in `hal/SERIAL_PROTOCOL.md`.

pub mod bus;
pub mod frame;
pub mod message;
pub mod port;
pub mod unit_io;
pub mod version;

pub use bus::{SerialAxis, SerialBus, SerialConfig, SerialSpindle};
pub use port::{LinkDown, SerialPort, TtyPort};

/// Why a serial bus cannot be set up.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum SerialError {
    #[error("cannot open serial port {path}: {reason}")]
    Open { path: String, reason: String },
    #[error(
        "{count} axes on serial link {path}, 1..={} are supported",
        crate::MAX_AXES
    )]
    AxisCount { count: usize, path: String },
    #[error("increments per mm of axis {axis} must be positive")]
    AxisScale { axis: usize },
    #[error("maximum speed of axis {axis} must be positive")]
    AxisSpeed { axis: usize },
    #[error("velocity units per rpm of the spindle must be positive")]
    SpindleScale,
    #[error("serial I/O bit {bit} is beyond the drive unit's 64-bit I/O words (0..=63)")]
    IoBit { bit: u8 },
}

impl SerialError {
    /// Stable code (tests and HMIs match it; the message may improve).
    pub fn code(&self) -> &'static str {
        match self {
            SerialError::Open { .. } => "serial_open",
            SerialError::AxisCount { .. } => "serial_axis_count",
            SerialError::AxisScale { .. } => "serial_axis_scale",
            SerialError::AxisSpeed { .. } => "serial_axis_speed",
            SerialError::SpindleScale => "serial_spindle_scale",
            SerialError::IoBit { .. } => "serial_io_bit",
        }
    }
}
