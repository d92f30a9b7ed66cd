//! The byte link: frames out, replies matched by request id, timeouts and a dead peer.

use std::collections::VecDeque;
use std::io::{self, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::{Receiver, RecvTimeoutError, channel};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use dips_wire::{
    Feed, Frame, FrameAccumulator, FromKernel, MAX_ENCODED_FRAME_LEN, ModelRole, NO_REQUEST_ID,
    ToKernel, WireError, decode_frame, encode_frame,
};

/// How long the host waits for the kernel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Timeouts {
    /// Any reply but a plan's.
    pub reply: Duration,
    /// A plan's reply: its time budget plus this (a plan stops at the first expansion after
    /// its budget).
    pub plan_margin: Duration,
    /// A plan without a time budget.
    pub unbudgeted_plan: Duration,
}

impl Default for Timeouts {
    /// 10 s per reply, a plan's budget + 60 s, an hour for a plan without a budget.
    fn default() -> Self {
        Self {
            reply: Duration::from_secs(10),
            plan_margin: Duration::from_secs(60),
            unbudgeted_plan: Duration::from_secs(3600),
        }
    }
}

/// Why a request got no usable answer.
#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    /// Nothing came back in time.
    #[error("the kernel ({link}) did not answer {request} (request {id}) within {seconds:.1} s")]
    Timeout {
        /// The link, named.
        link: String,
        /// The request, named.
        request: String,
        /// Its id.
        id: u32,
        /// The timeout.
        seconds: f64,
    },
    /// The link closed (the kernel exited, the socket closed) before the answer.
    #[error(
        "the kernel ({link}) closed the link while {request} (request {id}) was waiting for its answer{detail}"
    )]
    Closed {
        /// The link, named.
        link: String,
        /// The request, named.
        request: String,
        /// Its id.
        id: u32,
        /// The exit status and the last lines of its stderr, when known.
        detail: String,
    },
    /// The kernel refused the request with a wire error.
    #[error("the kernel ({link}) refused {request} (request {id}): {error}")]
    Refused {
        /// The link, named.
        link: String,
        /// The request, named.
        request: String,
        /// Its id.
        id: u32,
        /// The kernel's error.
        error: WireError,
    },
    /// An answer of another kind than the request calls for.
    #[error("the kernel ({link}) answered {request} (request {id}) with {got}")]
    Unexpected {
        /// The link, named.
        link: String,
        /// The request, named.
        request: String,
        /// Its id.
        id: u32,
        /// What came instead.
        got: String,
    },
    /// The link could not be opened.
    #[error("{0}")]
    Open(String),
    /// No kernel binary to spawn was found.
    #[error(transparent)]
    NoFirmware(#[from] crate::target::NoFirmware),
}

/// A request's name for messages: the variant, and the model role of an upload.
pub fn request_name(body: &ToKernel) -> String {
    let role = |r: ModelRole| match r {
        ModelRole::Denoiser => "denoiser",
        ModelRole::Discriminator => "discriminator",
    };
    match body {
        ToKernel::Hello(_) => "Hello".into(),
        ToKernel::PlanRequest(_) => "PlanRequest".into(),
        ToKernel::ModelBegin(b) => format!("ModelBegin ({})", role(b.role)),
        ToKernel::ModelChunk(c) => format!("ModelChunk (offset {} bytes)", c.offset_bytes),
        ToKernel::ModelEnd => "ModelEnd".into(),
        ToKernel::SetPrior(_) => "SetPrior".into(),
        ToKernel::SetSampler(_) => "SetSampler".into(),
        ToKernel::Status => "Status".into(),
        ToKernel::Cancel => "Cancel".into(),
    }
}

/// What the reader thread hands over.
enum Incoming {
    Reply(Frame<FromKernel>),
    /// A frame that did not decode (the kernel's output garbled).
    Garbled,
    /// The input ended or failed.
    Closed(Option<io::Error>),
}

/// Lines of the child's stderr kept for error messages.
const STDERR_LINES: usize = 12;

/// A link to one kernel.
pub struct Link {
    name: String,
    writer: Box<dyn Write + Send>,
    replies: Receiver<Incoming>,
    child: Option<Child>,
    stderr_tail: Arc<Mutex<VecDeque<String>>>,
    next_id: u32,
    closed: bool,
    timeouts: Timeouts,
}

impl std::fmt::Debug for Link {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Link")
            .field("name", &self.name)
            .field("next_id", &self.next_id)
            .field("closed", &self.closed)
            .finish_non_exhaustive()
    }
}

impl Link {
    /// A link over any byte streams (`name` is how messages call it).
    pub fn over<R: Read + Send + 'static, W: Write + Send + 'static>(
        name: impl Into<String>,
        reader: R,
        writer: W,
    ) -> Self {
        Self::with_parts(name.into(), Box::new(reader), Box::new(writer), None)
    }

    fn with_parts(
        name: String,
        mut reader: Box<dyn Read + Send>,
        writer: Box<dyn Write + Send>,
        child: Option<Child>,
    ) -> Self {
        let (tx, rx) = channel();
        std::thread::spawn(move || {
            let mut acc = FrameAccumulator::<MAX_ENCODED_FRAME_LEN>::new();
            let mut buf = [0u8; 4096];
            loop {
                let n = match reader.read(&mut buf) {
                    Ok(0) => {
                        let _ = tx.send(Incoming::Closed(None));
                        return;
                    }
                    Ok(n) => n,
                    Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                    Err(e) => {
                        let _ = tx.send(Incoming::Closed(Some(e)));
                        return;
                    }
                };
                let mut window = &buf[..n];
                loop {
                    let incoming = match acc.feed(window) {
                        Feed::Consumed => break,
                        Feed::Frame { payload, remaining } => {
                            window = remaining;
                            match decode_frame::<FromKernel>(payload) {
                                Ok(frame) => Incoming::Reply(frame),
                                Err(_) => Incoming::Garbled,
                            }
                        }
                        Feed::Error { remaining, .. } => {
                            window = remaining;
                            Incoming::Garbled
                        }
                    };
                    if tx.send(incoming).is_err() {
                        return;
                    }
                }
            }
        });
        Self {
            name,
            writer,
            replies: rx,
            child,
            stderr_tail: Arc::new(Mutex::new(VecDeque::new())),
            next_id: 1,
            closed: false,
            timeouts: Timeouts::default(),
        }
    }

    /// Start `exe` (a `dips-firmware-sim`) with `args` and talk to it over its stdin/stdout;
    /// its stderr is kept (the last lines) for error messages.
    pub fn spawn(exe: &Path, args: &[String]) -> Result<Self, LinkError> {
        let mut child = Command::new(exe)
            .args(args)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| LinkError::Open(format!("cannot start {}: {e}", exe.display())))?;
        let (Some(stdin), Some(stdout), Some(stderr)) =
            (child.stdin.take(), child.stdout.take(), child.stderr.take())
        else {
            return Err(LinkError::Open(format!(
                "{}: no pipes to the child",
                exe.display()
            )));
        };
        let file = exe.file_name().map_or_else(
            || exe.display().to_string(),
            |f| f.to_string_lossy().into_owned(),
        );
        let name = format!("{file}, pid {}", child.id());
        let link = Self::with_parts(name, Box::new(stdout), Box::new(stdin), Some(child));
        let tail = Arc::clone(&link.stderr_tail);
        std::thread::spawn(move || {
            let mut text = String::new();
            let mut stderr = stderr;
            let mut buf = [0u8; 1024];
            while let Ok(n) = stderr.read(&mut buf) {
                if n == 0 {
                    break;
                }
                text.push_str(&String::from_utf8_lossy(&buf[..n]));
                while let Some(end) = text.find('\n') {
                    let line: String = text.drain(..=end).collect();
                    if let Ok(mut t) = tail.lock() {
                        t.push_back(line.trim_end().to_string());
                        while t.len() > STDERR_LINES {
                            t.pop_front();
                        }
                    }
                }
            }
        });
        Ok(link)
    }

    /// Connect to a kernel serving TCP at `addr` (within the reply timeout).
    pub fn tcp(addr: SocketAddr) -> Result<Self, LinkError> {
        let timeout = Timeouts::default().reply;
        let stream = TcpStream::connect_timeout(&addr, timeout)
            .map_err(|e| LinkError::Open(format!("cannot connect to tcp://{addr}: {e}")))?;
        let _ = stream.set_nodelay(true);
        let reader = stream
            .try_clone()
            .map_err(|e| LinkError::Open(format!("tcp://{addr}: {e}")))?;
        Ok(Self::with_parts(
            format!("tcp://{addr}"),
            Box::new(reader),
            Box::new(stream),
            None,
        ))
    }

    /// Use other timeouts.
    pub fn set_timeouts(&mut self, timeouts: Timeouts) {
        self.timeouts = timeouts;
    }

    /// The timeouts in use.
    pub fn timeouts(&self) -> Timeouts {
        self.timeouts
    }

    /// How messages name this link.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Send `body` and wait up to `timeout` for the reply with its request id (replies to
    /// earlier requests that timed out are skipped). A wire error in reply is
    /// [`LinkError::Refused`].
    pub fn request(&mut self, body: &ToKernel, timeout: Duration) -> Result<FromKernel, LinkError> {
        let id = self.next_id;
        self.next_id = self.next_id.wrapping_add(1).max(NO_REQUEST_ID + 1);
        let request = request_name(body);
        if self.closed {
            return Err(self.closed_error(&request, id, None));
        }
        let mut buf = [0u8; MAX_ENCODED_FRAME_LEN];
        let bytes = encode_frame(
            &Frame {
                request_id: id,
                body: body.clone(),
            },
            &mut buf,
        )
        .map_err(|e| LinkError::Open(format!("{request} does not fit a frame: {e}")))?;
        if let Err(e) = self
            .writer
            .write_all(bytes)
            .and_then(|()| self.writer.flush())
        {
            self.closed = true;
            return Err(self.closed_error(&request, id, Some(e)));
        }
        let deadline = Instant::now() + timeout;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.replies.recv_timeout(left) {
                Ok(Incoming::Reply(frame)) if frame.request_id == id => {
                    return match frame.body {
                        FromKernel::Error(error) => Err(LinkError::Refused {
                            link: self.name.clone(),
                            request,
                            id,
                            error,
                        }),
                        body => Ok(body),
                    };
                }
                // A late answer to an earlier request, or a frame-level error about garbage
                // that is not ours: keep waiting.
                Ok(Incoming::Reply(_)) | Ok(Incoming::Garbled) => {}
                Ok(Incoming::Closed(e)) => {
                    self.closed = true;
                    return Err(self.closed_error(&request, id, e));
                }
                Err(RecvTimeoutError::Timeout) => {
                    return Err(LinkError::Timeout {
                        link: self.name.clone(),
                        request,
                        id,
                        seconds: timeout.as_secs_f64(),
                    });
                }
                Err(RecvTimeoutError::Disconnected) => {
                    self.closed = true;
                    return Err(self.closed_error(&request, id, None));
                }
            }
        }
    }

    /// The error for a closed link: the child's exit status and the last lines of its stderr.
    fn closed_error(&mut self, request: &str, id: u32, cause: Option<io::Error>) -> LinkError {
        let mut detail = String::new();
        if let Some(e) = cause {
            detail.push_str(&format!(" ({e})"));
        }
        if let Some(child) = &mut self.child {
            // Give an exiting child a moment to be reaped.
            let t0 = Instant::now();
            let status = loop {
                match child.try_wait() {
                    Ok(Some(s)) => break Some(s),
                    Ok(None) if t0.elapsed() < Duration::from_millis(500) => {
                        std::thread::sleep(Duration::from_millis(10));
                    }
                    _ => break None,
                }
            };
            if let Some(s) = status {
                detail.push_str(&format!("; it exited with {s}"));
            }
            std::thread::sleep(Duration::from_millis(20));
            if let Ok(tail) = self.stderr_tail.lock()
                && !tail.is_empty()
            {
                detail.push_str("; its last stderr lines:\n  ");
                detail.push_str(&tail.iter().cloned().collect::<Vec<_>>().join("\n  "));
            }
        }
        LinkError::Closed {
            link: self.name.clone(),
            request: request.to_string(),
            id,
            detail,
        }
    }
}

impl Drop for Link {
    fn drop(&mut self) {
        if let Some(mut child) = self.child.take() {
            // Closing stdin ends the firmware's serve loop; kill it if it lingers.
            self.writer = Box::new(io::sink());
            let t0 = Instant::now();
            while t0.elapsed() < Duration::from_secs(2) {
                if let Ok(Some(_)) = child.try_wait() {
                    return;
                }
                std::thread::sleep(Duration::from_millis(10));
            }
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}
