//! [`CanPort`] on a Linux SocketCAN interface (`can0`, `vcan0`), non-blocking, with error
//! frames enabled so bus-off and bus errors reach the master.

use std::io;
use std::time::Duration;

use socketcan::{
    CanDataFrame, CanFrame, CanSocket, EmbeddedFrame, Frame as _, Socket, SocketOptions, StandardId,
};

use super::{CanOpenError, CanPort, Frame, PortError, RxEvent};
use crate::candump::RecordTap;

pub struct SocketCanPort {
    socket: CanSocket,
    tap: Option<RecordTap>,
}

impl SocketCanPort {
    /// Opens `iface`. The message says what to check when it fails.
    pub fn open(iface: &str) -> Result<SocketCanPort, CanOpenError> {
        let socket = CanSocket::open(iface).map_err(|e| CanOpenError::Open {
            iface: iface.to_owned(),
            reason: e.to_string(),
        })?;
        socket
            .set_nonblocking(true)
            .and_then(|()| socket.set_error_filter_accept_all())
            .map_err(|e| CanOpenError::Configure {
                iface: iface.to_owned(),
                reason: e.to_string(),
            })?;
        Ok(SocketCanPort { socket, tap: None })
    }

    /// Records every frame sent and received (candump log format, see [`crate::candump`]).
    pub fn with_recording(mut self, tap: RecordTap) -> SocketCanPort {
        self.tap = Some(tap);
        self
    }
}

fn port_error(e: &io::Error) -> PortError {
    match e.kind() {
        io::ErrorKind::WouldBlock => PortError::WouldBlock,
        // ENOBUFS: the qdisc queue is full, as when no node acknowledges; not fatal by itself.
        _ if e.raw_os_error() == Some(105) => PortError::WouldBlock,
        _ => PortError::Down,
    }
}

impl SocketCanPort {
    /// Waits up to `timeout` for a frame (for simulators and tools; the master never waits).
    pub fn recv_timeout(&mut self, timeout: Duration) -> Result<Option<RxEvent>, PortError> {
        match self.socket.read_frame_timeout(timeout) {
            Ok(f) => Ok(self.convert(f)),
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock
                ) =>
            {
                Ok(None)
            }
            Err(e) => Err(port_error(&e)),
        }
    }

    /// Our view of a received frame; `None` for frames CANopen does not use (extended ids,
    /// remote frames).
    fn convert(&mut self, f: CanFrame) -> Option<RxEvent> {
        match f {
            CanFrame::Data(d) if !d.is_extended() => {
                let frame = Frame::new(d.raw_id() as u16, d.data());
                if let Some(tap) = &mut self.tap {
                    tap.record(&frame);
                }
                Some(RxEvent::Frame(frame))
            }
            CanFrame::Error(e) => {
                let mut data = [0u8; 8];
                let n = e.data().len().min(8);
                data[..n].copy_from_slice(&e.data()[..n]);
                Some(RxEvent::Error {
                    class: e.error_bits(),
                    data,
                })
            }
            _ => None,
        }
    }
}

impl CanPort for SocketCanPort {
    fn send(&mut self, frame: &Frame) -> Result<(), PortError> {
        let id = StandardId::new(frame.id).ok_or(PortError::Down)?;
        let data = CanDataFrame::new(id, frame.payload()).ok_or(PortError::Down)?;
        self.socket.write_frame(&data).map_err(|e| port_error(&e))?;
        if let Some(tap) = &mut self.tap {
            tap.record(frame);
        }
        Ok(())
    }

    fn try_recv(&mut self) -> Result<Option<RxEvent>, PortError> {
        loop {
            let f = match self.socket.read_frame() {
                Ok(f) => f,
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => return Ok(None),
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(port_error(&e)),
            };
            match self.convert(f) {
                Some(ev) => return Ok(Some(ev)),
                None => continue,
            }
        }
    }
}
