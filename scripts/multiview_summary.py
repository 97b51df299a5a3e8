#!/usr/bin/env python3
"""Summarises scripts/multiview_eval.py's CSV: a Markdown table per noise level (median over the
views of each set; sets as columns), which row is lowest, and a figure of the median pose error.
usage: multiview_summary.py multiview.csv --figure out.png > table.md"""
import argparse
import csv
import statistics
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

ROWS = ["chained MLS-SICP", "AlignScans MLS-SICP", "AlignScans CP-SICP", "Open3D multiway"]


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("csv")
    parser.add_argument("--figure")
    args = parser.parse_args()
    rows = list(csv.DictReader(open(args.csv)))
    sigmas = ["0", "0.8", "2", "real"]
    for sigma in sigmas:
        here = [r for r in rows if r["sigma_d"] == sigma]
        sets = list(dict.fromkeys(r["set"] for r in here))
        if not here:
            continue
        title = "real scans" if sigma == "real" else f"virtual scans, sigma = {sigma} d"
        print(f"\n**{title}**: median / max pose error of the views (units of d)"
              + ("" if sigma == "real" else "; merged-cloud RMSE to the mesh") + "\n")
        print("| row | " + " | ".join(sets) + " |")
        print("|---|" + "---|" * len(sets))
        for name in ROWS:
            cells = []
            for s in sets:
                r = next(x for x in here if x["set"] == s and x["row"] == name)
                best = min(float(x["median_pose_rmse_d"]) for x in here if x["set"] == s)
                cell = f"{float(r['median_pose_rmse_d']):.3g} / {float(r['max_pose_rmse_d']):.3g}"
                if r["merged_rmse_d"]:
                    cell += f"; {float(r['merged_rmse_d']):.3g}"
                if float(r["median_pose_rmse_d"]) == best:
                    cell = f"**{cell}**"
                cells.append(cell)
            print(f"| {name} | " + " | ".join(cells) + " |")
        loops = [float(r["loop_closure_error_d"]) for r in here
                 if r["row"] == "AlignScans MLS-SICP" and r["loop_closure_error_d"]]
        if loops and sigma != "real":
            print(f"\nLoop closure of the chained MLS-SICP edges (AlignScans MLS-SICP): "
                  f"median {statistics.median(loops):.3g} d, max {max(loops):.3g} d.")
            drift = [float(r["max_drift_removed_d"]) for r in here
                     if r["row"] == "AlignScans MLS-SICP" and r.get("max_drift_removed_d")]
            if drift:
                print(f"Chained poses against the optimised ones (the largest per set): median "
                      f"{statistics.median(drift):.3g} d, max {max(drift):.3g} d.")
            resampled = [(r["set"], float(r["merged_rmse_d"]), float(r["resampled_rmse_d"]),
                          float(r["o3d_voxel_rmse_d"])) for r in here
                         if r["row"] == "AlignScans MLS-SICP" and r.get("resampled_rmse_d")]
            if resampled:
                print("Merged cloud RMSE to the mesh (AlignScans MLS-SICP poses), as merged -> "
                      "resampled onto the joint MLS surface (`--resample`) / Open3D's "
                      "voxel_down_sample at d: "
                      + ", ".join(f"{n} {a:.3g} -> {b:.3g} / {c:.3g} d"
                                  for n, a, b, c in resampled) + ".")
    if args.figure:
        fig, axes = plt.subplots(1, 4, figsize=(15, 4), sharey=True)
        for ax, sigma in zip(axes, sigmas):
            here = [r for r in rows if r["sigma_d"] == sigma]
            sets = list(dict.fromkeys(r["set"] for r in here))
            width = 0.8 / len(ROWS)
            for k, name in enumerate(ROWS):
                values = [float(next(x for x in here if x["set"] == s and x["row"] == name)
                                 ["median_pose_rmse_d"]) for s in sets]
                ax.bar([i + (k - 1.5) * width for i in range(len(sets))], values, width,
                       label=name)
            ax.set_xticks(range(len(sets)))
            ax.set_xticklabels([s.replace("real ", "") for s in sets], rotation=30, fontsize=8)
            ax.set_yscale("log")
            ax.set_ylim(0.02, 1000)
            ax.set_title("real scans" if sigma == "real" else f"sigma = {sigma} d", fontsize=10)
            ax.grid(True, axis="y", which="both", alpha=0.3)
        axes[0].set_ylabel("median pose error of the views (units of d)")
        axes[0].legend(fontsize=8)
        fig.suptitle("Multi-view alignment: every view's pose against the ground truth "
                     "(from 10 deg / 10 d per view)", fontsize=11)
        fig.tight_layout()
        fig.savefig(args.figure, dpi=110)
    return 0


if __name__ == "__main__":
    sys.exit(main())
