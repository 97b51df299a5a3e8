#!/usr/bin/python3
"""Turn `mlsreg eval` result CSVs into paper-style figures and a markdown report.

Usage:
    scripts/plot_evaluation.py --results DIR --figures DIR --report FILE [--fig5-mesh NAME]

Reads synthetic.csv, real.csv, ablation.csv and the optional meta.json from --results (each may
be missing) and draws the figures of Dutta, Russig, Gumhold (2019), "Moving Least Squares
Correspondences for Iterative Point Set Registration" (Figs. 3-7, Table 1).  RMSE values are in
units of the target's sampling distance d (paper Eq. 10/11); a run succeeds when RMSE < 5 d.
Rows whose status is not "ok" count as failures.  Only matplotlib, numpy and the standard library.
"""
import argparse
import csv
import json
import math
import os
import statistics

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
import numpy as np  # noqa: E402

THRESHOLD = 5.0
DPI = 130
METHODS = ["rc-bl", "rc-p", "g-icp", "cp-sicp", "fgr", "st-sicp", "cp-sicp+mls-sicp", "mls-sicp",
           "mls-sicp-paper-r", "auto"]
# Rows run with the paper's per-noise Table 2 radius (hand-set) carry this label; they are shown
# as their own method, beside the default (automatic radius) MLS-SICP.
PAPER_RADIUS_LABEL = "paper radius"
DISPLAY = {"rc-bl": "RC-BL", "rc-p": "RC-P", "g-icp": "G-ICP", "cp-sicp": "CP-SICP", "fgr": "FGR",
           "st-sicp": "ST-SICP", "cp-sicp+mls-sicp": "CP-SICP+MLS-SICP", "mls-sicp": "MLS-SICP",
           "mls-sicp-paper-r": "MLS-SICP, paper r (hand-set)",
           "auto": "auto (MLS-SICP + global candidates, verified; the default)"}
STYLE = {  # colour, line style, marker -- distinct in colour and in grayscale
    "rc-bl": ("#8c8c8c", (0, (1, 1)), "v"),
    "rc-p": ("#8c564b", (0, (3, 1, 1, 1)), "^"),
    "g-icp": ("#1f77b4", (0, (5, 2)), "s"),
    "cp-sicp": ("#ff7f0e", "-.", "o"),
    "fgr": ("#2ca02c", (0, (8, 2, 1, 2)), "D"),
    "st-sicp": ("#9467bd", (0, (2, 2)), "P"),
    "cp-sicp+mls-sicp": ("#17becf", (0, (3, 1, 1, 1, 1, 1)), "X"),
    "mls-sicp": ("#d62728", "-", "*"),
    "mls-sicp-paper-r": ("#e377c2", (0, (1, 2)), "h"),
    "auto": ("#000000", (0, (6, 1)), "p"),
}
NOISE = [("0", "no noise"), ("0.8", "σ = 0.8 d"), ("2", "σ = 2 d")]
REAL_NAMES = {"stanford_bunny": "Stanford bunny (real)", "3dmatch_geotransformer_demo": "3DMatch (real)"}
ABLATION_ORDER = ["no filter", "normal", "curvature", "normal + curvature"]
FIG5_METHODS = ["cp-sicp", "st-sicp", "mls-sicp"]
FIG6_METHODS = ["cp-sicp", "st-sicp", "cp-sicp+mls-sicp", "mls-sicp"]
SEGMENTS = [("preprocessing", "time_preprocessing_s", "#4e79a7"), ("subsampling", "time_subsampling_s", "#f28e2b"),
            ("matching", "time_matching_s", "#59a14f"), ("optimisation", "time_optimisation_s", "#e15759"),
            ("other", None, "#d3d3d3"), ("target preparation", "target_build_s", "#ffffff")]

plt.rcParams.update({"font.size": 10, "axes.titlesize": 11, "axes.labelsize": 10, "legend.fontsize": 9,
                     "xtick.labelsize": 8.5, "ytick.labelsize": 9, "axes.grid": True, "grid.alpha": 0.3})


# ----------------------------------------------------------------------------- data helpers
def load_csv(path):
    """Rows as dicts of stripped strings (missing cells become ""), or None if the file is absent."""
    if not os.path.isfile(path):
        return None
    with open(path, newline="") as f:
        rows = [{k: (v or "").strip() for k, v in row.items() if isinstance(k, str) and isinstance(v, str)}
                for row in csv.DictReader(f)]
    for row in rows:
        if row.get("label") == PAPER_RADIUS_LABEL and row.get("method") == "mls-sicp":
            row["method"] = "mls-sicp-paper-r"
    return rows


def num(row, key):
    try:
        v = float(row.get(key, ""))
    except ValueError:
        return None
    return v if math.isfinite(v) else None


def nums(row, key):
    try:
        return [float(x) for x in row.get(key, "").split()]
    except ValueError:
        return []


def rmse(row):
    return num(row, "rmse_d") if row.get("status") == "ok" else None


def succeeded(row):
    r = rmse(row)
    return r is not None and r < THRESHOLD


def noise_key(row):
    v = num(row, "noise_sigma_d")
    return None if v is None else "%g" % v


def noise_label(key):
    return dict(NOISE).get(key, "σ = %s d" % key)


def method_order(rows):
    present = {r.get("method", "") for r in rows} - {""}
    return [m for m in METHODS if m in present] + sorted(present - set(METHODS))


def style(m):
    return STYLE.get(m, ("#555555", "-", "."))


def name(m):
    return DISPLAY.get(m, m)


def of(rows, method):
    return [r for r in rows if r.get("method") == method]


def median(values):
    return statistics.median(values) if values else None


def datasets(syn, real):
    """[(key, title, rows, is_synthetic)]: one per synthetic noise level, then one per real set."""
    out = []
    levels = sorted({noise_key(r) for r in syn or []} - {None}, key=float)
    for key in levels:
        out.append(("syn:" + key, "Synthetic, " + noise_label(key), [r for r in syn if noise_key(r) == key], True))
    groups = {}
    for r in real or []:
        folder = os.path.basename(os.path.dirname(r.get("manifest", ""))) or "unknown"
        groups.setdefault(folder, []).append(r)
    for folder in sorted(groups, key=lambda f: REAL_NAMES.get(f, f)):
        out.append(("real:" + folder, REAL_NAMES.get(folder, folder + " (real)"), groups[folder], False))
    return out


def save(fig, figdir, fname):
    fig.savefig(os.path.join(figdir, fname), dpi=DPI, bbox_inches="tight", metadata={"Software": None})
    plt.close(fig)
    return fname


# ----------------------------------------------------------------------------- figures
def draw_boxes(ax, groups, ylabel="RMSE / d", rotation=40, allow_log=True, empty="no successful runs"):
    """groups: [(tick label, colour, values)].  Returns True if a log y-scale was used."""
    pos = [i + 1 for i, g in enumerate(groups) if g[2]]
    vals = [g[2] for g in groups if g[2]]
    if vals:
        bp = ax.boxplot(vals, positions=pos, whis=(5, 95), widths=0.6, patch_artist=True,
                        medianprops={"color": "black", "linewidth": 1.6},
                        flierprops={"marker": ".", "markersize": 3, "markerfacecolor": "#444444",
                                    "markeredgecolor": "none"})
        for box, c in zip(bp["boxes"], [g[1] for g in groups if g[2]]):
            box.set_facecolor(c)
            box.set_alpha(0.75)
        for p, v in zip(pos, vals):  # a box of very few runs hides them: show the runs themselves
            if len(v) < 5:
                ax.plot([p] * len(v), v, ls="none", marker="o", markersize=3.5, color="black")
    ax.set_xticks(range(1, len(groups) + 1))
    ax.set_xticklabels([g[0] for g in groups], rotation=rotation, ha="right" if rotation else "center",
                       rotation_mode="anchor", multialignment="center")
    ax.set_xlim(0.4, len(groups) + 0.6)
    flat = [v for vs in vals for v in vs if v > 0]
    log = allow_log and bool(flat) and max(flat) / min(flat) > 100
    if log:
        ax.set_yscale("log")
    ax.set_ylabel(ylabel)
    if not vals:
        ax.text(0.5, 0.5, empty, transform=ax.transAxes, ha="center", va="center")
    return log


def success_group(label, colour, rows):
    """Box-plot group of the successful runs, labelled with successes/total."""
    return ("%s\n%d/%d" % (label, sum(succeeded(r) for r in rows), len(rows)), colour,
            [rmse(r) for r in rows if succeeded(r)])


def grid(n, w=5.2, h=4.4):
    ncols = min(n, 3)
    nrows = math.ceil(n / ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(w * ncols, h * nrows), squeeze=False)
    for ax in axes.flat[n:]:
        ax.set_visible(False)
    return fig, list(axes.flat[:n])


def fig3_boxplots(sets, figdir):
    if not sets:
        return None, "no synthetic or real results"
    fig, axes = grid(len(sets))
    logs = []
    for ax, (_, title, rows, _) in zip(axes, sets):
        if draw_boxes(ax, [success_group(name(m), style(m)[0], of(rows, m)) for m in method_order(rows)]):
            logs.append(title)
        ax.set_title(title)
    fig.suptitle("Final RMSE of successful registrations (RMSE < 5 d)", fontsize=12)
    fig.tight_layout()
    scale = ("log y-scale in: " + "; ".join(logs) + "; linear elsewhere") if logs else "linear y-scale"
    return save(fig, figdir, "fig3_boxplots.png"), scale


def fig4_alpha_recall(sets, figdir):
    sets = [s for s in sets if s[3]]
    if not sets:
        return None, "no synthetic results"
    positive = [rmse(r) for s in sets for r in s[2] if succeeded(r) and rmse(r) > 0]
    lo = float("%.1g" % min(max(0.7 * min(positive), 1e-3), 0.1)) if positive else 0.01
    alphas = np.logspace(math.log10(lo), math.log10(THRESHOLD), 400)
    fig, axes = grid(len(sets), 5.0, 4.0)
    for ax, (_, title, rows, _) in zip(axes, sets):
        for m in method_order(rows):
            mr = of(rows, m)
            v = np.array([rmse(r) if rmse(r) is not None else np.inf for r in mr])
            recall = np.array([(v <= a).sum() / len(v) for a in alphas])
            rising = np.nonzero((recall > 0) & (recall < recall[-1]))[0]  # markers only where the curve rises
            marks = rising[np.linspace(0, len(rising) - 1, 4).astype(int)] if len(rising) else [len(alphas) - 1]
            c, ls, mk = style(m)
            ax.plot(alphas, recall, color=c, ls=ls, marker=mk, markevery=sorted(set(int(k) for k in marks)),
                    markersize=5, lw=2.2 if m == "mls-sicp" else 1.4, zorder=3 if m == "mls-sicp" else 2)
        ax.set_xscale("log")
        ax.set_xlim(lo, THRESHOLD)
        ax.set_ylim(-0.02, 1.02)
        ax.set_xlabel("RMSE threshold α / d")
        ax.set_ylabel("α-recall (fraction of problems)")
        ax.set_title(title)
    handles = [Line2D([], [], color=style(m)[0], ls=style(m)[1], marker=style(m)[2], lw=1.6, label=name(m))
               for m in method_order([r for s in sets for r in s[2]])]
    fig.tight_layout()
    fig.legend(handles=handles, loc="upper center", ncol=len(handles), bbox_to_anchor=(0.5, 0.0), frameon=False)
    return save(fig, figdir, "fig4_alpha_recall.png"), "log x from %g d to %g d" % (lo, THRESHOLD)


def pick_mesh(syn, wanted):
    meshes = sorted({r.get("mesh", "") for r in syn or []} - {""})
    return wanted if wanted in meshes else (meshes[0] if meshes else None)


def fig5_rmse_over_time(syn, mesh, figdir):
    if mesh is None:
        return None, "no synthetic results with a mesh column"
    rows = [r for r in syn or [] if r.get("mesh") == mesh and r.get("method") in FIG5_METHODS
            and r.get("status") == "ok" and nums(r, "trace_error_d")]
    if not rows:
        return None, "no trace_error_d traces for mesh %r" % mesh
    levels = sorted({noise_key(r) for r in rows} - {None}, key=float)
    fig, axes = grid(len(levels), 5.0, 4.0)
    for ax, key in zip(axes, levels):
        for m in FIG5_METHODS:
            c, ls, mk = style(m)
            for r in sorted(of([x for x in rows if noise_key(x) == key], m), key=lambda x: x.get("id", "")):
                t, e = nums(r, "trace_elapsed_s"), nums(r, "trace_error_d")
                n = min(len(t), len(e))
                ax.plot(t[:n], e[:n], color=c, ls=ls, lw=0.9, marker=mk, markersize=2.5, alpha=0.8)
        ax.set_yscale("log")
        ax.set_xlim(left=0)
        ax.set_xlabel("time [s]")
        ax.set_ylabel("RMSE / d (vs ground truth)")
        ax.set_title("%s, %s" % (mesh, noise_label(key)))
    handles = [Line2D([], [], color=style(m)[0], ls=style(m)[1], marker=style(m)[2], markersize=5, label=name(m))
               for m in FIG5_METHODS]
    fig.tight_layout()
    fig.legend(handles=handles, loc="upper center", ncol=3, bbox_to_anchor=(0.5, 0.0), frameon=False)
    return save(fig, figdir, "fig5_rmse_over_time.png"), "%d traces of mesh %s" % (len(rows), mesh)


def segment_times(rows):
    """Mean seconds per SEGMENTS entry over rows; "other" = time_total_s minus the four phases."""
    def seconds(r, key):
        if key is None:
            return max(0.0, (num(r, "time_total_s") or 0.0) - sum(seconds(r, k) for _, k, _ in SEGMENTS[:4]))
        return num(r, key) or 0.0
    return [statistics.mean(seconds(r, key) for r in rows) for _, key, _ in SEGMENTS]


def fig6_runtime(syn, mesh, figdir):
    if mesh is None:
        return None, "no synthetic results with a mesh column"
    high = [r for r in syn or [] if r.get("mesh") == mesh and noise_key(r) == "2" and r.get("status") == "ok"]
    first = sorted({r["id"] for r in high if "_030_000" in r.get("id", "")})
    panels = []
    if first:
        panels.append(("(a) first pair %s" % first[0], [r for r in high if r["id"] == first[0]]))
    if high:
        panels.append(("(b) mean over all %d high-noise pairs" % len({r.get("id") for r in high}), high))
    panels = [(t, rows) for t, rows in panels if any(of(rows, m) for m in FIG6_METHODS)]
    if not panels:
        return None, "no σ = 2 d runs of %s for mesh %r" % ("/".join(FIG6_METHODS), mesh)
    fig, axes = plt.subplots(len(panels), 1, figsize=(9, 1.0 + 1.6 * len(panels) + 0.4), squeeze=False)
    for ax, (title, rows) in zip(axes[:, 0], panels):
        methods = [m for m in FIG6_METHODS if of(rows, m)]
        for y, m in enumerate(methods):
            left = 0.0
            for (label, _, colour), width in zip(SEGMENTS, segment_times(of(rows, m))):
                hatch = "////" if label == "target preparation" else None
                ax.barh(y, width, left=left, color=colour, edgecolor="#333333", lw=0.5, hatch=hatch, height=0.6)
                left += width
            total = statistics.mean(num(r, "time_total_s") or 0.0 for r in of(rows, m))
            its = statistics.mean(num(r, "iterations") or 0.0 for r in of(rows, m))
            ax.text(left, y, "  total %.3g s, %.3g it." % (total, its), va="center", fontsize=8.5)
        ax.set_yticks(range(len(methods)))
        ax.set_yticklabels([name(m) for m in methods])
        ax.invert_yaxis()
        ax.set_xlim(0, ax.get_xlim()[1] * 1.18)
        ax.set_xlabel("time [s]")
        ax.set_title("%s — %s, σ = 2 d" % (title, mesh), loc="left")
    handles = [plt.Rectangle((0, 0), 1, 1, facecolor=c, edgecolor="#333333", hatch="////" if k == "target_build_s"
                             else None, label=l) for l, k, c in SEGMENTS]
    fig.tight_layout()
    fig.legend(handles=handles, loc="upper center", ncol=len(SEGMENTS), frameon=False, bbox_to_anchor=(0.5, 0.0),
               title="hatched: target preparation (target_build_s), built once per target and cached by the server",
               title_fontsize=8.5)
    return save(fig, figdir, "fig6_runtime.png"), "; ".join(t for t, _ in panels)


def ablation_labels(rows):
    found = {r.get("label", "") or "(no label)" for r in rows}
    return [l for l in ABLATION_ORDER if l in found] + sorted(found - set(ABLATION_ORDER))


def describe_ablation(rows):
    """e.g. "MLS-SICP; mesh bunny; σ = 2 d" from the rows' method and extra manifest columns."""
    meshes = sorted({r.get("mesh", "") for r in rows} - {""})
    levels = sorted({noise_key(r) for r in rows} - {None}, key=float)
    parts = [", ".join(name(m) for m in method_order(rows)), "mesh " + ", ".join(meshes) if meshes else "",
             ", ".join(noise_label(k) for k in levels)]
    return "; ".join(p for p in parts if p)


def fig7_filter_ablation(abl, figdir):
    if not abl:
        return None, "no ablation results"
    groups = [success_group(lab, "#d62728" if lab == "normal + curvature" else "#bbbbbb",
                            [r for r in abl if (r.get("label", "") or "(no label)") == lab])
              for lab in ablation_labels(abl)]
    fig, ax = plt.subplots(figsize=(1.2 * len(groups) + 2.5, 4.4))
    log = draw_boxes(ax, groups, rotation=0)
    ax.set_title("Correspondence filtering: " + describe_ablation(abl))
    fig.tight_layout()
    return save(fig, figdir, "fig7_filter_ablation.png"), "log y-scale" if log else "linear y-scale"


def fig_iterations(sets, figdir):
    sets = [s for s in sets if s[3]]
    if not sets:
        return None, "no synthetic results"
    fig, axes = grid(len(sets))
    for ax, (_, title, rows, _) in zip(axes, sets):
        groups = []
        for m in method_order(rows):
            okr = [r for r in of(rows, m) if r.get("status") == "ok" and num(r, "iterations") is not None]
            at_max = sum(r.get("termination") == "max_iterations" for r in okr)
            groups.append(("%s\n%d at max" % (name(m), at_max), style(m)[0], [num(r, "iterations") for r in okr]))
        draw_boxes(ax, groups, ylabel="ICP iterations", allow_log=False, empty="no runs with status ok")
        ax.set_title(title)
    fig.suptitle("Iterations per registration (runs with status ok)", fontsize=12)
    fig.tight_layout()
    return save(fig, figdir, "fig_iterations.png"), ""


# ----------------------------------------------------------------------------- report
def table(header, rows):
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    return lines + ["| " + " | ".join(r) + " |" for r in rows]


def fmt(v):
    """Three significant digits; integers and values >= 100 without exponent."""
    if v is None or isinstance(v, bool) or not isinstance(v, (int, float)):
        return "n/a" if v is None else str(v)
    return str(v) if isinstance(v, int) else "%.0f" % v if abs(v) >= 100 else "%.3g" % v


def count_cell(rows):
    return "%d/%d" % (sum(succeeded(r) for r in rows), len(rows)) if rows else "n/a"


def table1(sets, syn):
    syn_sets = [s for s in sets if s[3]]
    real_sets = [s for s in sets if not s[3]]
    header = ["method"] + [s[1].replace("Synthetic, ", "") for s in syn_sets]
    header += ["synthetic total"] if syn_sets else []
    header += [s[1] for s in real_sets]
    body = []
    for m in method_order([r for s in sets for r in s[2]]):
        cells = [count_cell(of(s[2], m)) for s in syn_sets]
        cells += [count_cell([r for r in of(syn or [], m) if noise_key(r) is not None])] if syn_sets else []
        body.append([name(m)] + cells + [count_cell(of(s[2], m)) for s in real_sets])
    return table(header, body)


def median_table(sets):
    methods = method_order([r for s in sets for r in s[2]])
    med = {(m, s[0]): median([rmse(r) for r in of(s[2], m) if succeeded(r)]) for m in methods for s in sets}
    best = {s[0]: min([v for (m, k), v in med.items() if k == s[0] and v is not None], default=None) for s in sets}
    body = [[name(m)] + [("**%s**" if med[m, s[0]] is not None and med[m, s[0]] == best[s[0]] else "%s")
                         % fmt(med[m, s[0]]) for s in sets] for m in methods]
    return table(["method"] + [s[1] for s in sets], body), med


def acceptance(sets, med):
    lines = []
    by_key = {s[0]: s for s in sets}
    for key, label in NOISE:
        s = by_key.get("syn:" + key)
        if s is None:
            lines.append("- Successes, synthetic %s: n/a (no data)" % label)
            continue
        wins = {m: sum(succeeded(r) for r in of(s[2], m)) for m in method_order(s[2])}
        if "mls-sicp" not in wins:
            lines.append("- Successes, synthetic %s: **FAIL** (MLS-SICP has no runs)" % label)
            continue
        better = ["%s (%d)" % (name(m), n) for m, n in wins.items()
                  if n > wins["mls-sicp"] and m not in ("mls-sicp-paper-r", "auto")]
        lines.append("- Successes, synthetic %s: MLS-SICP %d/%d — %s" % (
            label, wins["mls-sicp"], len(of(s[2], "mls-sicp")),
            "**FAIL**, more successes: " + ", ".join(better) if better else "**PASS** (no method has more)"))
    s = by_key.get("syn:2")
    if s is None:
        lines.append("- Lowest median RMSE/d at σ = 2 d: n/a (no data)")
    elif med.get(("mls-sicp", "syn:2")) is None:
        lines.append("- Lowest median RMSE/d at σ = 2 d: **FAIL** (MLS-SICP has no successful runs)")
    else:
        own = med["mls-sicp", "syn:2"]
        lower = ["%s (%s)" % (name(m), fmt(med[m, "syn:2"])) for m in method_order(s[2])
                 if med.get((m, "syn:2")) is not None and med[m, "syn:2"] < own]
        lines.append("- Lowest median RMSE/d at σ = 2 d: MLS-SICP %s — %s" % (
            fmt(own), "**FAIL**, lower median: " + ", ".join(lower) if lower else "**PASS**"))
    return lines


def runtime_section(sets, meta):
    lines = ["## Runtime", ""]
    wall = (meta or {}).get("wall_seconds") or {}
    if isinstance(wall, dict) and wall:
        keys = [k for k in ("scan", "synthetic", "real", "ablation", "total") if k in wall]
        keys += sorted(set(wall) - set(keys))
        lines += ["Wall-clock time of the evaluation stages (meta.json):", ""]
        lines += table(["stage", "seconds"], [[k, fmt(wall[k])] for k in keys]) + [""]
    methods = method_order([r for s in sets for r in s[2]])
    if methods:
        lines += ["Median `time_total_s` per registration (runs with status ok; target preparation excluded), "
                  "in seconds:", ""]
        body = [[name(m)] + [fmt(median([num(r, "time_total_s") for r in of(s[2], m)
                                         if r.get("status") == "ok" and num(r, "time_total_s") is not None]))
                             for s in sets] for m in methods]
        lines += table(["method"] + [s[1] for s in sets], body) + [""]
    return lines if len(lines) > 2 else lines + ["No runtime data.", ""]


def meta_section(meta):
    if not meta:
        return ["## Run metadata", "", "meta.json: not found.", ""]
    lines = ["## Run metadata", ""]
    for key in ("command", "started", "machine"):
        if meta.get(key):
            lines.append("- %s: `%s`" % (key, meta[key]) if key == "command" else "- %s: %s" % (key, meta[key]))
    meshes = meta.get("meshes")
    if isinstance(meshes, dict) and meshes:
        cols = ["source", "vertices", "triangles", "points_per_view", "d"]
        body = [[str(k)] + [fmt(v.get(c, "")) for c in cols] for k, v in sorted(meshes.items()) if isinstance(v, dict)]
        lines += ["", "Synthetic meshes:", ""] + table(["mesh"] + cols, body)
    lines.append("")
    for key, title in (("parameters", "Parameters"), ("tuning", "Tuning split"),
                       ("any_start", "Registration from any start"),
                       ("multiview", "Many scans into one frame")):
        if meta.get(key):
            lines += ["## " + title, "", str(meta[key]).rstrip(), ""]
    return lines


CAPTIONS = {
    "fig3_boxplots.png": ("Figure 3: accuracy per data set",
                          "Box plots of the final RMSE / d of the successful registrations (RMSE < 5 d) per method, "
                          "one panel per data set, as in paper Fig. 3. The box spans the 25th to 75th percentile, "
                          "the black line is the median, the whiskers are the 5th and 95th percentiles and dots are "
                          "runs outside them (panels with fewer than 5 successful runs of a method also show "
                          "those runs as black dots). The numbers under each method are successes/total. "
                          "Lower is better."),
    "fig4_alpha_recall.png": ("Figure 4: α-recall on the synthetic data",
                              "Fraction of all registration problems (failed and errored runs count as not recalled) "
                              "whose final RMSE / d is at most α, one panel per noise level, as in paper Fig. 4. "
                              "Curves that rise earlier are more accurate; the height reached at α = 5 d is the "
                              "success rate. Steeper and higher is better."),
    "fig5_rmse_over_time.png": ("Figure 5: convergence over time",
                                "Ground-truth RMSE / d (paper Eq. 10) of the pose after each ICP iteration against "
                                "elapsed time (preprocessing included), one line per registration problem; each "
                                "marker is the end of an ICP iteration (paper Fig. 5), so the first marker's time "
                                "includes the preprocessing. Fewer, longer steps show as widely spaced markers."),
    "fig6_runtime.png": ("Figure 6: runtime composition",
                         "Stacked time per phase for the high-noise (σ = 2 d) problems, as in paper Fig. 6. "
                         "'other' is time_total_s minus the four measured phases. The hatched 'target "
                         "preparation' segment (target_build_s) is built once per target and cached by the server, "
                         "so it is not part of time_total_s. The label gives the total and the iteration count."),
    "fig7_filter_ablation.png": ("Figure 7: correspondence filtering",
                                 "Box plots (same style as Figure 3, successful runs only) of the final RMSE / d "
                                 "for each filter variant in ablation.csv, as in paper Fig. 7."),
    "fig_iterations.png": ("Iterations per registration",
                           "Box plots of the ICP iteration count of all runs with status ok (box 25th-75th "
                           "percentile, whiskers 5th-95th, line = median), per synthetic noise level. The label "
                           "gives how many runs stopped at the iteration limit."),
}


def write_report(path, figdir, inputs, sets, syn, meta, figures):
    lines = ["# Evaluation", "",
             "Accuracy, robustness and runtime of the registration methods on synthetic virtual scans and on "
             "real scans, in the style of Dutta, Russig and Gumhold (2019), *Moving Least Squares "
             "Correspondences for Iterative Point Set Registration*. RMSE is measured against the ground-truth "
             "pose over all source points (paper Eq. 10) in units of the target's mean sampling distance d "
             "(paper Eq. 11); a registration is successful when RMSE < 5 d.", "",
             "This report is generated by `bash scripts/evaluate.sh`.", "", "## Inputs", ""]
    for fname, rows in inputs:
        if rows is None:
            lines.append("- `%s`: not found (no data; figures that need it are skipped)" % fname)
        else:
            bad = sum(r.get("status") != "ok" for r in rows)
            lines.append("- `%s`: %d rows, %d with status other than ok (counted as failures)"
                         % (fname, len(rows), bad))
            if fname == "synthetic.csv" and any(noise_key(r) is None for r in rows):
                lines[-1] += "; %d rows without a noise_sigma_d value are ignored" % sum(
                    noise_key(r) is None for r in rows)
    lines += ["", "## Table 1: successful registrations", "",
              "Successes (RMSE < 5 d) / problems per method and data set; the synthetic columns pool all meshes. "
              "n/a: the method was not run on that data set.", ""]
    if sets:
        lines += table1(sets, syn)
        mtable, med = median_table(sets)
        lines += ["", "Median RMSE / d of the successful runs (lowest per column in bold):", ""] + mtable
        lines += ["", "## Acceptance check", "",
                  "Computed from the tables above (medians over successful runs, synthetic meshes pooled).", ""]
        lines += acceptance(sets, med)
    else:
        lines.append("No synthetic or real results.")
    lines += ["", "## Figures", ""]
    for fname, (out, note) in figures:
        title, caption = CAPTIONS[fname]
        lines += ["### " + title, ""]
        if out is None:
            lines += ["Not drawn: %s." % note, ""]
            continue
        rel = os.path.relpath(os.path.join(figdir, out), os.path.dirname(os.path.abspath(path)))
        note = " %s%s." % (note[0].upper(), note[1:]) if note else ""
        lines += ["![%s](%s)" % (title, rel.replace(os.sep, "/")), "", caption + note, ""]
    lines += runtime_section(sets, meta) + meta_section(meta)
    with open(path, "w") as f:
        f.write("\n".join(lines).rstrip() + "\n")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--results", required=True, help="folder with synthetic.csv, real.csv, ablation.csv, meta.json")
    ap.add_argument("--figures", required=True, help="output folder for the PNG figures")
    ap.add_argument("--report", required=True, help="output markdown file")
    ap.add_argument("--fig5-mesh", default="bunny", help="synthetic mesh for Figures 5 and 6 (default: bunny)")
    args = ap.parse_args()
    os.makedirs(args.figures, exist_ok=True)
    os.makedirs(os.path.dirname(os.path.abspath(args.report)), exist_ok=True)
    syn, real, abl = (load_csv(os.path.join(args.results, f)) for f in ("synthetic.csv", "real.csv", "ablation.csv"))
    meta = None
    try:
        with open(os.path.join(args.results, "meta.json")) as f:
            meta = json.load(f)
    except (OSError, ValueError):
        pass
    meta = meta if isinstance(meta, dict) else None
    sets = datasets(syn, real)
    mesh = pick_mesh(syn, args.fig5_mesh)
    note = "" if mesh in (None, args.fig5_mesh) else "; mesh %r not found, used %r" % (args.fig5_mesh, mesh)
    fig5, fig6 = fig5_rmse_over_time(syn, mesh, args.figures), fig6_runtime(syn, mesh, args.figures)
    figures = [("fig3_boxplots.png", fig3_boxplots(sets, args.figures)),
               ("fig4_alpha_recall.png", fig4_alpha_recall(sets, args.figures)),
               ("fig5_rmse_over_time.png", (fig5[0], fig5[1] + note)),
               ("fig6_runtime.png", (fig6[0], fig6[1] + note)),
               ("fig7_filter_ablation.png", fig7_filter_ablation(abl, args.figures)),
               ("fig_iterations.png", fig_iterations(sets, args.figures))]
    for fname, (out, _) in figures:  # drop a figure left over from an earlier run that has no data now
        if out is None and os.path.isfile(os.path.join(args.figures, fname)):
            os.remove(os.path.join(args.figures, fname))
    inputs = [("synthetic.csv", syn), ("real.csv", real), ("ablation.csv", abl)]
    write_report(args.report, args.figures, inputs, sets, syn, meta, figures)


if __name__ == "__main__":
    main()
