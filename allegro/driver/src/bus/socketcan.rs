//! [`SocketCanBus`]: Linux SocketCAN through the `socketcan` crate (a PEAK PCAN-USB adapter
//! is `can0` with the kernel's `peak_usb` driver; `vcan0` is a virtual bus).

use std::time::Duration;

use dips_allegro_protocol::CanFrame;
use socketcan::{CanSocket, Socket};

use super::{BusError, CanBus};

/// A SocketCAN interface.
#[derive(Debug)]
pub struct SocketCanBus {
    iface: String,
    socket: CanSocket,
    timeout: Option<Duration>,
}

impl SocketCanBus {
    /// Open `iface` (`can0`, `vcan0`). The interface must exist and be up at 1 Mbit/s.
    pub fn open(iface: &str) -> Result<SocketCanBus, BusError> {
        let socket = CanSocket::open(iface).map_err(|source| BusError::Open {
            iface: iface.to_string(),
            source,
        })?;
        Ok(SocketCanBus {
            iface: iface.to_string(),
            socket,
            timeout: None,
        })
    }

    fn io(&self, source: std::io::Error) -> BusError {
        BusError::Io {
            iface: self.iface.clone(),
            source,
        }
    }
}

impl CanBus for SocketCanBus {
    fn name(&self) -> &str {
        &self.iface
    }

    fn send(&mut self, frame: &CanFrame) -> Result<(), BusError> {
        let f: socketcan::CanFrame = frame
            .to_frame()
            .ok_or_else(|| self.io(std::io::Error::other("frame refused by socketcan")))?;
        self.socket.write_frame(&f).map_err(|e| self.io(e))
    }

    fn recv(&mut self, timeout: Duration) -> Result<Option<CanFrame>, BusError> {
        // A zero read timeout means "block forever" to the socket: poll with the shortest.
        let t = timeout.max(Duration::from_micros(1));
        if self.timeout != Some(t) {
            self.socket.set_read_timeout(t).map_err(|e| self.io(e))?;
            self.timeout = Some(t);
        }
        match self.socket.read_frame() {
            Ok(f) => Ok(Some(CanFrame::from_frame(&f))),
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) =>
            {
                Ok(None)
            }
            Err(e) => Err(self.io(e)),
        }
    }
}
