//! `dips-fs`: the one atomic file write of the host crates, std only, so that every crate
//! that writes results, models, datasets or shard records can use it (`dips-world` and
//! `dips-dataset` at the bottom included) without pulling anything in.
//!
//! [`write_atomic`] writes a temporary file in the target's folder, named after this host,
//! process and call, syncs it and renames it over the target: a reader sees the old file or
//! the new one, never half of one, and shards on several hosts sharing one folder (a cluster's
//! shared filesystem) never write the same temporary file.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// This machine's name (`/proc/sys/kernel/hostname`, else `$HOSTNAME`, else `unknown`).
pub fn hostname() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .ok()
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty())
        .or_else(|| std::env::var("HOSTNAME").ok())
        .unwrap_or_else(|| "unknown".into())
}

/// Write `bytes` to `path` atomically: a temporary file in the same folder named after this
/// host, process and call (`PATH.tmp-HOST-PID-N`, unique even when shards on several hosts
/// share the folder), synced, then renamed over `path`. On an error the temporary file is
/// removed and `path` is left as it was.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    static CALLS: AtomicU64 = AtomicU64::new(0);
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(format!(
        ".tmp-{}-{}-{}",
        hostname(),
        std::process::id(),
        CALLS.fetch_add(1, Ordering::Relaxed)
    ));
    let tmp = PathBuf::from(tmp);
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("dips-fs-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn writes_replaces_and_leaves_no_temporary_file() {
        let d = dir("write");
        let path = d.join("a.json");
        write_atomic(&path, b"first").unwrap();
        write_atomic(&path, b"second").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"second");
        let names: Vec<_> = std::fs::read_dir(&d)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, ["a.json"]);
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_failed_write_leaves_the_target_and_no_temporary_file() {
        let d = dir("fail");
        let path = d.join("a.json");
        write_atomic(&path, b"kept").unwrap();
        // A directory where the file should go: the rename fails.
        let blocked = d.join("sub");
        std::fs::create_dir_all(blocked.join("x")).unwrap();
        assert!(write_atomic(&blocked, b"lost").is_err());
        assert!(write_atomic(&d.join("missing").join("b.json"), b"lost").is_err());
        assert_eq!(std::fs::read(&path).unwrap(), b"kept");
        let mut names: Vec<_> = std::fs::read_dir(&d)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        names.sort();
        assert_eq!(names, ["a.json", "sub"]);
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn the_host_has_a_name() {
        assert!(!hostname().is_empty());
    }
}
