//! [`MemoryBus`]: two ends of an in-process CAN bus. What one end sends, the other receives,
//! in order; either end can be moved to its own thread. A [`Tap`] on an end records every
//! frame it sends (what tests read back, such as the emulator's last torques).

use std::sync::mpsc::{Receiver, RecvTimeoutError, Sender, TryRecvError, channel};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use dips_allegro_protocol::CanFrame;

use super::{BusError, CanBus};

/// The frames one end has sent, shared with whoever holds the tap.
pub type Tap = Arc<Mutex<Vec<CanFrame>>>;

/// One end of an in-process bus.
#[derive(Debug)]
pub struct MemoryBus {
    name: String,
    tx: Sender<CanFrame>,
    rx: Receiver<CanFrame>,
    tap: Option<Tap>,
}

impl MemoryBus {
    /// A connected pair: the host's end and the hand's end.
    pub fn pair(name: &str) -> (MemoryBus, MemoryBus) {
        let (a_tx, b_rx) = channel();
        let (b_tx, a_rx) = channel();
        let end = |tx, rx| MemoryBus {
            name: name.to_string(),
            tx,
            rx,
            tap: None,
        };
        (end(a_tx, a_rx), end(b_tx, b_rx))
    }

    /// Record every frame this end sends from now on; the returned tap reads them.
    pub fn tap(&mut self) -> Tap {
        let tap = Tap::default();
        self.tap = Some(tap.clone());
        tap
    }
}

impl CanBus for MemoryBus {
    fn name(&self) -> &str {
        &self.name
    }

    fn send(&mut self, frame: &CanFrame) -> Result<(), BusError> {
        if let Some(tap) = &self.tap
            && let Ok(mut t) = tap.lock()
        {
            t.push(*frame);
        }
        self.tx
            .send(*frame)
            .map_err(|_| BusError::Closed(self.name.clone()))
    }

    fn recv(&mut self, timeout: Duration) -> Result<Option<CanFrame>, BusError> {
        if timeout.is_zero() {
            return match self.rx.try_recv() {
                Ok(f) => Ok(Some(f)),
                Err(TryRecvError::Empty) => Ok(None),
                Err(TryRecvError::Disconnected) => Err(BusError::Closed(self.name.clone())),
            };
        }
        match self.rx.recv_timeout(timeout) {
            Ok(f) => Ok(Some(f)),
            Err(RecvTimeoutError::Timeout) => Ok(None),
            Err(RecvTimeoutError::Disconnected) => Err(BusError::Closed(self.name.clone())),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use embedded_can::{Frame, StandardId};

    #[test]
    fn what_one_end_sends_the_other_receives_in_order() {
        let (mut a, mut b) = MemoryBus::pair("memory");
        let tap = a.tap();
        for i in 0..3u8 {
            let f = CanFrame::new(StandardId::new(0x180).unwrap(), &[i]).unwrap();
            a.send(&f).unwrap();
        }
        for i in 0..3u8 {
            let f = b.recv(Duration::from_millis(10)).unwrap().unwrap();
            assert_eq!(f.data(), &[i]);
        }
        assert_eq!(b.recv(Duration::from_millis(1)).unwrap(), None);
        assert_eq!(tap.lock().unwrap().len(), 3);
        drop(a);
        assert!(matches!(b.recv(Duration::ZERO), Err(BusError::Closed(_))));
    }
}
