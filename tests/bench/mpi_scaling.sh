#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# tests/bench/mpi_scaling.sh -- strong scaling of pendavg's sweeps under MPI, 1 and 2 ranks with
# one OpenMP thread each, on realistic rows (>= 1 ms) and on the double `--cases` run:
#   sweep77   `table --beta log:1e-3:1e3:100 --mu1 0.001,0.05,0.5,0.95,0.999 --digits 77`: 500
#             rows at 77 digits;
#   torus4    `table --chain 4 --beta log:0.1:10:100 --g 1,2`: 200 rows of N = 4 (torus);
#   transfer  `table --chain 64 --beta log:0.1:10:200`: 200 transfer rows of N = 64;
#   cases     `average --cases` of 20,000 rows in double (tests/bench/cases.hpp x 20).
# The sweep's own time comes from the test build's report (pendavg_row_faults beside pendavg,
# PENDAVG_SWEEP_REPORT=1: from the sweep's start to its last row written; mpirun's start-up,
# reading and checking excluded), with the share of that time the compute threads spent in rows
# ("busy"). Runs alternate 1 rank, 2 ranks and a pair (two 1-rank runs of the whole sweep at
# once, one per core), REPEATS times each, and the medians are compared:
#   efficiency     T(1) / (2 T(2)), the target's measure, of the medians and of the fastest
#                  runs (the machine's noise only ever adds time);
#   machine        T(1) / T(pair): how much slower a row is when both cores compute (the VM's
#                  share of any loss; 100% = none);
#   distribution   T(pair) / (2 T(2)): the 2-rank run against two serial runs on the same loaded
#                  machine, and busy(2) / busy(1): both are the distribution's own share.
# The load average is printed before and after (the machine is shared). Then the per-row costs
# of sweep77 go to mpi_model.py, the model of a 10^6-row sweep on 1,000 ranks.
#
#   bash tests/bench/mpi_scaling.sh build/pendavg [REPEATS] [NAMES]
# (REPEATS default 5; NAMES: the workloads to run, default "sweep77 torus4 transfer cases" --
# transfer's N = 64 rows take ~1 s of a core each: 200 s for one 1-rank run)
set -euo pipefail
(($# >= 1)) || { echo "usage: $0 PENDAVG [REPEATS]" >&2; exit 2; }
pendavg=$(realpath "$1")
repeats=${2:-5}
names=" ${3:-sweep77 torus4 transfer cases} "
build=$(dirname "$pendavg")
faulty=$build/tests/pendavg_row_faults
writer=$build/tests/bench_double_pendulum
here=$(dirname "$(realpath "$0")")
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
mpirun=(mpirun --bind-to core --map-by core --mca btl self,vader --mca plm isolated
        -x OMP_NUM_THREADS=1 -x PENDAVG_SWEEP_REPORT=1)
"$writer" --write-cases "$work/cases.csv" --replicate 20 >/dev/null
workloads=(
  "sweep77|table --beta log:1e-3:1e3:100 --mu1 0.001,0.05,0.5,0.95,0.999 --digits 77"
  "torus4|table --chain 4 --beta log:0.1:10:100 --g 1,2"
  "transfer|table --chain 64 --beta log:0.1:10:200"
  "cases|average --cases $work/cases.csv"
)
echo "load average $(cut -d' ' -f1-3 /proc/loadavg) at the start ($(nproc) cores)"
# "seconds busy%" from the test build's report line
report() { sed -n 's/^pendavg: test: sweep .*computed, \([0-9.]*\) s.*threads busy \([0-9.]*\)%.*/\1 \2/p'; }
for workload in "${workloads[@]}"; do
  name=${workload%%|*}
  [[ $names == *" $name "* ]] || continue
  read -r -a args <<<"${workload#*|}"
  for ((k = 0; k < repeats; ++k)); do
    for ranks in 1 2; do
      echo "$name $ranks $("${mpirun[@]}" -n "$ranks" "$faulty" "${args[@]}" \
                            --output "$work/out.csv" 2>&1 >/dev/null | report)"
    done
    for core in 0 1; do
      OMP_NUM_THREADS=1 PENDAVG_SWEEP_REPORT=1 taskset -c "$core" "$faulty" "${args[@]}" \
        --output "$work/pair$core.csv" 2>&1 >/dev/null | report >"$work/pair$core" &
    done
    wait
    echo "$name pair $(cat "$work/pair0")"
    echo "$name pair $(cat "$work/pair1")"
  done
done | tee "$work/runs.txt"
echo "load average $(cut -d' ' -f1-3 /proc/loadavg) at the end"
python3 - "$work/runs.txt" <<'PY'
import statistics, sys
runs = {}
for line in open(sys.argv[1]):
    name, ranks, seconds, busy = line.split()
    runs.setdefault(name, {}).setdefault(ranks, []).append((float(seconds), float(busy)))
for name, r in runs.items():
    t = {k: statistics.median(s for s, _ in v) for k, v in r.items()}
    b = {k: statistics.median(u for _, u in v) for k, v in r.items()}
    fastest = {k: min(s for s, _ in v) for k, v in r.items()}
    print(f"{name:8s} 1 rank {t['1']:.3f} s (busy {b['1']:.1f}%), 2 ranks {t['2']:.3f} s "
          f"(busy {b['2']:.1f}%), pair {t['pair']:.3f} s (medians of {len(r['1'])}): "
          f"efficiency {t['1'] / (2 * t['2']):.1%} (of the fastest runs, "
          f"{fastest['1'] / (2 * fastest['2']):.1%}); machine {t['1'] / t['pair']:.1%}; "
          f"distribution {t['pair'] / (2 * t['2']):.1%}, busy {b['2'] / b['1']:.1%}")
PY
"$pendavg" table --beta log:1e-3:1e3:100 --mu1 0.001,0.05,0.5,0.95,0.999 --digits 77 2>/dev/null |
  python3 -c '
import csv, sys
rows = csv.DictReader(l for l in sys.stdin if not l.startswith("#"))
print("beta,g,m1,m2,l1,l2")
for r in rows:
    print(",".join(r[k] for k in ("beta", "g", "m1", "m2", "l1", "l2")))' >"$work/sweep_cases.csv"
OMP_NUM_THREADS=1 "$pendavg" average --cases "$work/sweep_cases.csv" --digits 77 \
  --timing-rows "$work/row_us.csv" >/dev/null
python3 "$here/mpi_model.py" "$work/row_us.csv"
python3 "$here/mpi_model.py" "$work/row_us.csv" --mean-ms 20
