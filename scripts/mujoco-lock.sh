#!/usr/bin/env bash
# host/mujoco/Cargo.lock must pin every crate it shares with the main workspace at the main
# Cargo.lock's version, so that the two workspaces share their builds in the main target dir
# (docs/mujoco.md, "CI time"). `scripts/mujoco-lock.sh` checks it (scripts/mujoco-test.sh runs
# the check); `scripts/mujoco-lock.sh --sync` rewrites host/mujoco/Cargo.lock from the main one
# (cargo then adds the MuJoCo-only crates and drops what dips-mujoco does not use).
set -euo pipefail
cd "$(dirname "$0")/.."

if [[ "${1:-}" == "--sync" ]]; then
    cp Cargo.lock host/mujoco/Cargo.lock
    (cd host/mujoco && cargo tree --offline --depth 0 >/dev/null 2>&1 || cargo tree --depth 0 >/dev/null)
    echo "host/mujoco/Cargo.lock synced with Cargo.lock"
fi

# `name version` of every registry package of a lock file.
pairs() { awk '/^name = /{n=$3} /^version = /{v=$3} /^source = "registry/{print n, v}' "$1" | tr -d '"' | sort -u; }
# The MuJoCo-only crates: the binding and what only it pulls in.
only_mujoco='^(mujoco-rs) '
stale=$(comm -23 <(pairs host/mujoco/Cargo.lock | grep -Ev "$only_mujoco") <(pairs Cargo.lock))
if [[ -n "$stale" ]]; then
    echo "error: host/mujoco/Cargo.lock pins versions the main Cargo.lock does not have:" >&2
    sed 's/^/    /' <<<"$stale" >&2
    echo "run scripts/mujoco-lock.sh --sync (docs/mujoco.md, \"CI time\")" >&2
    exit 1
fi
echo "ok: host/mujoco/Cargo.lock pins the main Cargo.lock's versions ($(pairs host/mujoco/Cargo.lock | wc -l) registry crates)"
