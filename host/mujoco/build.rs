//! Check that libmujoco is where mujoco-rs will link it (a clear message naming
//! scripts/fetch-mujoco.sh otherwise) and give every binary an rpath to it, so nothing needs
//! LD_LIBRARY_PATH at run time.

use std::path::PathBuf;

#[allow(dead_code, unreachable_pub)]
#[path = "src/locate.rs"]
mod locate;

fn main() {
    println!("cargo::rerun-if-env-changed={}", locate::LIB_DIR_VAR);
    println!("cargo::rerun-if-changed=src/locate.rs");
    let dir = std::env::var_os(locate::LIB_DIR_VAR).map(PathBuf::from);
    match locate::find_library(dir.as_deref()) {
        Ok(file) => {
            println!("cargo::rerun-if-changed={}", file.display());
            let dir = dir.expect("find_library succeeded, so the directory is set");
            let dir = std::fs::canonicalize(&dir).unwrap_or(dir);
            println!("cargo::rustc-link-arg=-Wl,-rpath,{}", dir.display());
        }
        Err(message) => {
            println!("cargo::error=dips-mujoco: {message}");
        }
    }
}
