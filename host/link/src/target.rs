//! Where the kernel is: `--kernel in-process | spawn | spawn:PATH | tcp://HOST:PORT`.

use std::net::{SocketAddr, ToSocketAddrs};
use std::path::PathBuf;

use crate::transport::{Link, LinkError};

/// The environment variable naming the `dips-firmware-sim` binary `spawn` starts.
pub const FIRMWARE_ENV: &str = "DIPS_FIRMWARE_SIM";

/// A kernel target that is none of the allowed forms ([`KernelTarget::parse`]).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("kernel target {given}: {why}expected in-process, spawn, spawn:PATH or tcp://HOST:PORT")]
pub struct KernelTargetError {
    /// The target given.
    pub given: String,
    /// What is wrong with it beyond not being one of the forms (empty, or ending in `; `).
    pub why: &'static str,
}

/// Where planning calls are made.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum KernelTarget {
    /// The kernel in this process (the default).
    InProcess,
    /// `dips-firmware-sim` started as a child over stdin/stdout; `None`: [`find_firmware`].
    Spawn(Option<PathBuf>),
    /// A kernel serving TCP (`dips-firmware-sim --listen ADDR`).
    Tcp(String),
}

impl KernelTarget {
    /// Parse `in-process`, `spawn`, `spawn:PATH` or `tcp://HOST:PORT`; the error names the
    /// allowed forms.
    pub fn parse(s: &str) -> Result<Self, KernelTargetError> {
        let error = |why| KernelTargetError {
            given: s.to_string(),
            why,
        };
        if s == "in-process" {
            Ok(Self::InProcess)
        } else if s == "spawn" {
            Ok(Self::Spawn(None))
        } else if let Some(path) = s.strip_prefix("spawn:") {
            if path.is_empty() {
                return Err(error("no path after spawn:; "));
            }
            Ok(Self::Spawn(Some(PathBuf::from(path))))
        } else if let Some(addr) = s.strip_prefix("tcp://") {
            if addr
                .rsplit_once(':')
                .is_none_or(|(h, p)| h.is_empty() || p.parse::<u16>().is_err())
            {
                return Err(error("not HOST:PORT after tcp://; "));
            }
            Ok(Self::Tcp(addr.to_string()))
        } else {
            Err(error(""))
        }
    }

    /// Whether plans are made in this process.
    pub fn in_process(&self) -> bool {
        *self == Self::InProcess
    }

    /// Open a link to the kernel (`None` for [`Self::InProcess`]).
    pub fn open(&self) -> Result<Option<Link>, LinkError> {
        match self {
            Self::InProcess => Ok(None),
            Self::Spawn(path) => {
                let exe = match path {
                    Some(p) => p.clone(),
                    None => find_firmware()?,
                };
                Link::spawn(&exe, &[]).map(Some)
            }
            Self::Tcp(addr) => {
                let resolved: SocketAddr = addr
                    .to_socket_addrs()
                    .map_err(|e| LinkError::Open(format!("tcp://{addr}: {e}")))?
                    .next()
                    .ok_or_else(|| LinkError::Open(format!("tcp://{addr}: no address")))?;
                Link::tcp(resolved).map(Some)
            }
        }
    }
}

impl std::fmt::Display for KernelTarget {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::InProcess => f.write_str("in-process"),
            Self::Spawn(None) => f.write_str("spawn"),
            Self::Spawn(Some(p)) => write!(f, "spawn:{}", p.display()),
            Self::Tcp(a) => write!(f, "tcp://{a}"),
        }
    }
}

/// Why no `dips-firmware-sim` binary was found ([`find_firmware`]).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum NoFirmware {
    /// `$DIPS_FIRMWARE_SIM` names no file.
    #[error("$DIPS_FIRMWARE_SIM names {}, which is not a file", path.display())]
    EnvNotAFile {
        /// The path it names.
        path: PathBuf,
    },
    /// None of the places looked in has the binary.
    #[error(
        "no {name} found (tried {}); build it with `cargo build --release -p dips-firmware-sim`, \
         or set $DIPS_FIRMWARE_SIM, or give the kernel target spawn:PATH",
        tried.join(", ")
    )]
    NotFound {
        /// The binary's file name.
        name: String,
        /// Where it was looked for.
        tried: Vec<String>,
    },
}

/// The `dips-firmware-sim` binary: `$DIPS_FIRMWARE_SIM`, else the one beside this program
/// (a cargo build puts both in `target/<profile>/`), else one on `PATH`. The error lists
/// what was tried.
pub fn find_firmware() -> Result<PathBuf, NoFirmware> {
    let name = format!("dips-firmware-sim{}", std::env::consts::EXE_SUFFIX);
    if let Some(p) = std::env::var_os(FIRMWARE_ENV) {
        let path = PathBuf::from(p);
        return if path.is_file() {
            Ok(path)
        } else {
            Err(NoFirmware::EnvNotAFile { path })
        };
    }
    let mut tried = Vec::new();
    if let Ok(exe) = std::env::current_exe()
        && let Some(dir) = exe.parent()
    {
        // Beside this program, and one level up (test binaries live in target/*/deps).
        for d in [dir, dir.parent().unwrap_or(dir)] {
            let p = d.join(&name);
            if p.is_file() {
                return Ok(p);
            }
            tried.push(p.display().to_string());
        }
    }
    if let Some(path) = std::env::var_os("PATH") {
        for d in std::env::split_paths(&path) {
            let p = d.join(&name);
            if p.is_file() {
                return Ok(p);
            }
        }
        tried.push("every directory on PATH".into());
    }
    Err(NoFirmware::NotFound { name, tried })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn targets_parse_and_bad_ones_name_the_forms() {
        assert_eq!(
            KernelTarget::parse("in-process"),
            Ok(KernelTarget::InProcess)
        );
        assert_eq!(KernelTarget::parse("spawn"), Ok(KernelTarget::Spawn(None)));
        assert_eq!(
            KernelTarget::parse("spawn:/x/fw"),
            Ok(KernelTarget::Spawn(Some("/x/fw".into())))
        );
        assert_eq!(
            KernelTarget::parse("tcp://127.0.0.1:7000"),
            Ok(KernelTarget::Tcp("127.0.0.1:7000".into()))
        );
        for bad in [
            "",
            "tcp://host",
            "tcp://:80",
            "tcp://h:port",
            "spawn:",
            "udp://h:1",
        ] {
            let e = KernelTarget::parse(bad).unwrap_err();
            assert_eq!(e.given, bad);
            let e = e.to_string();
            assert!(e.contains("tcp://HOST:PORT"), "{bad}: {e}");
        }
        assert_eq!(KernelTarget::Tcp("h:1".into()).to_string(), "tcp://h:1");
    }
}
