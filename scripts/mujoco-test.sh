#!/usr/bin/env bash
# The MuJoCo hand (host/mujoco, docs/mujoco.md), one command: fetch MuJoCo 3.17.0 if it is
# not there (scripts/fetch-mujoco.sh), then format check, clippy with warnings as errors, docs
# and the release tests of dips-mujoco. It is a workspace of its own, so the main workspace's
# `cargo build --release` and `cargo test --workspace --release` never need MuJoCo; it builds
# into the main target dir (host/mujoco/.cargo/config.toml) with the main Cargo.lock's
# versions (scripts/mujoco-lock.sh), so what both workspaces share is built once
# (docs/mujoco.md, "CI time").
set -euo pipefail
cd "$(dirname "$0")/.."

scripts/fetch-mujoco.sh
scripts/mujoco-lock.sh
cd host/mujoco
# Cargo reads host/mujoco/.cargo/config.toml from here: it points mujoco-rs at the library.
cargo fmt --check
# The dev profile, as the main CI's clippy: the shared crates' checks are already there.
cargo clippy --all-targets -- -D warnings
RUSTDOCFLAGS="-D warnings" cargo doc --no-deps
cargo test --release -- --nocapture
echo "ok: dips-mujoco built and tested (binaries in target/release)"
