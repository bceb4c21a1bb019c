#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Dynamics figures from TABLES_DIR's dynamics CSVs (written by tables/dynamics_tables.py).

usage: plot_dynamics.py TABLES_DIR     writes, each atomically, into TABLES_DIR/figures/:
  fig3_4_kinetic_vs_i.png   the paper's Figs. 3-4: time averages <K_i> and <K_i^(c)> against i for
                            N = 16 (and N = 7), with error bars, and the exact microcanonical values
  fig9_poincare.png         the paper's Fig. 9: Poincare sections (phi_2, p_2) at four energies
"""
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from figure_io import pyplot, read_table, save_figure, table_dirs  # noqa: E402

plt = pyplot()
TABLES, FIGURES = table_dirs(sys.argv)


def read(name):
    return read_table(TABLES, name)


# ---------------------------------------------------------------- Figs. 3-4
runs = read("dynamics_paper_runs.csv")
fig, axes = plt.subplots(1, 2, figsize=(12, 4.6))
for ax, n in zip(axes, ("16", "7")):
    rows = [r for r in runs if r["N"] == n and r["integrator"] == "yoshida6"]
    paper = [r for r in runs if r["N"] == n and r["integrator"] == "yoshida4"]
    i = [int(r["i"]) for r in rows]
    ax.errorbar([int(r["i"]) + 0.2 for r in paper], [float(r["K"]) for r in paper],
                yerr=[2 * float(r["K_error"]) for r in paper], fmt="x", color="tab:gray", capsize=2,
                ms=5, label=r"$\overline{K_i}$, the paper's Yoshida-4 run ($\pm 2\sigma$)")
    ax.errorbar(i, [float(r["K"]) for r in rows], yerr=[2 * float(r["K_error"]) for r in rows], fmt="o",
                color="tab:blue", capsize=3, label=r"$\overline{K_i}$ (Yoshida-6 trajectory, $\pm 2\sigma$)")
    ax.errorbar(i, [float(r["Kc"]) for r in rows], yerr=[2 * float(r["Kc_error"]) for r in rows], fmt="s",
                color="tab:orange", capsize=3, markerfacecolor="none",
                label=r"$\overline{K_i^{(c)}}$ (trajectory, $\pm 2\sigma$)")
    ax.plot(i, [float(r["exact_K"]) for r in rows], "-", color="tab:blue", lw=1.2,
            label=r"exact microcanonical $\langle K_i\rangle_E$")
    ax.axhline(float(rows[0]["exact_Kc"]), color="tab:orange", ls="--", lw=1.2,
               label=r"exact $\langle K_i^{(c)}\rangle_E = \langle K\rangle_E / N$")
    ax.set_xlabel("particle $i$ (1 = next to the pivot)")
    ax.set_ylabel(r"time-averaged kinetic energy ($m g l$ units)")
    ax.set_title(f"N = {n}, unit masses and lengths, g = 1, " + r"$\varphi_i(0) = \pi/2$, $T = 10^4$",
                 fontsize=10)
    ax.set_xticks(i)
    ax.grid(True, alpha=0.3)
axes[0].legend(fontsize=8, loc="upper left")
fig.suptitle("Paper Figs. 3-4: non-uniform $\\langle K_i\\rangle$, uniform $\\langle K_i^{(c)}\\rangle$ "
             "(RATTLE + Yoshida-6, dt = 1e-3) against the exact fixed-energy values")
fig.tight_layout(rect=(0, 0, 1, 0.94))
save_figure(fig, FIGURES, "fig3_4_kinetic_vs_i.png")

# ---------------------------------------------------------------- Fig. 9
points = read("poincare.csv")
energies = list(dict.fromkeys(r["E_above_min"] for r in points))
fig, axes = plt.subplots(1, len(energies), figsize=(3.9 * len(energies), 4.4))
cmap = plt.get_cmap("tab20")
for ax, above in zip(axes, energies):
    rows = [r for r in points if r["E_above_min"] == above]
    for orbit in sorted({int(r["orbit"]) for r in rows}):
        mine = [r for r in rows if int(r["orbit"]) == orbit]
        ax.plot([float(r["phi2"]) for r in mine], [float(r["p2"]) for r in mine], ".", ms=1.5,
                color=cmap(orbit % 20))
    energy = float(rows[0]["energy"])
    # The boundary of the allowed region on the section: p2^2 = 2 (E + 2 + cos phi2), drawn
    # only where it exists (cos phi2 >= -(E + 2)).
    reach = math.pi if energy + 2 >= 1 else math.acos(-(energy + 2))
    phi = [-reach + 2 * reach * k / 400 for k in range(401)]
    edge = [math.sqrt(max(0.0, 2 * (energy + 2 + math.cos(x)))) for x in phi]
    ax.plot(phi, edge, "-", color="0.5", lw=0.8)
    ax.plot(phi, [-e for e in edge], "-", color="0.5", lw=0.8)
    ax.set_xlim(-min(math.pi, 1.1 * reach), min(math.pi, 1.1 * reach))
    ax.set_xlabel(r"$\varphi_2$ (rad)")
    ax.set_title(f"$E - E_{{min}}$ = {above}  (E = {energy:g})", fontsize=10)
    ax.grid(True, alpha=0.3)
axes[0].set_ylabel(r"$p_2$ (canonical momentum, $m l^2$/time units)")
fig.suptitle(r"Paper Fig. 9: Poincare sections $\varphi_1 = 0$, $\dot\varphi_1 > 0$ of the unit double "
             "pendulum (16 orbits x 300 crossings; grey: energy boundary)")
fig.tight_layout(rect=(0, 0, 1, 0.93))
save_figure(fig, FIGURES, "fig9_poincare.png")
