#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""Timings of the Python module (issue 12 targets): one N = 2 call in double from Python, the same
point through the CLI as a subprocess (what scripts paid before the module), and a 61 x 61
(beta, l2) grid in double on all cores.

usage: PYTHONPATH=build/python python3 tests/bench/bench_python.py [PATH/TO/pendavg]
Medians of repeated timings (wall time, time.perf_counter); the load average is printed beside
them, since the machine may be shared.
"""
import json
import os
import statistics
import subprocess
import sys
import time
import timeit

import numpy as np
import pendavg

CLI = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "../../build/pendavg")


def per_call(f, number, repeat):
    """Median and minimum of `repeat` timings of `number` calls, per call (seconds)."""
    times = sorted(t / number for t in timeit.repeat(f, number=number, repeat=repeat))
    return statistics.median(times), times[0]


def report(name, median, best, unit, scale):
    print(f"{name:58s} median {median * scale:10.3f} {unit}   (min {best * scale:.3f})")


print(f"pendavg {pendavg.__version__}, {os.cpu_count()} cores, load average "
      f"{' '.join(f'{x:.2f}' for x in os.getloadavg())}")

# One point, N = 2, double: the call and the result object (fields are read on demand).
point = lambda: pendavg.average([0.5, 0.5], [1.0, 1.0], 1.0)  # noqa: E731
point()
report("average([0.5, 0.5], [1, 1], 1.0)  (one N = 2 point, double)",
       *per_call(point, 2000, 31), "us", 1e6)
read = lambda: pendavg.average([0.5, 0.5], [1.0, 1.0], 1.0).beta_K  # noqa: E731
report("  ... and reading .beta_K (a numpy array)", *per_call(read, 2000, 31), "us", 1e6)
library = pendavg.average([0.5, 0.5], [1.0, 1.0], 1.0).seconds
print(f"{'  the library call inside it (Averages.seconds, one run)':58s}        {library * 1e6:10.3f} us")


# The same point through the CLI (subprocess + JSON), as tables/*.py used to.
def cli_call():
    out = subprocess.run([CLI, "average", "--masses", "0.5,0.5", "--lengths", "1,1", "--beta", "1",
                          "--format", "json"], capture_output=True, text=True, check=True).stdout
    return json.loads(out)["beta_K"]


if os.path.exists(CLI):
    cli_call()
    report("pendavg average ... --format json  (subprocess + json)", *per_call(cli_call, 1, 41),
           "ms", 1e3)

# 61 x 61 (beta, l2) grid, double pendulum mu1 = 0.5, double.
beta = np.logspace(-3, 3, 61)
l2 = np.logspace(-1, 1, 61)
grid = lambda: pendavg.average([0.5, 0.5], [1.0, l2[None, :]], beta[:, None])  # noqa: E731
sweep = lambda: pendavg.sweep(beta=beta, l2=l2)  # noqa: E731
r = grid()
assert r.beta_K.shape == (61, 61, 2)
report("61 x 61 (beta, l2) grid: average(..., [1, l2[None, :]], beta[:, None])",
       *per_call(grid, 1, 21), "s", 1)
report("61 x 61 (beta, l2) grid: sweep(beta=beta, l2=l2)", *per_call(sweep, 1, 21), "s", 1)
print(f"{'  library time per point (median of Averages.seconds)':58s}        "
      f"{np.median(r.seconds) * 1e6:10.3f} us")
start = time.perf_counter()
serial = [pendavg.average([0.5, 0.5], [1.0, l], b).beta_K for b in beta for l in l2]
print(f"{'  the same 3721 points as scalar calls in a Python loop':58s}        "
      f"{time.perf_counter() - start:10.3f} s")
assert np.array_equal(np.array(serial).reshape(61, 61, 2), r.beta_K)
