#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Work-precision figure from TABLES_DIR/work_precision.csv: seconds (x) vs true error (y), log-log,
one panel per case, one line per method; the method's reported error is the lighter open marker.

usage: plot_work_precision.py TABLES_DIR      writes TABLES_DIR/figures/work_precision.pdf and .png (300 dpi) atomically
"""
import csv
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from figure_io import pyplot, save_figure, table_dirs  # noqa: E402

plt = pyplot()
from matplotlib.lines import Line2D  # noqa: E402

TABLES, FIGURES = table_dirs(sys.argv)
NAME = "work_precision.png"
STYLE = {  # method: (color, marker)
    "integral": ("tab:blue", "o"),
    "series": ("tab:orange", "s"),
    "torus-trapezoid": ("tab:green", "^"),
    "torus-gauss": ("tab:red", "v"),
    "qmc": ("tab:purple", "D"),
    "dynamics": ("tab:brown", "P"),
}
FLOOR = 1e-110  # true errors of exactly 0 (never seen so far) are drawn here

with open(os.path.join(TABLES, "work_precision.csv")) as fh:
    rows = [r for r in csv.DictReader(l for l in fh if not l.startswith("#")) if r["seconds"]]
cases = list(dict.fromkeys(r["case"] for r in rows))

fig, axes = plt.subplots(2, 2, figsize=(11, 8.5), sharex=True)
for ax, case in zip(axes.flat, cases):
    mine = [r for r in rows if r["case"] == case]
    for method, (color, marker) in STYLE.items():
        pts = [r for r in mine if r["method"] == method]
        if not pts:
            continue
        x = [float(r["seconds"]) for r in pts]
        ax.plot(x, [max(float(r["true_error"]), FLOOR) for r in pts], "-", color=color, marker=marker,
                markersize=6, lw=1.2, label=f"{method} (true)")
        ax.plot(x, [float(r["reported_error"]) for r in pts], linestyle="none", marker=marker, markersize=7,
                markerfacecolor="none", markeredgecolor=color, alpha=0.4)
    ax.axhline(1e-15, color="0.6", ls=":", lw=1)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_title(case + ("  (series skipped)" if case.startswith("mu1=1e-6") else ""), fontsize=10)
    ax.grid(True, which="major", alpha=0.3)
for ax in axes[1]:
    ax.set_xlabel("seconds (library call, median of 3)")
for ax in axes[:, 0]:
    ax.set_ylabel(r"absolute error of $\beta\langle K_1\rangle$")
handles = [Line2D([], [], color=c, marker=m, label=meth) for meth, (c, m) in STYLE.items()]
handles += [Line2D([], [], color="0.3", marker="o", label="true error (filled, joined)"),
            Line2D([], [], color="0.3", marker="o", markerfacecolor="none", linestyle="none", alpha=0.4,
                   label="reported error (open, light)"),
            Line2D([], [], color="0.6", ls=":", label="1e-15")]
fig.legend(handles=handles, loc="lower center", ncol=4, fontsize=9, frameon=False)
fig.suptitle("pendavg work precision: speed against error (true error vs 100-digit / 30-digit reference)")
fig.tight_layout(rect=(0, 0.07, 1, 0.97))

save_figure(fig, FIGURES, NAME)
