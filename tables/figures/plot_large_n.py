#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Large-N figures (issue 13), each drawn only when its table exists:

  large_n_work_precision.png  from large_n_work_precision.csv, large_n_fits.csv and
                              large_n_timings.csv (tests/bench/large_n_work_precision.sh): seconds
                              against the largest true error of beta<K_i>, transfer vs qmc, with
                              the fitted rates; the timing targets
  chain_profiles.png          from chain_profiles.csv (make_tables.sh): beta<K_i> against i/N for
                              N = 8..1024 at beta = 0.1, 1, 10 with error bars, and the reported
                              errors themselves (log scale) below

usage: plot_large_n.py TABLES_DIR      writes TABLES_DIR/figures/*.pdf and *.png (300 dpi), each atomically
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from figure_io import BETA, pyplot, read_table, save_figure, table_dirs  # noqa: E402

plt = pyplot()
from matplotlib.lines import Line2D  # noqa: E402

TABLES, FIGURES = table_dirs(sys.argv)


def exists(name):
    return os.path.exists(os.path.join(TABLES, name))


def f(rows, key):
    return [float(r[key]) for r in rows]


STYLE = {  # method: (color, marker, label)
    "transfer": ("tab:green", "o", "transfer (tolerance 1e-3..1e-12)"),
    "transfer-level": ("tab:olive", ".", "transfer, one level (n, m(n))"),
    "qmc-pivot": ("tab:purple", "D", "qmc (today's: pivot law, 16 shifts)"),
    "qmc-vonmises": ("tab:pink", "v", "qmc, von Mises law"),
    "torus": ("tab:blue", "^", "torus trapezoid"),
}
FLOOR = 1e-16


def work_precision():
    rows = read_table(TABLES, "large_n_work_precision.csv")
    fits = read_table(TABLES, "large_n_fits.csv") if exists("large_n_fits.csv") else []
    panels = [("16", 0.1), ("16", 1.0), ("16", 10.0), ("64", 0.1), ("64", 1.0), ("64", 10.0), ("5", 1.0)]
    fig, axes = plt.subplots(3, 3, figsize=(14, 12))
    for ax, (n, beta) in zip(axes.flat, panels):
        mine = [r for r in rows if r["N"] == n and float(r["beta"]) == beta]
        for method, (color, marker, _) in STYLE.items():
            pts = [r for r in mine if r["method"] == method]
            if not pts:
                continue
            x = f(pts, "seconds")
            fit = [r for r in fits if r["N"] == n and float(r["beta"]) == beta and r["method"] == method]
            rate = ""
            if fit:
                rate = (f"e^({float(fit[0]['rate']):.2f} n)" if method == "transfer-level"
                        else f"work^{float(fit[0]['rate']):.2f}")
            ax.plot(x, [max(float(r["err_Kmax"]), FLOOR) for r in pts], "-" if method != "transfer" else "",
                    color=color, marker=marker, ms=6 if marker != "." else 9, lw=1.2, label=rate or None)
            if pts[0]["reported_Kmax"]:
                ax.plot(x, f(pts, "reported_Kmax"), linestyle="none", marker=marker, ms=7,
                        markerfacecolor="none", markeredgecolor=color, alpha=0.5)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_ylim(1e-17, 1)
        ax.set_title(f"N = {n}, {BETA} = {beta:g} (unit chain)", fontsize=10)
        ax.grid(True, which="major", alpha=0.3)
        ax.set_xlabel("seconds (one thread, CPU)")
        ax.set_ylabel(r"largest true error of $\beta\langle K_i\rangle$")
        if any(l.get_label() and not l.get_label().startswith("_") for l in ax.lines):
            ax.legend(fontsize=7, title="fitted", title_fontsize=7, loc="lower left")
    # The timing targets.
    ax = axes.flat[7]
    if exists("large_n_timings.csv"):
        timings = read_table(TABLES, "large_n_timings.csv")
        aims = {"16": (1e-8, 10), "64": (1e-7, 10), "256": (1e-6, 30), "1024": (1e-5, 60)}
        for beta, color in (("0.1", "tab:blue"), ("1", "tab:green"), ("10", "tab:red")):
            pts = [r for r in timings if float(r["beta"]) == float(beta)]
            ax.plot(f(pts, "N"), f(pts, "wall_seconds"), "o-", color=color, label=f"beta = {beta}")
        for n, (tol, limit) in aims.items():
            ax.plot([float(n)], [limit], marker="_", ms=20, color="k")
            ax.annotate(f"aim {limit:g} s\n(tol {tol:g})", (float(n), limit), fontsize=7,
                        textcoords="offset points", xytext=(4, 4))
        ax.set_xscale("log", base=2)
        ax.set_yscale("log")
        ax.set_xlabel("N (N = 1024 on 2 threads, else 1)")
        ax.set_ylabel("wall seconds to the tolerance")
        ax.set_title("timing targets: transfer to 1e-8, 1e-7, 1e-6, 1e-5", fontsize=10)
        ax.grid(True, which="major", alpha=0.3)
        ax.legend(fontsize=7)
    else:
        ax.axis("off")
    ax = axes.flat[8]
    ax.axis("off")
    handles = [Line2D([], [], color=c, marker=m, label=label) for c, m, label in STYLE.values()]
    handles += [Line2D([], [], color="0.3", marker="o", label="true error (filled)"),
                Line2D([], [], color="0.3", marker="o", markerfacecolor="none", linestyle="none",
                       alpha=0.5, label="reported error (open)")]
    ax.legend(handles=handles, loc="center", fontsize=9, frameon=False)
    fig.suptitle("Large N: the transfer operator against randomized lattice QMC (true errors vs a finer "
                 "transfer level)")
    fig.tight_layout()
    save_figure(fig, FIGURES, "large_n_work_precision.png")


def profiles():
    rows = read_table(TABLES, "chain_profiles.csv")
    ns = sorted({int(r["N"]) for r in rows})
    betas = sorted({float(r["beta"]) for r in rows})
    fig, axes = plt.subplots(2, len(betas), figsize=(5 * len(betas), 8.5), sharex=True,
                             gridspec_kw={"height_ratios": [3, 1.4]})
    colors = plt.cm.viridis([k / max(1, len(ns) - 1) for k in range(len(ns))])
    for col, beta in enumerate(betas):
        top, bottom = axes[0][col], axes[1][col]
        for n, color in zip(ns, colors):
            mine = sorted((r for r in rows if int(r["N"]) == n and float(r["beta"]) == beta),
                          key=lambda r: int(r["i"]))
            x = f(mine, "i_over_N")
            top.errorbar(x, f(mine, "beta_K"), yerr=f(mine, "error_K"), color=color, lw=1,
                         marker="o" if n <= 32 else None, ms=3, capsize=2 if n <= 32 else 0,
                         elinewidth=1, label=f"N = {n}")
            bottom.plot(x, f(mine, "error_K"), color=color, lw=1, marker="." if n <= 32 else None)
        top.axhline(0.5, ls=":", color="gray", lw=1)
        top.set_title(f"{BETA} = {beta:g}")
        top.grid(True, alpha=0.3)
        bottom.set_yscale("log")
        bottom.grid(True, which="major", alpha=0.3)
        bottom.set_xlabel("i / N  (i = 1 next to the pivot, i = N the free end)")
    axes[0][0].set_ylabel(r"$\beta\langle K_i\rangle$ (error bars: reported errors)")
    axes[1][0].set_ylabel(r"reported error of $\beta\langle K_i\rangle$")
    axes[0][0].legend(fontsize=8)
    fig.suptitle("Unit chains (m_i = l_i = 1, g = 1): where along the chain the kinetic energy piles up "
                 "(transfer method)")
    fig.tight_layout()
    save_figure(fig, FIGURES, "chain_profiles.png")


if exists("large_n_work_precision.csv"):
    work_precision()
if exists("chain_profiles.csv"):
    profiles()
