#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Speed against error: every available pendavg method on a fixed set of cases (issue 5, item g).

usage: work_precision.py PENDAVG      writes the CSV to stdout (make_tables.sh renames it into
                                      place atomically); progress goes to stderr. The averages come
                                      from the Python module pendavg (on PYTHONPATH), the dynamics
                                      from the CLI PENDAVG.

true_error = |beta_K[0] - reference|, subtracted exactly in decimal (60 digits). The reference is
`integral --digits 100` for N = 2 and `torus-trapezoid --digits 30` for N = 3; a true error below the
reference's own resolution (its error estimate plus half a unit in its last printed digit,
`ref_floor` in the header) is not resolvable and is only known to be <= ref_floor.
seconds = median over 3 runs of the library call's wall time (Averages.seconds: the stopwatch of the
CLI's `seconds` field, around the same call).
"""
import json
import statistics
import subprocess
import sys
from datetime import datetime, timezone
from decimal import Decimal as D, getcontext

import pendavg

getcontext().prec = 60
PENDAVG = sys.argv[1]
REPEATS = 3

# name, masses, lengths, g, beta
CASES = [
    ("mu1=0.5 beta=1", "0.5,0.5", "1,1", "1", "1"),
    ("mu1=0.05 beta=10", "0.05,0.95", "1,1", "1", "10"),
    ("mu1=1e-6 beta=100", "1e-6,0.999999", "1,1", "1", "100"),
    ("chain N=3 beta=1", "1,1,1", "1,1,1", "1", "1"),
]
SAMPLES = ["4096", "16384", "65536"]
# Dynamics: constrained Langevin (BAOAB + RATTLE, dt = 1e-3, friction 1, from the hanging chain
# at rest) for these averaging times, on the cases where it mixes well (beta = 1).
DYNAMICS_TIMES = ["100", "1000", "10000"]
DYNAMICS_CASES = ("mu1=0.5 beta=1", "chain N=3 beta=1")


def configs(n, name):
    """(method, setting, options of pendavg.average) in the order they appear in the table."""
    out = []
    if n == 2:
        out += [("integral", f"digits={d}", {"digits": d}) for d in ("16", "24", "38", "77")]
        if not name.startswith("mu1=1e-6"):
            out += [("series", f"digits={d}", {"digits": d}) for d in ("16", "38")]
        tols = ["1e-6", "1e-9", "1e-12"]
    else:
        tols = [f"1e-{k}" for k in range(6, 14)]
    for method in ("torus-trapezoid", "torus-gauss"):
        out += [(method, f"tol={t}", {"tol": t}) for t in tols]
    out += [("qmc", f"samples={s}", {"samples": s}) for s in SAMPLES]
    return out


def run(masses, lengths, g, beta, method, options):
    """pendavg.average on the same decimal strings the CLI would read: its strings and seconds.
    (The error's strings under their output schema 1 name, beta_K_error, or "error" from a module
    that still has the schema 0 name.)"""
    r = pendavg.average(masses.split(","), lengths.split(","), beta, g, method=method, **options)
    error = r.decimal["beta_K_error"] if "beta_K_error" in r.decimal else r.decimal["error"]
    return {"beta_K": r.decimal["beta_K"], "error": error, "digits": r.digits,
            "evaluations": r.evaluations, "seconds": r.seconds}


def simulate(masses, lengths, g, beta, time):
    """The CLI's run: the table reformats its 10-digit JSON numbers (the module's full doubles
    would move last digits of the derived columns)."""
    n = len(masses.split(","))
    cmd = [PENDAVG, "simulate", "--masses", masses, "--lengths", lengths, "--g", g,
           "--phi", ",".join(["0"] * n), "--thermostat", "langevin", "--beta", beta,
           "--time", time, "--exact", "no", "--format", "json"]
    return json.loads(subprocess.run(cmd, capture_output=True, text=True, check=True).stdout)


def ulp_half(s):
    """Half a unit in the last printed digit of the decimal string s."""
    t = D(s).as_tuple()
    return D(5) * D(10) ** (t.exponent - 1)


version = pendavg.__version__
rows, notes = [], []
for name, masses, lengths, g, beta in CASES:
    n = len(masses.split(","))
    ref_method, ref_digits = ("integral", "100") if n == 2 else ("torus-trapezoid", "30")
    print(f"[work_precision] {name}: reference {ref_method} --digits {ref_digits}", file=sys.stderr)
    ref = run(masses, lengths, g, beta, ref_method, {"digits": ref_digits})
    ref_value = D(ref["beta_K"][0])
    ref_floor = D(ref["error"][0]) + ulp_half(ref["beta_K"][0])
    notes.append(f"# reference {name}: {ref_method} --digits {ref_digits}, beta_K1 = {ref['beta_K'][0]}, "
                 f"error {ref['error'][0]}, ref_floor {float(ref_floor):.1e} ({ref['seconds']:.3f} s)")
    for method, setting, options in configs(n, name):
        results = [run(masses, lengths, g, beta, method, options) for _ in range(REPEATS)]
        first = results[0]
        true_error = abs(D(first["beta_K"][0]) - ref_value)
        rows.append([name, str(n), method, setting, str(first["digits"]), f"{float(true_error):.3e}",
                     first["error"][0], f"{statistics.median(r['seconds'] for r in results):.3e}",
                     str(first["evaluations"])])
    if name in DYNAMICS_CASES:
        for time in DYNAMICS_TIMES:
            print(f"[work_precision] {name}: dynamics T = {time}", file=sys.stderr)
            d = simulate(masses, lengths, g, beta, time)
            value = D(repr(d["K"][0])) * D(beta)  # beta<K1> from the time average of K1
            true_error = abs(value - ref_value)
            reported = 3 * d["K_error"][0] * float(beta)
            rows.append([name, str(n), "dynamics", f"T={time}", "16", f"{float(true_error):.3e}",
                         f"{reported:.3e}", f"{d['seconds']:.3e}", str(d["steps"])])
    if n == 2 and name.startswith("mu1=1e-6"):
        for d in ("16", "38"):
            rows.append([name, str(n), "series", f"digits={d}", d, "skipped", "", "", ""])

print("# Speed against error (work precision): beta<K1> by every available pendavg method on four cases;")
print("# cases: double pendulum l = 1,1, g = 1 at (m 0.5,0.5; beta 1), (m 0.05,0.95; beta 10),")
print("# (m 1e-6,0.999999; beta 100), and the chain N = 3 of unit masses/lengths at beta = 1.")
print("# true_error = |beta_K1 - reference| (exact decimal subtraction); reported_error = the engine's own")
print("# absolute error estimate of beta_K1 (qmc: the 99.9% Student-t multiple of the standard error, 4.07 for 16 shifts); seconds = median of 3 runs of the library call")
print("# (the CLI's `seconds`, process start excluded); evaluations = the engine's work count.")
print("# A true_error below the reference's ref_floor is not resolvable (only <= ref_floor is known).")
print("# series is skipped for mu1 = 1e-6 (rows 'skipped'): it converges like mu2^n = 0.999999^n and needs")
print("# millions of terms. torus-* and qmc run in double (digits 16); --tol applies to torus-* only.")
print("# dynamics: pendavg simulate --thermostat langevin (BAOAB + RATTLE, dt 1e-3, friction 1, from rest at")
print("# phi = 0) for T = 100, 1000, 10000 on the beta = 1 cases; beta<K1> = beta x time average of K1;")
print("# reported_error = 3 blocking standard errors; one run each (seconds of the run, evaluations = steps).")
for line in notes:
    print(line)
print(f"# generated by tables/make_tables.sh (work_precision.py) with pendavg {version} on "
      f"{datetime.now(timezone.utc).strftime('%Y-%m-%d')}")
print("case,N,method,setting,digits,true_error,reported_error,seconds,evaluations")
for row in rows:
    print(",".join(row))
