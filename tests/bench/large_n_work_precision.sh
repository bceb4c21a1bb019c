#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# The large-N study (issue 13): the transfer operator against randomized lattice QMC on unit
# chains, one process per (N, beta), one thread, thread CPU time (tests/bench/bench_large_n.cpp).
#   tables/large_n_work_precision.csv  every run: method, work, seconds, true and reported errors
#                                       (N = 5 with the torus; N = 16 and 64 at beta = 0.1, 1, 10)
#   tables/large_n_timings.csv          the Aim targets: N = 16 to 1e-8, 64 to 1e-7, 256 to 1e-6
#                                       (one thread), 1024 to 1e-5 (two threads), beta = 0.1, 1, 10
#   tables/large_n_fits.csv,            fitted convergence rates and the errors at equal time
#   tables/large_n_equal_time.csv       (tests/bench/large_n_summary.py)
# Then tables/figures/plot_large_n.py draws the figure. About 15 minutes on a shared 2-core machine:
#   tests/bench/large_n_work_precision.sh [BUILD_DIR [TABLES_DIR]]
# PENDAVG_LARGE_N_STEPS="wp aims summary" selects steps (default: all three).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
build=${1:-$here/../../build}
tables=${2:-$here/../../tables}
bench=$build/tests/bench_large_n
python=${PYTHON:-/usr/bin/python3}
steps=${PENDAVG_LARGE_N_STEPS:-wp aims summary}
[ -x "$bench" ] || { echo "no $bench: build first (cmake --build $build --target bench_large_n)" >&2; exit 2; }
log() { printf '[large-n] %s\n' "$*" >&2; }
tmp=""  # the table being written; removed if the run stops before it is renamed into place
trap '[ -z "$tmp" ] || rm -f "$tmp"' EXIT
trap 'exit 130' INT
trap 'exit 143' TERM
stamp="pendavg $(git -C "$here" rev-parse --short HEAD 2>/dev/null || echo unknown), $(date -u +%Y-%m-%dT%H:%M:%SZ) (UTC), $(nproc) cores"

if [[ " $steps " == *" wp "* ]]; then
  tmp=$(mktemp "$tables/large_n_work_precision.csv.tmp.XXXXXX")
  {
    echo "# Work precision for large N (issue 13): transfer (the transfer operator along the chain;"
    echo "# transfer-level: one resolution (n, m) of its refinement ladder, no estimate) against today's"
    echo "# qmc (rank-1 lattice, pivot law, 16 shifts) and qmc over the von Mises law; torus for N = 5."
    echo "# Unit chains (m_i = l_i = 1, g = 1). seconds: thread CPU time, one thread, median of 3 (qmc"
    echo "# runs of 2^16 points and more: one run). err_*: true errors, largest over the particles, against"
    echo "# a finer transfer level (its own accuracy in the '# N = ...' lines). work: kernel evaluations"
    echo "# (transfer), points x shifts (qmc), nodes (torus). By tests/bench/large_n_work_precision.sh, $stamp."
    first=1
    for case in "5 1 16" "16 0.1 20" "16 1 20" "16 10 20" "64 0.1 18" "64 1 18" "64 10 18"; do
      set -- $case
      log "work precision N = $1, beta = $2"
      if [ $first = 1 ]; then
        "$bench" wp "$1" "$2" "$3"; first=0
      else
        "$bench" wp "$1" "$2" "$3" | sed '/^method,/d'
      fi
    done
  } > "$tmp"
  chmod 644 "$tmp"  # mktemp creates 0600
  mv -f "$tmp" "$tables/large_n_work_precision.csv"
fi

if [[ " $steps " == *" aims "* ]]; then
  tmp=$(mktemp "$tables/large_n_timings.csv.tmp.XXXXXX")
  {
    echo "# The Aim targets of issue 13: pendavg::average(method transfer) to a tolerance; wall and process"
    echo "# CPU seconds (median of 3), the final resolution (n angle nodes, m pivot nodes), the largest true"
    echo "# errors (against a run 1e4 times tighter, at most 1e-12; its largest error estimate in"
    echo "# reference_check) and reported errors of beta<K_i>, beta^2 Var K_i, <cos phi_i>; uncovered: how"
    echo "# many of the 3N quantities' reported errors (plus reference_check) miss the true error;"
    echo "# worst_true_over_reported: the largest such ratio. By tests/bench/large_n_work_precision.sh, $stamp."
    header=header
    for case in "16 1e-8 1" "64 1e-7 1" "256 1e-6 1" "1024 1e-5 2"; do
      set -- $case
      for beta in 0.1 1 10; do
        log "timing N = $1, beta = $beta, tol = $2, threads = $3"
        "$bench" aims "$1" "$beta" "$2" "$3" 3 $header
        header=
      done
    done
  } > "$tmp"
  chmod 644 "$tmp"
  mv -f "$tmp" "$tables/large_n_timings.csv"
fi

if [[ " $steps " == *" summary "* ]]; then
  log "fits and equal-time errors"
  "$python" "$here/large_n_summary.py" "$tables"
  "$python" "$tables/figures/plot_large_n.py" "$tables"
fi
log done
