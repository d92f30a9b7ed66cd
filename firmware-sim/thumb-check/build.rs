//! The image's entry is `Reset` (no runtime crate, no linker script: lld's default layout is
//! enough to prove the image links; a board crate would supply `memory.x`).
fn main() {
    println!("cargo:rustc-link-arg-bins=--entry=Reset");
}
