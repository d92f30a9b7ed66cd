#!/usr/bin/env bash
# Rebuild host/report/vendor/three/: the parts of three.js that report.html's 3D view uses,
# with OrbitControls, bundled and minified by esbuild into one classic script that defines
# the global DIPS_THREE, that script gzip-compressed, and three's licence. The versions are pinned here; the result is
# committed, so building dips never needs npm or a network (dips-report embeds the file with
# include_str!). Run from anywhere: scripts/vendor-three.sh
set -euo pipefail
THREE_VERSION=0.187.0
ESBUILD_VERSION=0.25.12
root=$(cd "$(dirname "$0")/.." && pwd)
dest="$root/host/report/vendor/three"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work"
echo '{"name":"dips-vendor-three","private":true}' >package.json
npm install --no-audit --no-fund --silent "three@$THREE_VERSION" "esbuild@$ESBUILD_VERSION"
cp "$dest/entry.js" entry.js
./node_modules/.bin/esbuild entry.js --bundle --minify --format=iife --global-name=DIPS_THREE \
    --target=es2020 --legal-comments=none --log-level=warning \
    --banner:js="/* three.js $THREE_VERSION (npm package three), Copyright 2010-2026 Three.js Authors, MIT licence (LICENSE beside this file); the exports of entry.js bundled by esbuild $ESBUILD_VERSION (scripts/vendor-three.sh) */" \
    --outfile="$dest/three-dips.min.js"
# What report.html carries: the bundle gzip-compressed (a quarter of its size), which the
# page inflates with the browser's DecompressionStream. -n: no name or time, same bytes on
# every run.
gzip -9nc "$dest/three-dips.min.js" >"$dest/three-dips.min.js.gz"
gzip -dc "$dest/three-dips.min.js.gz" | cmp - "$dest/three-dips.min.js"
cp node_modules/three/LICENSE "$dest/LICENSE"
echo "$THREE_VERSION" >"$dest/VERSION"
ls -l "$dest"
