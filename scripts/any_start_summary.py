#!/usr/bin/env python3
"""Summary of scripts/any-start.sh: success per set, start and method; method auto's
verification (right and wrong); alpha-recall per start-angle band, with the Open3D peers of
bench/peer_comparison.py --global when their CSV is given; an alpha-recall figure.

    python3 scripts/any_start_summary.py OUT [--peers peers_global.csv] [--figure out.png]

Success is RMSE/d below 5 d against the ground truth, as in `mlsreg eval`. A start's angle band
is the rotation error of the start pose against the truth.
"""
import argparse
import csv
import glob
import os
import statistics
import sys

BANDS = [(0, 20), (20, 60), (60, 90), (90, 135), (135, 180.01)]
ALPHAS = [0.25 * k for k in range(1, 41)]  # 0.25 .. 10 d
SUCCESS_D = 5.0


def read_runs(out):
    runs = []
    for path in sorted(glob.glob(os.path.join(out, "*.csv"))):
        if os.path.basename(path) in ("peers_global.csv",):
            continue
        with open(path) as f:
            for row in csv.DictReader(f):
                if "label" not in row:
                    break  # not an `mlsreg eval` CSV
                if row.get("status") != "ok":
                    row["rmse_d"] = "inf"
                row["set"], row["sigma"], row["start"] = (row["label"].split(",") + ["", "", ""])[:3]
                runs.append(row)
    return runs


def band_of(angle):
    for lo, hi in BANDS:
        if lo <= angle < hi:
            return f"{lo}-{min(hi, 180):.0f}°"
    return "?"


def fmt_rate(ok, n):
    return f"{ok}/{n} ({100.0 * ok / n:.0f} %)" if n else "-"


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("out")
    parser.add_argument("--peers", help="per-problem CSV of bench/peer_comparison.py --global")
    parser.add_argument("--figure", help="alpha-recall PNG")
    args = parser.parse_args()
    runs = [r for r in read_runs(args.out) if r["set"] != "mismatched"]
    mismatched = [r for r in read_runs(args.out) if r["set"] == "mismatched"]
    methods = []
    for r in runs:
        if r["method"] not in methods:
            methods.append(r["method"])

    print("### Success (RMSE below 5 d), default parameters\n")
    print("| set | σ | start | " + " | ".join(methods) + " |")
    print("|---|---|---|" + "---|" * len(methods))
    groups = {}
    for r in runs:
        groups.setdefault((r["set"], r["sigma"], r["start"]), []).append(r)
    order = {"scanner": 0, "near": 1, "rot90": 2, "any": 3}
    for key in sorted(groups, key=lambda k: (k[0] != "synthetic", k[1], order.get(k[2], 9))):
        rows = groups[key]
        cells = []
        for m in methods:
            mr = [r for r in rows if r["method"] == m]
            cells.append(fmt_rate(sum(float(r["rmse_d"]) < SUCCESS_D for r in mr), len(mr)))
        print(f"| {key[0]} | {key[1] or '-'} | {key[2]} | " + " | ".join(cells) + " |")

    auto = [r for r in runs if r["method"] == "auto"]
    if auto:
        print("\n### Method auto: verification and cost\n")
        print("| set | start | verified | verified but wrong | not verified but right | early exit |"
              " median time auto | median time mls-sicp | ratio |")
        print("|---|---|---|---|---|---|---|---|---|")
        for (s, start) in sorted({(r["set"], r["start"]) for r in auto},
                                 key=lambda k: (k[0] != "synthetic", order.get(k[1], 9))):
            a = [r for r in auto if r["set"] == s and r["start"] == start]
            mls = [r for r in runs if r["method"] == "mls-sicp" and r["set"] == s and r["start"] == start]
            verified = [r for r in a if r["verified"] == "1"]
            wrong = [r for r in verified if float(r["rmse_d"]) >= SUCCESS_D]
            missed = [r for r in a if r["verified"] != "1" and float(r["rmse_d"]) < SUCCESS_D]
            early = sum(r["auto_early_exit"] == "1" for r in a)
            ta = statistics.median(float(r["time_total_s"]) for r in a)
            tm = statistics.median(float(r["time_total_s"]) for r in mls) if mls else float("nan")
            print(f"| {s} | {start} | {fmt_rate(len(verified), len(a))} | {len(wrong)} | {len(missed)} |"
                  f" {fmt_rate(early, len(a))} | {ta:.3f} s | {tm:.3f} s | {ta / tm:.2f} |")
        # Near the truth auto must return MLS-SICP's transform: same RMSE per problem.
        near = {(r["manifest"], r["id"], r["sigma"]): r for r in auto if r["start"] == "near"}
        same = total = 0
        for r in runs:
            if r["method"] == "mls-sicp" and r["start"] == "near":
                k = (r["manifest"], r["id"], r["sigma"])
                if k in near:
                    total += 1
                    same += abs(float(near[k]["rmse_d"]) - float(r["rmse_d"])) < 1e-9
        if total:
            print(f"\nFrom the near start, auto returned MLS-SICP's result on {same}/{total} problems.")

    if mismatched:
        v = sum(r["verified"] == "1" for r in mismatched)
        fr = sorted(float(r["auto_fraction"]) for r in mismatched)
        ratio = sorted(float(r["auto_rmse_d"]) / float(r["auto_inlier_distance_d"]) for r in mismatched)
        print(f"\n### Mismatched pairs (two different meshes, same size and place)\n\nverified: {v} of"
              f" {len(mismatched)}; share of the source on the target's surface: median"
              f" {statistics.median(fr):.3f}, max {fr[-1]:.3f}; RMSE of the agreeing samples over the"
              f" inlier distance: median {statistics.median(ratio):.2f}, min {ratio[0]:.2f}.")
        good = [r for r in runs if r["method"] == "auto" and float(r["rmse_d"]) < SUCCESS_D]
        if good:
            gf = sorted(float(r["auto_fraction"]) for r in good)
            gr = sorted(float(r["auto_rmse_d"]) / float(r["auto_inlier_distance_d"]) for r in good)
            print(f"For comparison, the {len(good)} successful auto runs on true pairs: share min"
                  f" {gf[0]:.3f}, median {statistics.median(gf):.3f}; RMSE over the inlier distance"
                  f" median {statistics.median(gr):.2f}, max {gr[-1]:.2f}.")

    # alpha-recall per start-angle band, over every start of both sets.
    peers = {}
    if args.peers:
        with open(args.peers) as f:
            for row in csv.DictReader(f):
                peers.setdefault(row["method"], {})[(row["set"], row["sigma"], row["id"])] = float(row["rmse_d"])
    rotated = runs
    curves = {}
    for r in rotated:
        b = band_of(float(r["initial_rotation_error_deg"]))
        curves.setdefault((r["method"], b), []).append(float(r["rmse_d"]))
        if r["method"] == methods[0]:
            for pm, values in peers.items():
                key = (r["set"], r["sigma"], r["id"])
                if key in values:
                    curves.setdefault((pm, b), []).append(values[key])
    all_methods = methods + sorted(peers)
    bands = [band_of(lo) for lo, _ in BANDS]
    print("\n### α-recall per start-angle band (every start, synthetic and real)\n")
    print("Share of problems with RMSE below α = 1 d / 5 d.\n")
    print("| method | " + " | ".join(bands) + " |")
    print("|---|" + "---|" * len(bands))
    for m in all_methods:
        cells = []
        for b in bands:
            v = curves.get((m, b), [])
            cells.append(f"{sum(x < 1 for x in v) / len(v):.2f} / {sum(x < 5 for x in v) / len(v):.2f} (n={len(v)})"
                         if v else "-")
        print(f"| {m} | " + " | ".join(cells) + " |")

    if args.figure:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, axes = plt.subplots(1, len(bands), figsize=(4 * len(bands), 3.6), sharey=True)
        for ax, b in zip(axes, bands):
            for m in all_methods:
                v = curves.get((m, b), [])
                if v:
                    ax.plot(ALPHAS, [sum(x < a for x in v) / len(v) for a in ALPHAS], label=m,
                            color="black" if m == "auto" else None, lw=2.4 if m == "auto" else 1.3,
                            zorder=3 if m == "auto" else 2)
            ax.set_title(f"start {b} (n={len(curves.get((methods[0], b), []))})")
            ax.set_xlabel("α (RMSE threshold, units of d)")
            ax.grid(alpha=0.3)
        axes[0].set_ylabel("recall")
        axes[-1].legend(fontsize=8, loc="lower right")
        fig.tight_layout()
        fig.savefig(args.figure, dpi=110)
        print(f"\n(figure: {args.figure})", file=sys.stderr)


if __name__ == "__main__":
    main()
