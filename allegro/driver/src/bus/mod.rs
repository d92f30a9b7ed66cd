//! CAN buses the driver and the emulator talk over: [`CanBus`], with two backends, Linux
//! SocketCAN ([`socketcan::SocketCanBus`], `can0` on a PCAN-USB adapter, or `vcan0`) and an
//! in-process pair ([`memory::MemoryBus`]) for tests and the emulated hand.

use std::time::Duration;

use dips_allegro_protocol::CanFrame;

pub mod echo;
pub mod memory;
#[cfg(target_os = "linux")]
pub mod socketcan;

/// Errors of a bus.
#[derive(Debug, thiserror::Error)]
pub enum BusError {
    /// The interface could not be opened (absent, down, or no permission).
    #[error(
        "CAN interface {iface}: {source} (is the adapter plugged in and the link up? \
         `ip link set {iface} up type can bitrate 1000000`)"
    )]
    Open {
        /// The interface.
        iface: String,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// Reading or writing a frame failed.
    #[error("CAN interface {iface}: {source}")]
    Io {
        /// The interface.
        iface: String,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// The other end of an in-process bus is gone.
    #[error("CAN bus {0}: the other end closed")]
    Closed(String),
    /// SocketCAN does not exist on this operating system.
    #[error("CAN interface {0}: SocketCAN needs Linux")]
    Unsupported(String),
}

/// A CAN bus as the driver uses it: send a frame, wait a while for one.
pub trait CanBus: Send {
    /// The bus's name (`can0`, `memory`).
    fn name(&self) -> &str;
    /// Send one frame.
    fn send(&mut self, frame: &CanFrame) -> Result<(), BusError>;
    /// The next frame, waiting up to `timeout`; `None` when none came.
    fn recv(&mut self, timeout: Duration) -> Result<Option<CanFrame>, BusError>;
    /// Drop every frame already received (the start-up flush).
    fn flush(&mut self) -> Result<usize, BusError> {
        let mut n = 0;
        while self.recv(Duration::ZERO)?.is_some() {
            n += 1;
        }
        Ok(n)
    }
}

impl CanBus for Box<dyn CanBus> {
    fn name(&self) -> &str {
        (**self).name()
    }
    fn send(&mut self, frame: &CanFrame) -> Result<(), BusError> {
        (**self).send(frame)
    }
    fn recv(&mut self, timeout: Duration) -> Result<Option<CanFrame>, BusError> {
        (**self).recv(timeout)
    }
    fn flush(&mut self) -> Result<usize, BusError> {
        (**self).flush()
    }
}
