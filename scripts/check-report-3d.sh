#!/usr/bin/env bash
# report.html's 3D view in headless Chromium (docs/pictures.md, "The 3D view"): for one
# screwdriver and one card episode published under docs/results, write the report again from
# its result.json (dips-report's example episode_report) and check in Debian's chromium that
#   - the page loads with no console error or warning, uncaught error or rejected promise,
#     and the view says it is ready (WebGL through SwiftShader, no GPU needed);
#   - moving the slider moves the hand: the fingertips drawn at the first and the last state
#     differ, and each is where the embedded data (our forward kinematics) puts it;
#   - the play button plays: 3 s after a click the view shows a later state;
#   - the canvas draws: a screenshot's canvas area holds the coloured hand and object.
# Installs chromium with apt-get when it is missing; if that fails, says "skipped" and exits
# 0. `--keep DIR` keeps the screenshots (DIR/<task>.png; docs/pictures/report-3d.png is one).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
keep=
if [[ ${1:-} == --keep ]]; then
    keep=$(realpath -m "${2:?--keep needs a directory}")
    mkdir -p "$keep"
fi

if ! command -v chromium >/dev/null 2>&1; then
    echo "chromium is missing: installing Debian's package"
    if ! { timeout 300 apt-get update &&
        DEBIAN_FRONTEND=noninteractive timeout 600 apt-get install -y chromium; } \
        >/tmp/check-report-3d-apt.log 2>&1 || ! command -v chromium >/dev/null 2>&1; then
        echo "skipped: chromium could not be installed (see /tmp/check-report-3d-apt.log)"
        exit 0
    fi
fi
if ! command -v python3 >/dev/null 2>&1; then
    echo "skipped: the checks are written in python3, which is missing"
    exit 0
fi
chromium --version 2>/dev/null || true

# --workspace: the features the whole workspace resolves, as `cargo test --workspace --release`
# built them; `-p dips-report` alone resolves fewer and rebuilds nalgebra and what is above it.
cargo build --release --workspace --example episode_report
report=target/release/examples/episode_report

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# Run before anything else on the page: every console error or warning, uncaught error and
# rejected promise lands in <html data-check-errors>; once the view is ready (three.js is
# inflated first), the canvas's place in data-check-rect, and with #…&play, a click on play
# and the state shown 3 s later in data-check-played.
probe='<script>(function(){var errs=[];var root=document.documentElement;
function note(m){errs.push(String(m));root.setAttribute("data-check-errors",JSON.stringify(errs));}
["error","warn"].forEach(function(k){var f=console[k];console[k]=function(){
note("console."+k+": "+Array.prototype.map.call(arguments,String).join(" "));return f.apply(console,arguments);};});
window.addEventListener("error",function(e){note("uncaught: "+e.message);});
window.addEventListener("unhandledrejection",function(e){note("unhandled rejection: "+e.reason);});
window.addEventListener("load",function(){var t=setInterval(function(){var s=document.getElementById("dips-scene");
if(!s||s.getAttribute("data-ready")!=="true")return;clearInterval(t);
var c=document.querySelector("#dips-scene-view canvas");
if(c){var r=c.getBoundingClientRect();root.setAttribute("data-check-rect",JSON.stringify([r.left,r.top,r.width,r.height,window.devicePixelRatio||1]));}
if(/play/.test(location.hash)){document.getElementById("dips-scene-play").click();
setTimeout(function(){root.setAttribute("data-check-played",s.getAttribute("data-frame"));},3000);}},50);});
})();</script>'

chrome() {
    local profile
    profile=$(mktemp -d "$work/profile.XXXX")
    timeout 120 chromium --headless --no-sandbox --disable-gpu --disable-quic --no-first-run \
        --disable-background-networking --disable-component-update --disable-sync \
        --user-data-dir="$profile" --use-angle=swiftshader --enable-unsafe-swiftshader \
        --enable-logging=stderr --v=0 --hide-scrollbars --window-size=1300,1000 \
        --virtual-time-budget=8000 "$@"
}

status=0
for case in "screwdriver docs/results/screwdriver/episodes/dips/seed-3005 20" \
    "card docs/results/card/episodes/dips/seed-3008 20"; do
    read -r task src shot <<<"$case"
    dir="$work/$task"
    mkdir -p "$dir"
    cp "$src/result.json" "$dir/"
    "$report" "$dir" >/dev/null
    # The page as written, with the probe first in <head>.
    python3 - "$dir/report.html" "$dir/check.html" "$probe" <<'EOF'
import sys
html = open(sys.argv[1], encoding="utf-8").read()
assert "<head>" in html, "no <head> in report.html"
open(sys.argv[2], "w", encoding="utf-8").write(html.replace("<head>", "<head>\n" + sys.argv[3], 1))
EOF
    url="file://$dir/check.html"
    chrome --dump-dom "$url#frame=0" >"$dir/first.html" 2>"$dir/first.log"
    chrome --dump-dom "$url#frame=last" >"$dir/last.html" 2>"$dir/last.log"
    chrome --dump-dom "$url#frame=0&play" >"$dir/play.html" 2>"$dir/play.log"
    chrome --screenshot="$dir/shot.png" "$url#frame=$shot" >/dev/null 2>"$dir/shot.log"
    if [[ -n $keep ]]; then cp "$dir/shot.png" "$keep/$task.png"; fi
    if ! python3 - "$task" "$dir" <<'EOF'; then
import html as H, json, re, struct, sys, zlib

task, d = sys.argv[1], sys.argv[2]
problems = []

def attrs(tag, page):
    m = re.search(r"<" + tag + r"\b([^>]*)>", page)
    return {k: H.unescape(v) for k, v in re.findall(r'([\w-]+)="([^"]*)"', m.group(1))} if m else {}

def tips_of(data, k):
    n = len(data["fingers"])
    p = len(data["frames"][k]["hand"]) // (3 * n)
    h = data["frames"][k]["hand"]
    return [h[3 * (i * p + p - 1): 3 * (i * p + p)] for i in range(n)]

drawn = {}
rect = None
for name in ("first", "last"):
    page = open(f"{d}/{name}.html", encoding="utf-8").read()
    log = open(f"{d}/{name}.log", encoding="utf-8", errors="replace").read()
    root, scene = attrs("html", page), attrs("div", page[page.find('<div id="dips-scene"'):])
    if "data-check-errors" in root:
        problems.append(f"{name}: {root['data-check-errors']}")
    for line in log.splitlines():
        if "CONSOLE" in line and "Uncaught" in line:
            problems.append(f"{name}: {line.strip()}")
    if scene.get("data-ready") != "true":
        problems.append(f"{name}: the view is not ready ({scene.get('data-error', 'no error given')})")
        continue
    m = re.search(r'<script type="application/json" id="dips-scene-data">(.*?)</script>', page, re.S)
    data = json.loads(m.group(1))
    k = int(scene["data-frame"])
    want = 0 if name == "first" else len(data["frames"]) - 1
    if k != want:
        problems.append(f"{name}: the slider chose state {k}, not {want}")
    got = json.loads(scene["data-tips"])
    exp = tips_of(data, want)
    err = max(abs(a - b) for g, e in zip(got, exp) for a, b in zip(g, e))
    if len(got) != len(exp) or err > 1e-6:
        problems.append(f"{name}: drawn fingertips {got} are not the data's {exp}")
    drawn[name] = got
    rect = json.loads(root["data-check-rect"]) if "data-check-rect" in root else rect
page = open(f"{d}/play.html", encoding="utf-8").read()
played = attrs("html", page).get("data-check-played")
if "data-check-errors" in attrs("html", page):
    problems.append(f"play: {attrs('html', page)['data-check-errors']}")
if played is None or int(played) < 2:
    problems.append(f"play: 3 s after a click on play the view shows state {played}, not a later one")
else:
    print(f"{task}: 3 s after a click on play the view shows state {played}")
if len(drawn) == 2:
    moved = max(abs(a - b) for f, l in zip(drawn["first"], drawn["last"]) for a, b in zip(f, l))
    print(f"{task}: the slider moved the fingertips by up to {1000 * moved:.1f} mm")
    if moved < 1e-3:
        problems.append("the slider did not move the hand (fingertips moved under 1 mm)")

def png_rgb(path):
    raw = open(path, "rb").read()
    assert raw[:8] == b"\x89PNG\r\n\x1a\n", "not a PNG"
    pos, idat, w = 8, b"", 0
    while pos < len(raw):
        n, kind = struct.unpack(">I4s", raw[pos:pos + 8])
        body = raw[pos + 8:pos + 8 + n]
        if kind == b"IHDR":
            w, h, depth, ctype = struct.unpack(">IIBB", body[:10])
            assert depth == 8 and ctype in (2, 6), f"PNG colour type {ctype}/{depth}"
            bpp = 3 if ctype == 2 else 4
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    data, stride, rows, prev = zlib.decompress(idat), w * bpp, [], bytearray(w * bpp)
    for y in range(h):
        f, line = data[y * (stride + 1)], bytearray(data[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            a = line[i - bpp] if i >= bpp else 0
            b, c = prev[i], prev[i - bpp] if i >= bpp else 0
            if f == 1: line[i] = (line[i] + a) & 255
            elif f == 2: line[i] = (line[i] + b) & 255
            elif f == 3: line[i] = (line[i] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        rows.append([tuple(line[x * bpp:x * bpp + 3]) for x in range(w)])
        prev = line
    return rows

if rect:
    rows = png_rgb(f"{d}/shot.png")
    x0, y0, cw, ch, dpr = rect
    xs = range(int(x0 * dpr) + 2, min(len(rows[0]), int((x0 + cw) * dpr) - 2), 2)
    ys = range(int(y0 * dpr) + 2, min(len(rows), int((y0 + ch) * dpr) - 2), 2)
    seen = [rows[y][x] for y in ys for x in xs]
    colored = sum(1 for p in seen if max(p) - min(p) > 60)
    colors = len({(r >> 4, g >> 4, b >> 4) for r, g, b in seen})
    print(f"{task}: {100 * colored / max(1, len(seen)):.1f} % of the canvas is coloured, "
          f"{colors} colours")
    if colored < 0.02 * len(seen) or colors < 12:
        problems.append("the canvas looks blank in the screenshot")
else:
    problems.append("no canvas on the page")
for p in problems:
    print(f"{task}: FAIL: {p}")
sys.exit(1 if problems else 0)
EOF
        status=1
    fi
done
if [[ $status -eq 0 ]]; then
    echo "ok: report.html's 3D view loads, draws and follows its slider in headless Chromium"
fi
exit $status
