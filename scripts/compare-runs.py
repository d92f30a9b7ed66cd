#!/usr/bin/env python3
"""Check that two runs of the same work agree bit for bit, apart from wall times.

    scripts/compare-runs.py eval A B      every episode of two `dips eval` directories:
                                          result.json equal (outcome, modes, every state and
                                          plan), fields that are wall times (`*_s`, `seconds`)
                                          left out; the same episodes in both
    scripts/compare-runs.py datagen A B   every demo of two datasets: tensor bytes equal and
                                          metadata equal but `seconds`/`csvto_seconds`; the
                                          same seeds in both

Used by scripts/slurm-ci.sh (a job array against one process). Exit 0 when they agree, 1 with
the first differences named otherwise.
"""
import json
import struct
import sys
from pathlib import Path

WALL_KEYS = {"seconds", "csvto_seconds"}


def strip_walls(v):
    if isinstance(v, dict):
        return {k: strip_walls(x) for k, x in v.items()
                if not (k.endswith("_s") or k in WALL_KEYS)}
    if isinstance(v, list):
        return [strip_walls(x) for x in v]
    return v


def first_diff(a, b, at=""):
    if type(a) is not type(b):
        return f"{at}: {a!r:.60} vs {b!r:.60}"
    if isinstance(a, dict):
        for k in sorted(set(a) | set(b)):
            if k not in a or k not in b:
                return f"{at}.{k}: only in {'B' if k not in a else 'A'}"
            d = first_diff(a[k], b[k], f"{at}.{k}")
            if d:
                return d
        return None
    if isinstance(a, list):
        if len(a) != len(b):
            return f"{at}: {len(a)} vs {len(b)} items"
        for i, (x, y) in enumerate(zip(a, b)):
            d = first_diff(x, y, f"{at}[{i}]")
            if d:
                return d
        return None
    return None if a == b else f"{at}: {a!r:.60} vs {b!r:.60}"


def episodes(root):
    return {str(p.parent.relative_to(root)): p for p in sorted(root.glob("episodes/*/*/result.json"))}


def compare_eval(a, b):
    ea, eb = episodes(a), episodes(b)
    problems = []
    if set(ea) != set(eb):
        problems.append(f"episodes only in A: {sorted(set(ea) - set(eb))}, "
                        f"only in B: {sorted(set(eb) - set(ea))}")
    for name in sorted(set(ea) & set(eb)):
        ra = strip_walls(json.loads(ea[name].read_text()))
        rb = strip_walls(json.loads(eb[name].read_text()))
        d = first_diff(ra, rb)
        if d:
            problems.append(f"{name}: {d}")
    return len(set(ea) & set(eb)), problems


def read_safetensors(path):
    raw = path.read_bytes()
    (n,) = struct.unpack("<Q", raw[:8])
    header = json.loads(raw[8:8 + n])
    meta = header.pop("__metadata__", {})
    for k in WALL_KEYS:
        meta.pop(k, None)
    return header, meta, raw[8 + n:]


def compare_datagen(a, b):
    da = {p.name: p for p in sorted((a / "demos").glob("*.safetensors"))}
    db = {p.name: p for p in sorted((b / "demos").glob("*.safetensors"))}
    problems = []
    if set(da) != set(db):
        problems.append(f"demos only in A: {sorted(set(da) - set(db))}, "
                        f"only in B: {sorted(set(db) - set(da))}")
    for name in sorted(set(da) & set(db)):
        ha, ma, xa = read_safetensors(da[name])
        hb, mb, xb = read_safetensors(db[name])
        if ha != hb:
            problems.append(f"{name}: tensor layout differs")
        elif xa != xb:
            problems.append(f"{name}: tensor bytes differ")
        d = first_diff(ma, mb, "metadata")
        if d:
            problems.append(f"{name}: {d}")
    return len(set(da) & set(db)), problems


def main():
    if len(sys.argv) != 4 or sys.argv[1] not in ("eval", "datagen"):
        print(__doc__, file=sys.stderr)
        return 2
    kind, a, b = sys.argv[1], Path(sys.argv[2]), Path(sys.argv[3])
    n, problems = (compare_eval if kind == "eval" else compare_datagen)(a, b)
    if n == 0:
        problems.append("nothing to compare")
    for p in problems[:20]:
        print(f"differs: {p}", file=sys.stderr)
    if problems:
        return 1
    print(f"{kind}: {n} {'episodes' if kind == 'eval' else 'demos'} identical in {a} and {b}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
