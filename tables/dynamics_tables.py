#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Dynamics tables (issues 4 and 5): trajectories that confirm the exact averages.

usage: dynamics_tables.py PENDAVG TABLES_DIR     writes, each atomically (temp file + rename):
  dynamics_paper_runs.csv   the paper's runs (Figs. 3-4): N = 7 and N = 16 unit chains, g = 1,
                            phi_i(0) = pi/2 at rest, RATTLE in Yoshida-6 (the default) and in the
                            paper's Yoshida-4, dt = 1e-3, T = 1e4;
                            <K_i>, <K_i^(c)> with 1-sigma blocking error bars beside the exact
                            microcanonical values at the run's energy E = 0.
  dynamics_confirmation.csv N = 2 and N = 3 fixed-energy (NVE) runs against the exact
                            microcanonical averages, and constrained Langevin runs against the exact
                            canonical ones, T = 1e4: deviations in combined error bars.
  dynamics_fig5.csv         Langevin time averages of beta<K_i> for the double pendulum of Fig. 5
                            (m = 1/2, 1/2, l = 1, 1) at several beta, with <cos phi_i> (Fig. 8):
                            the paper's MCMC symbols, here from trajectories.
  poincare.csv              Poincare sections (paper Fig. 9) of the unit double pendulum at energies
                            0.1, 0.2, 1, 2 and 3 above the minimum (the paper's E = 0.1, 0.2, 1.0 read
                            as measured from the hanging chain at rest; at 2 the outer link can go
                            over the top; 3 is the paper's N = 2 start, E = 0).
Progress goes to stderr.
"""
import json
import os
import subprocess
import sys
import tempfile
from datetime import datetime, timezone

PENDAVG, TABLES = sys.argv[1], sys.argv[2]
# The first line of --version, "pendavg X.Y.Z" (the other lines name the build).
VERSION = subprocess.run([PENDAVG, "--version"], capture_output=True, text=True,
                         check=True).stdout.splitlines()[0].removeprefix("pendavg ")
TODAY = datetime.now(timezone.utc).strftime("%Y-%m-%d")


def log(message):
    print(f"[dynamics] {message}", file=sys.stderr, flush=True)


def write_atomically(name, text):
    fd, tmp = tempfile.mkstemp(prefix=name + ".tmp.", dir=TABLES)
    try:
        with os.fdopen(fd, "w") as fh:
            fh.write(text)
        os.replace(tmp, os.path.join(TABLES, name))
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def simulate(masses, lengths, *args):
    cmd = [PENDAVG, "simulate", "--masses", masses, "--lengths", lengths, "--format", "json", *args]
    return json.loads(subprocess.run(cmd, capture_output=True, text=True, check=True).stdout)


def ones(n):
    return ",".join(["1"] * n)


def g(x, digits=10):
    return f"{x:.{digits}g}"


# ---------------------------------------------------------------- the paper's runs
rows, notes = [], []
for n in (7, 16):
    for integrator in ("yoshida6", "yoshida4"):
        log(f"the paper's N = {n} run: T = 1e4, 1e7 steps of RATTLE + {integrator}, then the exact values")
        d = simulate(ones(n), ones(n), "--theta", "90deg", "--time", "1e4", "--integrator", integrator)
        notes.append(f"# N = {n} ({integrator}): energy {g(d['energy'], 6)}, steps {d['steps']}, seconds "
                     f"{d['seconds']:.1f} (the trajectory, one core), energy_error_max "
                     f"{d['energy_error_max']:.2e}, energy_error_rms {d['energy_error_rms']:.2e}, energy_drift "
                     f"{d['energy_drift']:.2e}, constraint_residual {d['constraint_residual']:.2e}, exact: "
                     f"{d['exact_method']}")
        for i in range(n):
            rows.append([str(n), integrator, str(i + 1), g(d["K"][i]), g(d["K_error"][i], 3), g(d["Kc"][i]),
                         g(d["Kc_error"][i], 3), g(d["exact_K"][i]), g(d["exact_K_error"][i], 3),
                         g(d["exact_Kc"]), f"{d['K_deviation_sigmas'][i]:.2f}"])
log("the N = 16 run again with the 9-stage sixth-order Kahan-Li composition (energy errors only)")
d = simulate(ones(16), ones(16), "--theta", "90deg", "--time", "1e4", "--integrator", "kahan-li6", "--exact", "no")
notes.append(f"# N = 16 with --integrator kahan-li6 (9 RATTLE stages per step): seconds {d['seconds']:.1f}, "
             f"energy_error_max {d['energy_error_max']:.2e}, energy_error_rms {d['energy_error_rms']:.2e}, "
             f"energy_drift {d['energy_drift']:.2e}, constraint_residual {d['constraint_residual']:.2e}; "
             f"<K_1> = {g(d['K'][0], 6)} +- {g(d['K_error'][0], 2)}, <K_16> = {g(d['K'][-1], 6)} +- "
             f"{g(d['K_error'][-1], 2)}")
text = ("# The paper's runs (Figs. 3-4): unit masses and lengths, g = 1, phi_i(0) = pi/2, phidot = 0 (E = 0),\n"
        "# RATTLE in Cartesian coordinates inside a symmetric composition, dt = 1e-3, T = 1e4: yoshida4 is the\n"
        "# paper's 4th-order triple jump, yoshida6 (pendavg's default) Yoshida's 7-stage 6th-order one.\n"
        "# K, Kc: time averages of K_i and of the canonical kinetic energy K_i^(c) = p_i phidot_i / 2 with\n"
        "# 1-sigma error bars (blocking). exact_K: the exact microcanonical <K_i>_E at the run's energy\n"
        "# (src/engine/microcanonical/README.md; QMC, 99.9% Student-t bars); exact_Kc = <K>_E / N for every i. K_deviation_sigmas =\n"
        "# (K - exact_K) / sqrt(K_error^2 + exact_K_error^2). Energy errors are relative to (sum m) g (sum l).\n"
        + "\n".join(notes) + "\n"
        f"# generated by tables/make_tables.sh (dynamics_tables.py) with pendavg {VERSION} on {TODAY}\n"
        "N,integrator,i,K,K_error,Kc,Kc_error,exact_K,exact_K_error,exact_Kc,K_deviation_sigmas\n"
        + "".join(",".join(r) + "\n" for r in rows))
write_atomically("dynamics_paper_runs.csv", text)

# ---------------------------------------------------------------- confirmation, N = 2 and 3
CONFIRM = [  # label, masses, lengths, initial condition, ensemble args
    ("N=2 NVE E=0", "1,1", "1,1", ["--theta", "90deg"], []),
    ("N=3 NVE E=0", "1,1,1", "1,1,1", ["--theta", "90deg"], []),
    ("N=2 Langevin beta=1", "1,1", "1,1", ["--theta", "0"], ["--thermostat", "langevin", "--beta", "1"]),
    ("N=3 Langevin beta=1", "1,1,1", "1,1,1", ["--theta", "0"], ["--thermostat", "langevin", "--beta", "1"]),
]
rows = []
for label, masses, lengths, start, ensemble in CONFIRM:
    log(f"confirmation: {label}, T = 1e4")
    d = simulate(masses, lengths, *start, "--time", "1e4", *ensemble)
    n = d["particles"]
    beta = d.get("beta", "")
    for i in range(n):
        kc_dev = (d["Kc"][i] - d["exact_Kc"]) / d["Kc_error"][i]
        rows.append([label, str(n), d["ensemble"], g(beta) if beta != "" else "", g(d["energy"], 6),
                     g(d["time"], 6), str(i + 1), g(d["K"][i]), g(d["K_error"][i], 3), g(d["exact_K"][i]),
                     g(d["exact_K_error"][i], 3), f"{d['K_deviation_sigmas'][i]:.2f}", g(d["Kc"][i]),
                     g(d["Kc_error"][i], 3), g(d["exact_Kc"]), f"{kc_dev:.2f}",
                     f"{d['energy_error_max']:.2e}" if d["ensemble"] == "microcanonical" else "",
                     f"{d['constraint_residual']:.2e}", f"{d['seconds']:.2f}", d["exact_method"]])
text = ("# Dynamics against the exact averages: N = 2 and N = 3 unit chains (g = 1), T = 1e4, dt = 1e-3.\n"
        "# NVE: RATTLE + Yoshida-6 from phi_i = pi/2 at rest (E = 0), against the exact microcanonical\n"
        "# <K_i>_E (src/engine/microcanonical/README.md). Langevin: constrained BAOAB (friction 1) from rest at phi = 0, against\n"
        "# the exact canonical <K_i> = beta<K_i>/beta (1-D integral for N = 2, torus for N = 3) and\n"
        "# <K_i^(c)> = 1/(2 beta). Errors: 1 sigma (blocking) for the dynamics, the engines' own for the\n"
        "# exact values; deviation_sigmas = (K - exact) / combined error. Target: |deviation| <= 3.\n"
        f"# generated by tables/make_tables.sh (dynamics_tables.py) with pendavg {VERSION} on {TODAY}\n"
        "run,N,ensemble,beta,energy,time,i,K,K_error,exact_K,exact_K_error,deviation_sigmas,Kc,Kc_error,"
        "exact_Kc,Kc_deviation_sigmas,energy_error_max,constraint_residual,seconds,exact_method\n"
        + "".join(",".join(r) + "\n" for r in rows))
write_atomically("dynamics_confirmation.csv", text)

# ---------------------------------------------------------------- Fig. 5 symbols
rows = []
for beta in ("0.1", "0.3", "1", "3", "10"):
    log(f"Fig. 5 symbols: Langevin at beta = {beta}, T = 3000")
    d = simulate("0.5,0.5", "1,1", "--theta", "0", "--time", "3000", "--thermostat", "langevin",
                 "--beta", beta)
    b = float(beta)
    for i in range(2):
        rows.append([beta, str(i + 1), g(b * d["K"][i]), g(b * d["K_error"][i], 3), g(b * d["exact_K"][i]),
                     f"{d['K_deviation_sigmas'][i]:.2f}", g(d["cos_phi"][i]), g(d["cos_phi_error"][i], 3),
                     g(d["exact_cos_phi"][i])])
text = ("# Fig. 5 symbols from trajectories: double pendulum m = 1/2, 1/2, l = 1, 1, g = 1; constrained Langevin\n"
        "# (BAOAB + RATTLE, dt 1e-3, friction 1) for T = 3000 from rest at phi = 0. beta_K = beta x time\n"
        "# average of K_i, beta_K_error = 1 sigma (blocking); exact_beta_K from the 1-D integral; cos_phi: the\n"
        "# time average of cos phi_i (paper Fig. 8's MCMC symbols), 1 sigma, exact_cos_phi from the integral.\n"
        f"# generated by tables/make_tables.sh (dynamics_tables.py) with pendavg {VERSION} on {TODAY}\n"
        "beta,i,beta_K,beta_K_error,exact_beta_K,deviation_sigmas,cos_phi,cos_phi_error,exact_cos_phi\n" + "".join(",".join(r) + "\n" for r in rows))
write_atomically("dynamics_fig5.csv", text)

# ---------------------------------------------------------------- Poincare sections (Fig. 9)
comments, data = [], []
for above in ("0.1", "0.2", "1", "2", "3"):
    energy = -3 + float(above)
    log(f"Poincare section at E - E_min = {above} (E = {energy:g})")
    out = subprocess.run([PENDAVG, "poincare", "--masses", "1,1", "--lengths", "1,1", "--energy", f"{energy:g}",
                          "--orbits", "16", "--points", "300"], capture_output=True, text=True, check=True).stdout
    comments += [f"# E - E_min = {above}: " + l.lstrip("# ") for l in out.splitlines() if l.startswith("#")]
    body = [l for l in out.splitlines() if l and not l.startswith("#")]
    data += [f"{above},{energy:g},{row}" for row in body[1:]]  # body[0] is the CSV header
text = ("# Poincare sections of the unit double pendulum (m = l = g = 1): phi_1 = 0, phidot_1 > 0 (paper Fig. 9,\n"
        "# Appendix E); p2 is the canonical momentum of phi_2. Energies E - E_min = 0.1, 0.2, 1 (the paper's\n"
        "# E = 0.1, 0.2, 1.0, read as measured from the hanging chain at rest, E_min = -3), 2 (the outer link\n"
        "# can go over the top) and 3 (E = 0, the paper's start). 16 orbits each, started on the section, 300 crossings per orbit, RATTLE +\n"
        "# Yoshida-4 at dt = 1e-3, crossings refined onto the section by partial steps.\n"
        + "".join(c + "\n" for c in comments)
        + f"# generated by tables/make_tables.sh (dynamics_tables.py) with pendavg {VERSION} on {TODAY}\n"
        "E_above_min,energy,orbit,phi2,p2,time\n" + "".join(d + "\n" for d in data))
write_atomically("poincare.csv", text)
log("done")
