# Draws the convergence of one registration as a PNG (mlsreg register --plot). Embedded in the
# mlsreg binary and run with python3 + matplotlib; reads the JSON the CLI writes:
#   {"title", "iteration", "stage", "candidate", "rmse_d", "gt_rmse_d" (or null), "matched",
#    "rejected_normal", "rejected_curvature", "rejected_distance", "invalid"}
#
# Exit codes the CLI turns into one line each (python_script.h): 3 when matplotlib is missing,
# 4 when the picture cannot be written; the reason is the last line on stderr.
import json
import sys

try:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: E402
except ImportError as e:
    print(f"{sys.executable} cannot import matplotlib ({e})", file=sys.stderr)
    sys.exit(3)

data = json.load(open(sys.argv[1]))
out = sys.argv[2]
x = list(range(1, len(data["iteration"]) + 1))  # runs of auto restart their iteration count
fig, (top, bottom) = plt.subplots(2, 1, figsize=(8, 6.5), sharex=True,
                                  gridspec_kw={"height_ratios": [3, 2]})
top.semilogy(x, data["rmse_d"], "o-", ms=3, color="#1f77b4", label="correspondence RMSE")
if data.get("gt_rmse_d"):
    top.semilogy(x, data["gt_rmse_d"], "s-", ms=3, color="#d62728",
                 label="RMSE against ground truth")
    top.axhline(5.0, color="#d62728", lw=0.8, ls=":", label="success threshold (5 d)")
top.set_ylabel("RMSE (units of d)")
top.grid(True, which="both", alpha=0.3)
bottom.plot(x, data["matched"], "-", color="#2ca02c", label="matched")
for key, colour in [("rejected_normal", "#ff7f0e"), ("rejected_curvature", "#9467bd"),
                    ("rejected_distance", "#8c564b"), ("invalid", "#7f7f7f")]:
    if any(data[key]):
        bottom.plot(x, data[key], "-", color=colour,
                    label=key.replace("_", " ").replace("rejected", "rejected:"))
bottom.set_ylabel("correspondences")
bottom.set_xlabel("iteration")
bottom.grid(True, alpha=0.3)
# Method auto: shade the stages of the path to the result (the winner's refinement, then the
# final one) and label them.
stages = data["stage"]
start = 0
shades = {"start": "#eeeeee", "candidate": "#fff3e0", "final": "#e8f5e9", "finish": "#e3f2fd"}
for i in range(1, len(stages) + 1):
    if i == len(stages) or stages[i] != stages[start]:
        if stages[start] in shades and len(set(stages)) > 1:
            for ax in (top, bottom):
                ax.axvspan(start + 0.5, i + 0.5, color=shades[stages[start]], zorder=0)
            label = stages[start]
            if label == "candidate":
                label = f"candidate {data['candidate'][start]}"
            top.text((start + i + 1) / 2, 1.0, label, transform=top.get_xaxis_transform(),
                     ha="center", va="bottom", fontsize=8)
        start = i
top.legend(fontsize=8, loc="upper right")
bottom.legend(fontsize=8, loc="upper right")
fig.suptitle(data["title"], fontsize=10)
fig.tight_layout()
try:
    fig.savefig(out, dpi=110)
except (OSError, ValueError) as e:
    print(f"cannot write '{out}': {getattr(e, 'strerror', None) or e}", file=sys.stderr)
    sys.exit(4)
