#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Hostile sweep (issue 11): extreme parameters through `pendavg average` for N = 1..6 (600 runs: N = 6
by the automatic method, the transfer operator, and by qmc; 20 s each at most); reports every NaN/inf with exit 0, bad rejection format, other exit code or timeout.
Usage: python3 tests/bench/hostile_sweep.py build/pendavg"""
import json, subprocess, sys, itertools, math
P = sys.argv[1]
def run(args, timeout=20):
    try:
        r = subprocess.run([P] + args, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return "TIMEOUT", "", ""
    return r.returncode, r.stdout, r.stderr
bad = []
count = 0
for n in (1, 2, 3, 4, 6):
    for beta in ("1e-300", "1e-30", "1e-3", "1", "1e3", "1e8", "1e15", "1e35", "1e100", "1e300"):
        for masses, lengths, g in [
            ("1", "1", "1"), ("1e-300", "1", "1"), ("1e300", "1", "1"), ("1", "1e-200", "1"), ("1", "1e300", "1"),
            ("1", "1", "1e-300"), ("1", "1", "1e300"), ("1", "1", "0"), ("1e-320", "1", "1"), ("1", "1e-320", "1")]:
            if n == 1: m, l = masses, lengths
            else:
                m = ",".join(["1"] * (n - 1) + [masses]); l = ",".join([lengths] + ["1"] * (n - 1))
            base = ["average", "--masses", m, "--lengths", l, "--g", g, "--beta", beta, "--format", "json"]
            variants = [base]
            if n >= 5: variants.append(base + ["--method", "qmc", "--samples", "1024", "--shifts", "4"])
            for args in variants:
              code, out, err = run(args)
              count += 1
              label = " ".join(args[1:])
              if code == "TIMEOUT": bad.append(("TIMEOUT", label)); continue
              if code == 0:
                  try:
                      o = json.loads(out)
                  except Exception:
                      bad.append(("INVALID JSON", label, out[:80])); continue
                  text = out.lower()
                  if "nan" in text or "inf" in text:
                      bad.append(("NAN/INF exit 0", label, o.get("converged"), out[:120]))
              elif code == 2:
                  if err.count("\n") != 1 or out: bad.append(("REJECTION FORMAT", label, err[:100]))
              else:
                  bad.append((f"EXIT {code}", label, err[:120]))
print(f"{count} runs, {len(bad)} problems")
for b in bad: print(*b)
