#!/usr/bin/env bash
# Fetch MuJoCo 3.17.0 (shared library and headers) for the MuJoCo hand (host/mujoco,
# docs/mujoco.md) from the PyPI wheel `mujoco==3.17.0` into .mujoco/3.17.0/{lib,include}
# (git ignores .mujoco/). No virtualenv, no system install: pip only downloads the wheel.
# Idempotent: does nothing when the library is already there.
set -euo pipefail
cd "$(dirname "$0")/.."

version=3.17.0
dest=.mujoco/$version
lib=$dest/lib/libmujoco.so.$version

if [[ -f $lib && -L $dest/lib/libmujoco.so ]]; then
    echo "ok: MuJoCo $version already in $dest"
    exit 0
fi
case "$(uname -s)-$(uname -m)" in
    Linux-x86_64 | Linux-aarch64) ;;
    *) echo "error: scripts/fetch-mujoco.sh handles Linux x86_64/aarch64 wheels only" >&2; exit 1 ;;
esac

tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
python3 -m pip download --quiet --no-deps "mujoco==$version" --only-binary :all: -d "$tmp"
wheel=$(find "$tmp" -maxdepth 1 -name "mujoco-$version-*.whl" | head -n 1)
if [[ -z $wheel ]]; then
    echo "error: pip downloaded no mujoco-$version wheel" >&2
    exit 1
fi

# Unpack only the library and the headers (python's zipfile: no unzip needed).
rm -rf "$dest.partial"
mkdir -p "$dest.partial/lib" "$dest.partial/include"
python3 - "$wheel" "$dest.partial" "$version" <<'PY'
import pathlib, shutil, sys, zipfile
wheel, dest, version = sys.argv[1], pathlib.Path(sys.argv[2]), sys.argv[3]
with zipfile.ZipFile(wheel) as z:
    for name in z.namelist():
        if name.endswith("/"):
            continue
        if name == f"mujoco/libmujoco.so.{version}":
            out = dest / "lib" / f"libmujoco.so.{version}"
        elif name.startswith("mujoco/include/"):
            out = dest / "include" / name[len("mujoco/include/"):]
        else:
            continue
        out.parent.mkdir(parents=True, exist_ok=True)
        with z.open(name) as src, open(out, "wb") as dst:
            shutil.copyfileobj(src, dst)
PY
if [[ ! -f $dest.partial/lib/libmujoco.so.$version ]]; then
    echo "error: the wheel $wheel holds no libmujoco.so.$version" >&2
    exit 1
fi
# The linker looks for libmujoco.so; the library's SONAME is the versioned file.
ln -s "libmujoco.so.$version" "$dest.partial/lib/libmujoco.so"
rm -rf "$dest"
mv "$dest.partial" "$dest"
echo "ok: MuJoCo $version in $dest (from $(basename "$wheel"))"
