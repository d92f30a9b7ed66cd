#!/usr/bin/env python3
"""What the particles and Ψ did: the figures of docs/particles.md from committed inputs.

    scripts/particles.py OUT_DIR EVAL_DIR [EVAL_DIR ...] [--probe PROBE.json ...]

EVAL_DIR: `dips eval` directories whose episodes' result.json carry `particles_diagnostics`
(every planning call made in process since 2026-11-27). PROBE.json: output of the
`particle_probe` example. Writes OUT_DIR/summary.json (every number docs/particles.md quotes)
and OUT_DIR/{ess,spread,psi,agreement}.png (matplotlib).
"""
import json
import math
import sys
from pathlib import Path


def mean(xs):
    xs = [x for x in xs if x is not None and not (isinstance(x, float) and math.isnan(x))]
    return sum(xs) / len(xs) if xs else None


def se(xs):
    xs = [x for x in xs if x is not None]
    if len(xs) < 2:
        return None
    m = mean(xs)
    return math.sqrt(sum((x - m) ** 2 for x in xs) / (len(xs) - 1) / len(xs))


def load_eval(d):
    out = {}
    for f in sorted(Path(d).glob("episodes/*/seed-*/result.json")):
        r = json.loads(f.read_text())
        out.setdefault(r["method"], []).append(r)
    return out


def outcome(r):
    return r.get("final_yaw", r.get("final_distance_m"))


def main():
    args = sys.argv[1:]
    probes = []
    if "--probe" in args:
        i = args.index("--probe")
        probes, args = args[i + 1:], args[:i]
    if len(args) < 2:
        print(__doc__, file=sys.stderr)
        return 2
    out_dir, evals = Path(args[0]), args[1:]
    out_dir.mkdir(parents=True, exist_ok=True)
    summary = {"inputs": {"evals": evals, "probes": probes}, "tasks": {}}
    for d in evals:
        episodes = load_eval(d)
        task = next(iter(episodes.values()))[0]["task"]
        t = summary["tasks"].setdefault(task, {"methods": {}})
        for method, rs in sorted(episodes.items()):
            calls = [p for r in rs for p in r.get("plans", []) if p.get("particles_diagnostics")]
            diags = [p["particles_diagnostics"] for p in calls]
            hist = [0] * 10
            for dg in diags:
                hist = [a + b for a, b in zip(hist, dg["psi_histogram"])]
            modes = sorted({m for dg in diags for m in dg["progress_spread"]})
            t["methods"][method] = {
                "episodes": len(rs),
                "seeds": sorted(r["seed"] for r in rs),
                "valid": sum(bool(r["valid"]) for r in rs),
                "outcome_mean": mean([outcome(r) for r in rs]),
                "outcome_se": se([outcome(r) for r in rs]),
                "outcomes_by_seed": {str(r["seed"]): outcome(r) for r in rs},
                "calls": len(diags),
                "ess_scores_mean": mean([dg["ess_scores_mean"] for dg in diags]),
                "ess_psi_mean": mean([dg["ess_psi_mean"] for dg in diags]),
                "ess_psi_min_median": sorted(dg["ess_psi_min"] for dg in diags)[len(diags) // 2] if diags else None,
                "distinct_mean": mean([dg["distinct_mean"] for dg in diags]),
                "psi_mean": mean([dg["psi_mean"] for dg in diags]),
                "psi_histogram": hist,
                "psi_share_below_0_1": hist[0] / sum(hist) if sum(hist) else None,
                "psi_share_above_0_9": hist[9] / sum(hist) if sum(hist) else None,
                "progress_spread": {m: mean([dg["progress_spread"].get(m) for dg in diags]) for m in modes},
                "weight_shift_mean": mean([dg["weight_shift_mean"] for dg in diags]),
                "ess_psi_by_call": [[p["executed"], p["particles_diagnostics"]["ess_psi_mean"]] for p in calls],
            }
        # Paired differences of dips against the ablations.
        base = {r["seed"]: outcome(r) for r in episodes.get("dips", [])}
        for other in ("dips-k1", "dips-max-likelihood"):
            pairs = [(base[r["seed"]], outcome(r)) for r in episodes.get(other, []) if r["seed"] in base]
            diffs = [a - b for a, b in pairs]
            if diffs:
                t[f"dips_minus_{other}"] = {"n": len(diffs), "mean": mean(diffs), "se": se(diffs),
                                            "identical": sum(d == 0 for d in diffs)}
    for p in probes:
        pr = json.loads(Path(p).read_text())
        task = json.loads(Path(pr["per_state"][0]["episode"]).read_text())["task"] if pr["per_state"] else "?"
        summary["tasks"].setdefault(task, {})["probe"] = {
            "file": p, "states": pr["states"], "seeds_per_planner": pr["seeds_per_planner"],
            "mean_agreement": pr["mean_agreement"]}
    (out_dir / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    plot(summary, out_dir)
    print(f"wrote {out_dir}/summary.json and the plots")
    return 0


def plot(summary, out_dir):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    tasks = list(summary["tasks"])
    colours = {"dips": "#1f77b4", "dips-k1": "#ff7f0e", "dips-max-likelihood": "#2ca02c"}
    # ESS of Ψ alone per planning call, by the call's index in its episode (dips only).
    fig, axes = plt.subplots(1, len(tasks), figsize=(5 * len(tasks), 3.6), squeeze=False)
    for ax, task in zip(axes[0], tasks):
        m = summary["tasks"][task]["methods"].get("dips")
        if not m:
            continue
        xs = [c for c, _ in m["ess_psi_by_call"]]
        ys = [e for _, e in m["ess_psi_by_call"]]
        ax.scatter(xs, ys, s=12, alpha=0.6, label="Ψ alone, mean over the call's children")
        ax.axhline(16, color="grey", ls="--", lw=1, label="k = 16 (flat Ψ)")
        ax.set_ylim(0, 17)
        ax.set_xlabel("planning call (modes executed before it)")
        ax.set_ylabel("effective particles of 16")
        ax.set_title(f"{task}: Ψ's effective sample size")
        ax.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    fig.savefig(out_dir / "ess.png", dpi=110)
    plt.close(fig)
    # Ψ histogram over every sampled segment of dips' calls.
    fig, axes = plt.subplots(1, len(tasks), figsize=(5 * len(tasks), 3.4), squeeze=False)
    for ax, task in zip(axes[0], tasks):
        m = summary["tasks"][task]["methods"].get("dips")
        if not m:
            continue
        h = m["psi_histogram"]
        total = sum(h) or 1
        ax.bar([i / 10 + 0.05 for i in range(10)], [x / total for x in h], width=0.09)
        ax.set_xlabel("Ψ (the discriminator's probability of real)")
        ax.set_ylabel("share of sampled segments")
        ax.set_title(f"{task}: Ψ on the search's own samples ({total})")
    fig.tight_layout()
    fig.savefig(out_dir / "psi.png", dpi=110)
    plt.close(fig)
    # Spread of a mode's 16 samples' end progress.
    fig, axes = plt.subplots(1, len(tasks), figsize=(5 * len(tasks), 3.4), squeeze=False)
    for ax, task in zip(axes[0], tasks):
        m = summary["tasks"][task]["methods"].get("dips")
        if not m:
            continue
        unit, scale = ("rad", 1.0) if task == "screwdriver" else ("cm", 100.0)
        names = list(m["progress_spread"])
        ax.bar(names, [m["progress_spread"][n] * scale for n in names])
        ax.set_ylabel(f"std of end progress ({unit})")
        ax.set_title(f"{task}: spread of a mode's 16 samples")
        ax.tick_params(axis="x", labelsize=7, rotation=15)
    fig.tight_layout()
    fig.savefig(out_dir / "spread.png", dpi=110)
    plt.close(fig)
    # Next-mode agreement.
    probed = [t for t in tasks if "probe" in summary["tasks"][t]]
    if probed:
        fig, axes = plt.subplots(1, len(probed), figsize=(6 * len(probed), 3.6), squeeze=False)
        for ax, task in zip(axes[0], probed):
            a = summary["tasks"][task]["probe"]["mean_agreement"]
            names = list(a)
            ax.barh(names, [a[n] for n in names])
            ax.set_xlim(0, 1)
            ax.set_xlabel("share of plan pairs with the same next mode")
            ax.set_title(f"{task}: {summary['tasks'][task]['probe']['states']} states")
        fig.tight_layout()
        fig.savefig(out_dir / "agreement.png", dpi=110)
        plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())
