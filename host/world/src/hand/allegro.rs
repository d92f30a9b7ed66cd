//! How to open the real (or emulated) Allegro hand, as `--hand allegro:…` spells it
//! ([`AllegroOptions`]): `allegro:IFACE[,gains=vendor|paper|FILE][,pose=SOURCE][,fault=F]…
//! [,dry-run]`. The driver (`dips-allegro`) reads these; this module only parses and prints
//! them, so that every crate that names a hand (results, evaluations) can without the driver.

use std::fmt;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::str::FromStr;
use std::time::Duration;

/// Which bus the hand is on.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub enum AllegroBus {
    /// The emulated hand on an in-process bus (`allegro:emulated`).
    Emulated,
    /// A SocketCAN interface (`allegro:can0`).
    Interface(String),
}

/// What moves the emulated hand's joints.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub enum EmulatedPlant {
    /// The joint model with our quasi-static world moving the object (the `dips` binary).
    #[default]
    JointModel,
    /// MuJoCo's dynamics of the hand and object (the `dips-mujoco` binary).
    Mujoco,
}

impl EmulatedPlant {
    /// The plant's name, as `plant=` spells it.
    pub fn name(self) -> &'static str {
        match self {
            EmulatedPlant::JointModel => "joint-model",
            EmulatedPlant::Mujoco => "mujoco",
        }
    }
}

impl FromStr for EmulatedPlant {
    type Err = BadAllegro;

    fn from_str(s: &str) -> Result<EmulatedPlant, BadAllegro> {
        match s {
            "joint-model" => Ok(EmulatedPlant::JointModel),
            "mujoco" => Ok(EmulatedPlant::Mujoco),
            _ => Err(BadAllegro::UnknownOption(format!("plant={s}"))),
        }
    }
}

impl fmt::Display for EmulatedPlant {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The PD gains to run.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub enum GainsChoice {
    /// The vendor's `gains_pd.yaml` (the default).
    Vendor,
    /// The DIPS authors' hardware controller: vendor gains, error and torque clamps, gravity
    /// compensation.
    Paper,
    /// A gains file (JSON).
    File(PathBuf),
}

/// Where the object's pose comes from.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub enum PoseSource {
    /// The emulator's simulated object (emulated hands only; their default).
    Truth,
    /// A file of timestamped poses (`pose=file:PATH`).
    File(PathBuf),
    /// A UDP stream of pose datagrams (`pose=udp:ADDR:PORT`), what a tracker sends.
    Udp(SocketAddr),
}

/// A fault the emulated hand injects (`fault=…`, emulated hands only).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum EmulatorFault {
    /// `silence@T`: from T seconds after the servo first comes on, the hand sends nothing.
    SilenceAt(Duration),
    /// `garbage`: malformed frames after every pose set.
    Garbage,
    /// `hot@T`: from T seconds after servo on, the joints read 95 °C and the hand's
    /// high-temperature bit is set.
    HotAt(Duration),
}

/// Everything `--hand allegro:…` says.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct AllegroOptions {
    /// The bus.
    pub bus: AllegroBus,
    /// The gains.
    pub gains: GainsChoice,
    /// The object pose source (`None`: the emulator's truth; a real bus needs one).
    pub pose: Option<PoseSource>,
    /// Faults to inject (emulated only).
    pub faults: Vec<EmulatorFault>,
    /// The emulated hand's plant (`plant=joint-model|mujoco`; emulated and dry runs only).
    pub plant: EmulatedPlant,
    /// Print every frame the driver sends instead of opening the bus: the driver runs
    /// against the emulated hand, and nothing reaches a real bus.
    pub dry_run: bool,
}

/// A `--hand allegro:…` that cannot be used.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum BadAllegro {
    /// No interface named.
    #[error(
        "`{0}`: name the bus, `allegro:emulated` or `allegro:IFACE` (e.g. allegro:can0), then \
         options gains=vendor|paper|FILE, pose=file:PATH|udp:ADDR:PORT|truth, fault=silence@T|garbage|hot@T, plant=joint-model|mujoco, dry-run"
    )]
    NoBus(String),
    /// An option this spec does not have.
    #[error(
        "`{0}` is not an allegro option (allowed: gains=vendor|paper|FILE, \
         pose=file:PATH|udp:ADDR:PORT|truth, fault=silence@T|garbage|hot@T, plant=joint-model|mujoco, dry-run)"
    )]
    UnknownOption(String),
    /// A pose source that does not parse.
    #[error("pose `{0}`: expected file:PATH, udp:ADDR:PORT (e.g. udp:0.0.0.0:9870) or truth")]
    BadPose(String),
    /// A fault that does not parse.
    #[error(
        "fault `{0}`: expected silence@SECONDS, garbage or hot@SECONDS (e.g. silence@2, hot@0.5)"
    )]
    BadFault(String),
    /// Faults or the truth pose asked of a real bus.
    #[error("`{0}` needs the emulated hand (allegro:emulated): a real hand has no {1}")]
    EmulatedOnly(String, &'static str),
    /// A real bus without a pose source.
    #[error(
        "allegro:{0} needs an object pose source: add pose=file:PATH or pose=udp:ADDR:PORT \
         (docs/allegro.md, 'Object pose')"
    )]
    NoPose(String),
}

fn seconds(s: &str) -> Option<Duration> {
    let t: f64 = s.parse().ok()?;
    (t.is_finite() && t >= 0.0).then(|| Duration::from_secs_f64(t))
}

impl FromStr for EmulatorFault {
    type Err = BadAllegro;

    fn from_str(s: &str) -> Result<EmulatorFault, BadAllegro> {
        let bad = || BadAllegro::BadFault(s.to_string());
        match s.split_once('@') {
            None if s == "garbage" => Ok(EmulatorFault::Garbage),
            Some(("silence", t)) => Ok(EmulatorFault::SilenceAt(seconds(t).ok_or_else(bad)?)),
            Some(("hot", t)) => Ok(EmulatorFault::HotAt(seconds(t).ok_or_else(bad)?)),
            _ => Err(bad()),
        }
    }
}

impl fmt::Display for EmulatorFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EmulatorFault::SilenceAt(t) => write!(f, "silence@{}", t.as_secs_f64()),
            EmulatorFault::Garbage => f.write_str("garbage"),
            EmulatorFault::HotAt(t) => write!(f, "hot@{}", t.as_secs_f64()),
        }
    }
}

impl FromStr for PoseSource {
    type Err = BadAllegro;

    fn from_str(s: &str) -> Result<PoseSource, BadAllegro> {
        let bad = || BadAllegro::BadPose(s.to_string());
        match s.split_once(':') {
            None if s == "truth" => Ok(PoseSource::Truth),
            Some(("file", p)) if !p.is_empty() => Ok(PoseSource::File(PathBuf::from(p))),
            Some(("udp", a)) => Ok(PoseSource::Udp(a.parse().map_err(|_| bad())?)),
            _ => Err(bad()),
        }
    }
}

impl fmt::Display for PoseSource {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PoseSource::Truth => f.write_str("truth"),
            PoseSource::File(p) => write!(f, "file:{}", p.display()),
            PoseSource::Udp(a) => write!(f, "udp:{a}"),
        }
    }
}

impl AllegroOptions {
    /// Parse what follows `allegro:`.
    pub fn parse(spec: &str) -> Result<AllegroOptions, BadAllegro> {
        let mut parts = spec.split(',');
        let bus = match parts.next().unwrap_or("") {
            "" => return Err(BadAllegro::NoBus(format!("allegro:{spec}"))),
            "emulated" => AllegroBus::Emulated,
            iface => AllegroBus::Interface(iface.to_string()),
        };
        let mut o = AllegroOptions {
            bus,
            gains: GainsChoice::Vendor,
            pose: None,
            faults: Vec::new(),
            plant: EmulatedPlant::JointModel,
            dry_run: false,
        };
        for part in parts {
            match part.split_once('=') {
                Some(("gains", "vendor")) => o.gains = GainsChoice::Vendor,
                Some(("gains", "paper")) => o.gains = GainsChoice::Paper,
                Some(("gains", file)) if !file.is_empty() => {
                    o.gains = GainsChoice::File(PathBuf::from(file))
                }
                Some(("pose", p)) => o.pose = Some(p.parse()?),
                Some(("fault", f)) => o.faults.push(f.parse()?),
                Some(("plant", p)) => o.plant = p.parse()?,
                None if part == "dry-run" => o.dry_run = true,
                _ => return Err(BadAllegro::UnknownOption(part.to_string())),
            }
        }
        if o.bus != AllegroBus::Emulated {
            if let Some(f) = o.faults.first() {
                return Err(BadAllegro::EmulatedOnly(
                    format!("fault={f}"),
                    "injected faults",
                ));
            }
            if o.pose == Some(PoseSource::Truth) {
                return Err(BadAllegro::EmulatedOnly(
                    "pose=truth".into(),
                    "simulated object",
                ));
            }
        }
        Ok(o)
    }
}

impl fmt::Display for AllegroOptions {
    /// The spec back, as it parses: `emulated,gains=paper,fault=silence@2`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.bus {
            AllegroBus::Emulated => f.write_str("emulated")?,
            AllegroBus::Interface(i) => f.write_str(i)?,
        }
        match &self.gains {
            GainsChoice::Vendor => {}
            GainsChoice::Paper => f.write_str(",gains=paper")?,
            GainsChoice::File(p) => write!(f, ",gains={}", p.display())?,
        }
        if let Some(p) = &self.pose {
            write!(f, ",pose={p}")?;
        }
        for fault in &self.faults {
            write!(f, ",fault={fault}")?;
        }
        if self.plant == EmulatedPlant::Mujoco {
            f.write_str(",plant=mujoco")?;
        }
        if self.dry_run {
            f.write_str(",dry-run")?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn specs_round_trip_and_bad_ones_name_the_problem() {
        for s in [
            "emulated",
            "emulated,gains=paper,fault=silence@2,fault=garbage",
            "emulated,fault=hot@0.5,dry-run",
            "emulated,gains=paper,plant=mujoco",
            "can0,gains=/etc/gains.json,pose=udp:0.0.0.0:9870",
            "can0,pose=file:poses.jsonl",
        ] {
            let o = AllegroOptions::parse(s).unwrap();
            assert_eq!(o.to_string(), s);
        }
        let o = AllegroOptions::parse("emulated,fault=silence@2").unwrap();
        assert_eq!(o.faults, [EmulatorFault::SilenceAt(Duration::from_secs(2))]);
        let err = |s: &str| AllegroOptions::parse(s).unwrap_err().to_string();
        assert!(err("").contains("name the bus"));
        assert!(AllegroOptions::parse("can0").unwrap().pose.is_none());
        assert!(err("can0,pose=truth").contains("needs the emulated hand"));
        assert!(err("can0,pose=udp:1.2.3.4:5,fault=garbage").contains("needs the emulated hand"));
        assert_eq!(
            err("emulated,speed=2"),
            "`speed=2` is not an allegro option (allowed: gains=vendor|paper|FILE, \
             pose=file:PATH|udp:ADDR:PORT|truth, fault=silence@T|garbage|hot@T, plant=joint-model|mujoco, dry-run)"
        );
        assert!(err("emulated,fault=silence@-1").starts_with("fault `silence@-1`"));
        assert!(err("emulated,fault=boom").starts_with("fault `boom`"));
        assert!(err("emulated,pose=udp:nowhere").starts_with("pose `udp:nowhere`"));
    }
}
