//! [`EchoBus`]: a bus that prints every frame sent through it, candump's way, before passing
//! it on (`--dry-run`: what the driver would send).

use std::io::Write;
use std::time::{Duration, Instant};

use dips_allegro_protocol::CanFrame;

use super::{BusError, CanBus};

/// Prints each sent frame as `(seconds) NAME ID [DLC] DATA` on a writer, then sends it on.
pub struct EchoBus<B: CanBus> {
    inner: B,
    label: String,
    out: Box<dyn Write + Send>,
    start: Instant,
}

impl<B: CanBus> std::fmt::Debug for EchoBus<B> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("EchoBus")
            .field("label", &self.label)
            .finish()
    }
}

impl<B: CanBus> EchoBus<B> {
    /// Echo the frames sent on `inner` as if on `label` (the interface a real run would use).
    pub fn new(inner: B, label: &str, out: Box<dyn Write + Send>) -> EchoBus<B> {
        EchoBus {
            inner,
            label: label.to_string(),
            out,
            start: Instant::now(),
        }
    }
}

impl<B: CanBus> CanBus for EchoBus<B> {
    fn name(&self) -> &str {
        &self.label
    }

    fn send(&mut self, frame: &CanFrame) -> Result<(), BusError> {
        // A closed stdout (a pager quit) must not stop the loop's shutdown frames.
        let _ = writeln!(
            self.out,
            "({:.6}) {} {frame}",
            self.start.elapsed().as_secs_f64(),
            self.label
        );
        self.inner.send(frame)
    }

    fn recv(&mut self, timeout: Duration) -> Result<Option<CanFrame>, BusError> {
        self.inner.recv(timeout)
    }
}
