//! Where libmujoco is and whether it is the one this crate is built for. Shared with
//! `build.rs` (included there by path), so the build and the run time say the same thing.

use std::path::{Path, PathBuf};

/// The MuJoCo release this crate is built and tested against (mujoco-rs 7.0.0's bindings).
pub const MUJOCO_VERSION: &str = "3.17.0";

/// [`MUJOCO_VERSION`] as `mj_version()` reports it (major·10⁶ + minor·10³ + patch).
pub const MUJOCO_VERSION_NUMBER: u32 = 3_017_000;

/// The script that puts the library where the build looks for it.
pub const FETCH_SCRIPT: &str = "scripts/fetch-mujoco.sh";

/// The environment variable naming the library's folder (mujoco-rs's dynamic-link variable;
/// `host/mujoco/.cargo/config.toml` sets it to `.mujoco/3.17.0/lib`).
pub const LIB_DIR_VAR: &str = "MUJOCO_DYNAMIC_LINK_DIR";

/// The versioned library file in `dir` (its SONAME, which the binaries load).
pub fn library_file(dir: &Path) -> PathBuf {
    dir.join(format!("libmujoco.so.{MUJOCO_VERSION}"))
}

/// Check that `dir` (the value of [`LIB_DIR_VAR`], `None` when unset) holds MuJoCo
/// [`MUJOCO_VERSION`]; the error message says what is missing and names [`FETCH_SCRIPT`].
pub fn find_library(dir: Option<&Path>) -> Result<PathBuf, String> {
    let Some(dir) = dir else {
        return Err(format!(
            "{LIB_DIR_VAR} is not set: build dips-mujoco from host/mujoco (its .cargo/config.toml \
             sets it) after running {FETCH_SCRIPT}, or use scripts/mujoco-test.sh"
        ));
    };
    let file = library_file(dir);
    if !file.is_file() {
        return Err(format!(
            "MuJoCo {MUJOCO_VERSION} is missing: {} does not exist; run {FETCH_SCRIPT}",
            file.display()
        ));
    }
    if !dir.join("libmujoco.so").exists() {
        return Err(format!(
            "{} has no libmujoco.so link for the linker; run {FETCH_SCRIPT} again",
            dir.display()
        ));
    }
    Ok(file)
}

/// The error message for a linked library of version number `found` (as `mj_version()`
/// reports it), or `None` when it is [`MUJOCO_VERSION_NUMBER`].
pub fn version_mismatch(found: u32) -> Option<String> {
    (found != MUJOCO_VERSION_NUMBER).then(|| {
        format!(
            "the linked MuJoCo library is version {}.{}.{} but dips-mujoco needs {MUJOCO_VERSION}; \
             run {FETCH_SCRIPT} and rebuild (scripts/mujoco-test.sh)",
            found / 1_000_000,
            found / 1000 % 1000,
            found % 1000
        )
    })
}
