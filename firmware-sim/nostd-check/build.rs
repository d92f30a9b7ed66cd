//! rustc links a `#![no_std]` binary with `-nodefaultlibs`; libc supplies `_start`, `write`,
//! `_exit` and the `mem*` functions that core calls.
fn main() {
    println!("cargo:rustc-link-arg-bins=-lc");
}
