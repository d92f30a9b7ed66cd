//! Where a real hand's object pose comes from ([`PoseFeed`]): a file of timestamped poses, a
//! UDP stream (what a motion-capture or AprilTag tracker sends), or the emulator's truth.
//!
//! **The pose datagram** (one UTF-8 JSON object per UDP datagram, and one per line of a pose
//! file): `{"t_s": 12.5, "position_m": [x, y, z], "quaternion_wxyz": [w, x, y, z]}`, the
//! object frame's pose in the world frame of the task scene (screwdriver: at its pivot; card:
//! its centre), in metres. `t_s` is the sender's clock in seconds: a file's poses are
//! replayed at `t_s` after the first one, a stream's latest datagram wins. The task
//! coordinates (roll, pitch, yaw or x, y, θ) are computed here, the angle unwrapped by
//! continuity from the previous pose.

use std::net::{SocketAddr, UdpSocket};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use dips_world::hand::ObjectPose;
use dips_world::scenes::{SceneKind, screwdriver};
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};
use serde::{Deserialize, Serialize};

/// One pose of the object, as a tracker sends it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PoseDatagram {
    /// The sender's time stamp (s).
    pub t_s: f64,
    /// Position of the object frame in the world (m).
    pub position_m: [f64; 3],
    /// Orientation as a unit quaternion `[w, x, y, z]` (normalised on receipt).
    pub quaternion_wxyz: [f64; 4],
}

impl PoseDatagram {
    /// The pose, refusing non-finite numbers and a zero quaternion.
    pub fn isometry(&self) -> Result<Isometry3<f64>, String> {
        let all = self.position_m.iter().chain(&self.quaternion_wxyz);
        if !all.clone().all(|x| x.is_finite()) || !self.t_s.is_finite() {
            return Err("a number is not finite".into());
        }
        let [w, x, y, z] = self.quaternion_wxyz;
        let q = Quaternion::new(w, x, y, z);
        if q.norm() < 1e-6 {
            return Err("the quaternion is zero".into());
        }
        let [px, py, pz] = self.position_m;
        Ok(Isometry3::from_parts(
            Translation3::new(px, py, pz),
            UnitQuaternion::from_quaternion(q),
        ))
    }
}

/// A pose source that cannot give a pose.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PoseError {
    /// The file cannot be read or a line is not a pose.
    #[error(
        "pose file {path} line {line}: {message} (expected {{\"t_s\", \"position_m\", \"quaternion_wxyz\"}} per line)"
    )]
    File {
        /// The file.
        path: PathBuf,
        /// 1-based line (0: the file itself).
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// The UDP socket could not be bound.
    #[error("pose stream udp:{addr}: {message}")]
    Udp {
        /// The address.
        addr: SocketAddr,
        /// What went wrong.
        message: String,
    },
    /// No pose yet, or the last one is too old.
    #[error("pose source {source_name}: {message}")]
    Stale {
        /// The source.
        source_name: String,
        /// What is missing.
        message: String,
    },
}

/// The raw angle a task's third coordinate unwraps: the screwdriver's yaw, the card's heading.
fn raw_angle(scene: SceneKind, r: &UnitQuaternion<f64>) -> f64 {
    let m = r.to_rotation_matrix();
    match scene {
        SceneKind::Screwdriver => screwdriver::euler_xyz(m.matrix())[2],
        SceneKind::Card => m[(1, 0)].atan2(m[(0, 0)]),
    }
}

/// Turns poses into task coordinates with the angle unwrapped by continuity.
#[derive(Debug, Clone)]
pub struct Unwrapper {
    scene: SceneKind,
    last: Option<(f64, f64)>,
}

impl Unwrapper {
    /// A fresh unwrapper; its first angle is taken as it is.
    pub fn new(scene: SceneKind) -> Unwrapper {
        Unwrapper { scene, last: None }
    }

    /// The task pose of `pose`.
    pub fn pose(&mut self, pose: Isometry3<f64>) -> ObjectPose {
        let raw = raw_angle(self.scene, &pose.rotation);
        let angle = match self.last {
            None => raw,
            Some((last_raw, last_angle)) => {
                let d = (raw - last_raw + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                    - std::f64::consts::PI;
                last_angle + d
            }
        };
        self.last = Some((raw, angle));
        let coords = match self.scene {
            SceneKind::Screwdriver => {
                let e = screwdriver::euler_xyz(pose.rotation.to_rotation_matrix().matrix());
                [e[0], e[1], angle]
            }
            SceneKind::Card => [pose.translation.x, pose.translation.y, angle],
        };
        ObjectPose { pose, coords }
    }
}

/// What the hand reads the object pose from.
pub trait PoseFeed: Send {
    /// The source's name, as results record it.
    fn name(&self) -> String;
    /// The object pose now.
    fn pose(&self) -> Result<ObjectPose, PoseError>;
}

/// The emulator's simulated object.
pub struct TruthFeed {
    read: Box<dyn Fn() -> Option<ObjectPose> + Send + Sync>,
}

impl std::fmt::Debug for TruthFeed {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("TruthFeed")
    }
}

impl TruthFeed {
    /// A feed that reads the pose with `read`.
    pub fn new(read: impl Fn() -> Option<ObjectPose> + Send + Sync + 'static) -> TruthFeed {
        TruthFeed {
            read: Box::new(read),
        }
    }
}

impl PoseFeed for TruthFeed {
    fn name(&self) -> String {
        "truth".into()
    }

    fn pose(&self) -> Result<ObjectPose, PoseError> {
        (self.read)().ok_or_else(|| PoseError::Stale {
            source_name: self.name(),
            message: "the emulated plant simulates no object".into(),
        })
    }
}

/// A file of poses replayed in time: the pose at `t_s ≤` the time since the feed opened.
#[derive(Debug)]
pub struct FileFeed {
    path: PathBuf,
    poses: Vec<(f64, ObjectPose)>,
    opened: Instant,
}

impl FileFeed {
    /// Read every line of `path` (blank lines skipped); `t_s` must not decrease.
    pub fn open(path: &Path, scene: SceneKind) -> Result<FileFeed, PoseError> {
        let err = |line, message: String| PoseError::File {
            path: path.to_path_buf(),
            line,
            message,
        };
        let text = std::fs::read_to_string(path).map_err(|e| err(0, e.to_string()))?;
        let mut unwrap = Unwrapper::new(scene);
        let mut poses: Vec<(f64, ObjectPose)> = Vec::new();
        for (i, line) in text.lines().enumerate() {
            if line.trim().is_empty() {
                continue;
            }
            let d: PoseDatagram =
                serde_json::from_str(line).map_err(|e| err(i + 1, e.to_string()))?;
            let iso = d.isometry().map_err(|m| err(i + 1, m))?;
            if let Some((t, _)) = poses.last()
                && d.t_s < *t
            {
                return Err(err(i + 1, format!("t_s {} goes back from {t}", d.t_s)));
            }
            poses.push((d.t_s, unwrap.pose(iso)));
        }
        if poses.is_empty() {
            return Err(err(0, "no poses".into()));
        }
        let t0 = poses[0].0;
        for p in &mut poses {
            p.0 -= t0;
        }
        Ok(FileFeed {
            path: path.to_path_buf(),
            poses,
            opened: Instant::now(),
        })
    }
}

impl PoseFeed for FileFeed {
    fn name(&self) -> String {
        format!("file:{}", self.path.display())
    }

    fn pose(&self) -> Result<ObjectPose, PoseError> {
        let t = self.opened.elapsed().as_secs_f64();
        let i = self.poses.partition_point(|(ts, _)| *ts <= t).max(1) - 1;
        Ok(self.poses[i].1.clone())
    }
}

/// The latest pose of a UDP stream, received on its own thread.
#[derive(Debug)]
pub struct UdpFeed {
    addr: SocketAddr,
    latest: Arc<Mutex<Option<(Instant, ObjectPose)>>>,
    bad: Arc<Mutex<u64>>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    max_age: Duration,
}

impl UdpFeed {
    /// Bind `addr` and receive poses; a pose older than `max_age` is stale.
    pub fn open(
        addr: SocketAddr,
        scene: SceneKind,
        max_age: Duration,
    ) -> Result<UdpFeed, PoseError> {
        let err = |m: String| PoseError::Udp { addr, message: m };
        let socket = UdpSocket::bind(addr).map_err(|e| err(e.to_string()))?;
        socket
            .set_read_timeout(Some(Duration::from_millis(20)))
            .map_err(|e| err(e.to_string()))?;
        let latest = Arc::new(Mutex::new(None));
        let bad = Arc::new(Mutex::new(0));
        let stop = Arc::new(AtomicBool::new(false));
        let (l, b, s) = (latest.clone(), bad.clone(), stop.clone());
        let thread = std::thread::Builder::new()
            .name("pose-udp".into())
            .spawn(move || {
                let mut unwrap = Unwrapper::new(scene);
                let mut buf = [0u8; 2048];
                while !s.load(Ordering::SeqCst) {
                    let Ok(n) = socket.recv(&mut buf) else {
                        continue;
                    };
                    let parsed = std::str::from_utf8(&buf[..n])
                        .ok()
                        .and_then(|t| serde_json::from_str::<PoseDatagram>(t).ok())
                        .and_then(|d| d.isometry().ok());
                    match parsed {
                        Some(iso) => {
                            let p = unwrap.pose(iso);
                            if let Ok(mut g) = l.lock() {
                                *g = Some((Instant::now(), p));
                            }
                        }
                        None => {
                            if let Ok(mut g) = b.lock() {
                                *g += 1;
                            }
                        }
                    }
                }
            })
            .map_err(|e| err(e.to_string()))?;
        Ok(UdpFeed {
            addr,
            latest,
            bad,
            stop,
            thread: Some(thread),
            max_age,
        })
    }

    /// Datagrams that were not poses (counted and ignored).
    pub fn bad_datagrams(&self) -> u64 {
        self.bad.lock().map(|g| *g).unwrap_or(0)
    }
}

impl PoseFeed for UdpFeed {
    fn name(&self) -> String {
        format!("udp:{}", self.addr)
    }

    fn pose(&self) -> Result<ObjectPose, PoseError> {
        let stale = |message: String| PoseError::Stale {
            source_name: self.name(),
            message,
        };
        let g = self
            .latest
            .lock()
            .map_err(|_| stale("receiver failed".into()))?;
        match &*g {
            None => Err(stale("no pose received yet".into())),
            Some((t, p)) if t.elapsed() <= self.max_age => Ok(p.clone()),
            Some((t, _)) => Err(stale(format!(
                "last pose {:.0} ms old (limit {:.0} ms)",
                t.elapsed().as_secs_f64() * 1e3,
                self.max_age.as_secs_f64() * 1e3
            ))),
        }
    }
}

impl Drop for UdpFeed {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn datagram(t: f64, x: f64, yaw: f64) -> String {
        let (s, c) = (0.5 * yaw).sin_cos();
        format!(
            r#"{{"t_s": {t}, "position_m": [{x}, 0.1, 0.02], "quaternion_wxyz": [{c}, 0, 0, {s}]}}"#
        )
    }

    #[test]
    fn a_file_replays_in_time_and_unwraps_the_heading() {
        let dir = std::env::temp_dir().join(format!("dips-pose-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("poses.jsonl");
        let lines = [datagram(10.0, 0.01, 3.1), datagram(10.02, 0.02, -3.1)].join("\n");
        std::fs::write(&path, lines).unwrap();
        let feed = FileFeed::open(&path, SceneKind::Card).unwrap();
        let p = feed.pose().unwrap();
        assert!((p.coords[0] - 0.01).abs() < 1e-12);
        std::thread::sleep(Duration::from_millis(30));
        let p = feed.pose().unwrap();
        // −3.1 after 3.1 is a turn of 0.083 rad past π, not back by 6.2.
        assert!(
            (p.coords[2] - (std::f64::consts::TAU - 3.1)).abs() < 1e-9,
            "{:?}",
            p.coords
        );
        std::fs::write(&path, "{\"t_s\": 1}").unwrap();
        let e = FileFeed::open(&path, SceneKind::Card)
            .unwrap_err()
            .to_string();
        assert!(e.contains("line 1") && e.contains("position_m"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_udp_stream_gives_its_latest_pose_and_counts_bad_datagrams() {
        let feed = UdpFeed::open(
            "127.0.0.1:0".parse().unwrap(),
            SceneKind::Card,
            Duration::from_millis(500),
        );
        // Port 0 binds an ephemeral port, which the feed does not report: bind a known one.
        drop(feed);
        let probe = UdpSocket::bind("127.0.0.1:0").unwrap();
        let addr = probe.local_addr().unwrap();
        drop(probe);
        let feed = UdpFeed::open(addr, SceneKind::Card, Duration::from_millis(500)).unwrap();
        assert!(matches!(feed.pose(), Err(PoseError::Stale { .. })));
        let tx = UdpSocket::bind("127.0.0.1:0").unwrap();
        tx.send_to(b"not a pose", addr).unwrap();
        tx.send_to(datagram(0.0, 0.03, 0.2).as_bytes(), addr)
            .unwrap();
        let deadline = Instant::now() + Duration::from_secs(2);
        while feed.pose().is_err() && Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(5));
        }
        let p = feed.pose().unwrap();
        assert!((p.coords[0] - 0.03).abs() < 1e-12 && (p.coords[2] - 0.2).abs() < 1e-9);
        assert_eq!(feed.bad_datagrams(), 1);
    }
}
