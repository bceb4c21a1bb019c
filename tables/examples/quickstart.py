#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Quickstart: the paper's Fig. 5 -- beta<K_i> of the double pendulum m1 = m2 = 1/2,
l1 = l2 = 1 (g = 1) against beta, with its beta -> 0 and beta -> infinity limits.

usage: PYTHONPATH=build/python python3 tables/examples/quickstart.py [OUT.png]   (default fig5.png)
"""
import sys

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pendavg  # noqa: E402

beta = np.logspace(-3, 3, 61)
r = pendavg.average([0.5, 0.5], [1, 1], beta)      # 61 points on all cores; r.beta_K.shape == (61, 2)
hot = pendavg.limit([0.5, 0.5]).high_temperature   # beta -> 0: (mu1/2) K(k)/E(k), k^2 = mu2
for i, color in ((0, "tab:blue"), (1, "tab:red")):
    plt.semilogx(beta, r.beta_K[:, i], color=color, label=rf"$\beta\langle K_{i + 1}\rangle$")
    plt.axhline(hot.beta_K[i], ls="--", lw=1, color=color)
plt.axhline(0.5, ls=":", color="gray", label=r"$\beta\to\infty$: 1/2")
plt.xlabel(r"$\beta$")
plt.legend()
plt.savefig(sys.argv[1] if len(sys.argv) > 1 else "fig5.png")
print(f"beta<K_i> at beta = 1: {r.beta_K[30]} +- {r.beta_K_error[30]} ({r.method[30]}, {r.beta_K_error_kind[30]})")
