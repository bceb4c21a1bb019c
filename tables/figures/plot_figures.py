#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Figures of pendavg's tables (paper Figs. 5-8 and the chains), from the CSVs in TABLES_DIR.

usage: plot_figures.py TABLES_DIR      writes TABLES_DIR/figures/*.pdf and *.png (300 dpi), each atomically
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from figure_io import BETA, L2, MU1, RATIO, pyplot, read_table, save_figure, table_dirs  # noqa: E402

plt = pyplot()
TABLES, FIGURES = table_dirs(sys.argv)


def read(name):
    return read_table(TABLES, name)


def save(fig, name):
    """Writes the figure atomically to FIGURES/name."""
    save_figure(fig, FIGURES, name)


def f(rows, key):
    return [float(r[key]) for r in rows]


def select(rows, **where):
    return [r for r in rows if all(float(r[k]) == float(v) for k, v in where.items())]


def trajectory_symbols(ax, key, error_key, label):
    """Langevin time averages from dynamics_fig5.csv as open symbols with 2-sigma bars, where the
    paper showed MCMC; `label` is formatted with the particle index i."""
    if not os.path.exists(os.path.join(TABLES, "dynamics_fig5.csv")):
        return
    sym = read("dynamics_fig5.csv")
    for i, color in (("1", "tab:blue"), ("2", "tab:red")):
        mine = [r for r in sym if r["i"] == i]
        ax.errorbar(f(mine, "beta"), f(mine, key), yerr=[2 * v for v in f(mine, error_key)],
                    fmt="o", ms=5, mfc="none", color=color, capsize=3, label=label.format(i=i))


beta_rows = read("beta_sweep.csv")
l2_rows = read("l2_sweep.csv")
cos_rows = read("cos_phi.csv")
limits = {r["mu1"]: r for r in read("high_temperature_limit.csv")}
chains = read("chains.csv")
MU1_VALUES = ["0.05", "0.5", "0.95"]  # the panels of Figs. 6 and 7

# Fig. 5: beta<K_i> vs beta, mu1 = 0.5, l = 1, 1, with the beta -> 0 limits.
rows = select(beta_rows, m1=0.5, l2=1)
fig, ax = plt.subplots(figsize=(6.4, 4.4))
ax.plot(f(rows, "beta"), f(rows, "beta_K2"), "-", color="tab:red", label=r"$\beta\langle K_2\rangle$")
ax.plot(f(rows, "beta"), f(rows, "beta_K1"), "-", color="tab:blue", label=r"$\beta\langle K_1\rangle$")
lim = limits["0.5"]
for key, color, name in (("beta_K2", "tab:red", "2"), ("beta_K1", "tab:blue", "1")):
    ax.axhline(float(lim[key]), ls="--", lw=1, color=color,
               label=rf"$\beta\to0$: $\beta\langle K_{name}\rangle$ = {float(lim[key]):.10f}")
ax.axhline(0.5, ls=":", lw=1, color="gray", label=r"$\beta\to\infty$: 1/2")
trajectory_symbols(ax, "beta_K", "beta_K_error",
                   r"Langevin trajectory $\beta\overline{{K_{i}}}$ ($\pm2\sigma$)")
ax.set_xscale("log")
ax.set_xlabel(BETA)
ax.set_ylabel(r"$\beta\langle K_i\rangle$")
ax.set_title(r"Double pendulum, $\mu_1 = 1/2$, $l_1 = l_2 = 1$, $g = 1$ (paper Fig. 5: exact curves, trajectory symbols)",
             fontsize=9)
ax.set_ylim(0.3, 0.7)
ax.legend(fontsize=8, loc="center left")  # the empty band between the curves at small beta
ax.grid(True, which="both", alpha=0.3)
save(fig, "fig5_beta_K.png")

# Fig. 6: <K1>/<K2> vs l2, three panels mu1, colors beta.
fig, axes = plt.subplots(1, 3, figsize=(13, 4.2), sharey=False)
colors = plt.cm.coolwarm([0.0, 0.33, 0.67, 1.0])
for ax, mu in zip(axes, MU1_VALUES):
    for beta, color in zip(("1", "2", "5", "10"), colors):
        rows = select(l2_rows, m1=mu, beta=beta)
        ax.plot(f(rows, "l2"), f(rows, "ratio"), color=color, label=f"{BETA} = {beta}")
    ax.set_xscale("log")
    ax.set_xlabel(L2)
    ax.set_title(f"{MU1} = {mu}")
    ax.grid(True, which="both", alpha=0.3)
axes[0].set_ylabel(RATIO)
axes[-1].legend(fontsize=8)
fig.suptitle(f"{L2} dependence of {RATIO} (paper Fig. 6, exact; $l_1 = 1$, $g = 1$)")
save(fig, "fig6_ratio_vs_l2.png")

# Fig. 7: <K1>/<K2> vs beta, panels mu1, colors l2.
fig, axes = plt.subplots(1, 3, figsize=(13, 4.2))
for ax, mu in zip(axes, MU1_VALUES):
    for l2, color in zip(("0.5", "1", "2"), ("tab:green", "tab:blue", "tab:purple")):
        rows = select(beta_rows, m1=mu, l2=l2)
        ax.plot(f(rows, "beta"), f(rows, "ratio"), color=color, label=f"{L2} = {l2}")
    lim = limits[mu] if mu in limits else None
    if lim:
        ax.axhline(float(lim["ratio"]), ls="--", lw=1, color="gray", label=r"$\beta\to0$ limit")
    ax.axhline(1, ls=":", lw=1, color="gray", label=r"$\beta\to\infty$: 1")
    if mu == "0.5" and os.path.exists(os.path.join(TABLES, "dynamics_fig5.csv")):
        # Trajectory symbols (Langevin, l2 = 1), where the paper showed MCMC; the bar propagates
        # the two 1-sigma bars as if independent (x 2).
        sym = read("dynamics_fig5.csv")
        one = [r for r in sym if r["i"] == "1"]
        two = [r for r in sym if r["i"] == "2"]
        ratio = [float(a["beta_K"]) / float(b["beta_K"]) for a, b in zip(one, two)]
        bar = [2 * q * ((float(a["beta_K_error"]) / float(a["beta_K"])) ** 2 +
                        (float(b["beta_K_error"]) / float(b["beta_K"])) ** 2) ** 0.5
               for q, a, b in zip(ratio, one, two)]
        ax.errorbar(f(one, "beta"), ratio, yerr=bar, fmt="o", ms=5, mfc="none", color="tab:blue",
                    capsize=3, label=r"Langevin, $l_2 = 1$ ($\pm2\sigma$)")
    ax.set_xscale("log")
    ax.set_xlabel(BETA)
    ax.set_title(f"{MU1} = {mu}")
    ax.grid(True, which="both", alpha=0.3)
axes[0].set_ylabel(RATIO)
axes[0].legend(fontsize=8)
axes[1].legend(fontsize=8)
fig.suptitle(f"{BETA} dependence of {RATIO} (paper Fig. 7: exact curves, trajectory symbols; $l_1 = 1$, $g = 1$)")
save(fig, "fig7_ratio_vs_beta.png")

# Fig. 8: <cos phi_i> vs beta, mu1 = 0.5, l = 1, 1.
fig, ax = plt.subplots(figsize=(6.4, 4.4))
ax.plot(f(cos_rows, "beta"), f(cos_rows, "cos_phi1"), color="tab:blue", label=r"$\langle\cos\varphi_1\rangle$")
ax.plot(f(cos_rows, "beta"), f(cos_rows, "cos_phi2"), color="tab:red", label=r"$\langle\cos\varphi_2\rangle$")
trajectory_symbols(ax, "cos_phi", "cos_phi_error",
                   r"Langevin trajectory $\overline{{\cos\varphi_{i}}}$ ($\pm2\sigma$)")
ax.set_xscale("log")
ax.set_xlabel(BETA)
ax.set_ylabel(r"$\langle\cos\varphi_i\rangle$")
ax.set_title(r"$\mu_1 = 1/2$, $l_1 = l_2 = 1$, $g = 1$ (paper Fig. 8: exact curves, trajectory symbols)",
             fontsize=9)
ax.legend(fontsize=8)
ax.grid(True, which="both", alpha=0.3)
save(fig, "fig8_cos_phi.png")

# Chains: beta<K_i> vs i, one panel per beta, diagonal approximation dashed.
fig, axes = plt.subplots(1, 3, figsize=(13, 4.4), sharey=True)
colors = plt.cm.viridis([k / 6 for k in range(6)])
for ax, beta in zip(axes, ("0.1", "1", "10")):
    for n, color in zip(range(3, 9), colors):
        rows = [r for r in chains if r["N"] == str(n) and float(r["beta"]) == float(beta)]
        i = [int(r["i"]) for r in rows]
        ax.errorbar(i, f(rows, "beta_K"), yerr=f(rows, "error_K"), marker="o", ms=4, color=color,
                    label=f"N = {n}" + (" (qmc)" if rows[0]["method"] == "qmc" else ""))
        ax.plot(i, f(rows, "diagonal_approx"), ls="--", lw=1, color=color)
    ax.axhline(0.5, ls=":", color="gray", lw=1)
    ax.set_xlabel("particle index $i$ (1 = next to the pivot)")
    ax.set_title(f"{BETA} = {beta}")
    ax.grid(True, alpha=0.3)
axes[0].set_ylabel(r"$\beta\langle K_i\rangle$")
axes[0].plot([], [], "k--", lw=1, label="diagonal approx. (dashed)")
axes[0].legend(fontsize=7)
fig.suptitle(r"Chains of unit masses and links: $\beta\langle K_i\rangle$ (solid) vs the diagonal approximation (dashed)")
save(fig, "chains.png")
