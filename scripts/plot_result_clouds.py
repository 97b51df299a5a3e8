#!/usr/bin/env python3
"""A picture of the clouds `mlsreg register --aligned A.ply --merged M.ply` writes (docs/figures/result_clouds.png):

    python3 scripts/plot_result_clouds.py A.ply M.ply out.png

Each panel is the cloud seen along -z, painted with the colours the files carry."""
import struct, sys
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
def read(path):
    data = open(path, "rb").read()
    end = data.index(b"end_header\n") + 11
    header = data[:end].decode().splitlines()
    n = int(next(l for l in header if l.startswith("element vertex")).split()[2])
    props = [l.split() for l in header if l.startswith("property")]
    dt = np.dtype([(p[2], {"double": "<f8", "float": "<f4", "uchar": "u1"}[p[1]]) for p in props])
    return np.frombuffer(data, dtype=dt, count=n, offset=end)
a, m = read(sys.argv[1]), read(sys.argv[2])
fig, axes = plt.subplots(1, 2, figsize=(11, 5.2))
for ax, c, title in ((axes[0], a, "--aligned: bun000 coloured by distance to bun045's MLS surface\n(blue 0, green 1.5 d, red >= 3 d)"),
                     (axes[1], m, "--merged: bun000 (orange) and bun045 (blue)")):
    order = np.argsort(c["z"])
    rgb = np.stack([c["red"], c["green"], c["blue"]], axis=1)[order] / 255.0
    ax.scatter(c["x"][order], c["y"][order], c=rgb, s=2.0, linewidths=0)
    ax.set_aspect("equal"); ax.set_axis_off(); ax.set_title(title, fontsize=9)
fig.tight_layout()
fig.savefig(sys.argv[3], dpi=110)
