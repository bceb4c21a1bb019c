#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# tests/bench/mpi_scaling.sh -- strong scaling of pendavg's sweeps under MPI (issue 14), 1 and 2
# ranks with one OpenMP thread each, on the issue's two workloads and ten times longer ones:
#   cases     `average --cases` of 20,000 rows in double: the 1000 seeded benchmark cases of
#             tests/bench/cases.hpp repeated 20 times (rows of 1 to ~100 us, ~0.08 s in all);
#   sweep     `table --beta log:1e-3:1e3:100 --mu1 0.001,0.05,0.5,0.95,0.999 --digits 77`: 500
#             rows at 77 digits (rows of 0.1 to 3 ms, ~0.25 s in all);
#   cases10x  the same cases 200 times (200,000 rows);
#   sweep10x  the same sweep with 1000 betas (5000 rows).
# Each run prints the sweep engine's report (PENDAVG_SWEEP_REPORT=1: the sweep's wall time, from
# the first row handed out to the last written, and the rows each rank computed); the whole
# command's wall time (mpirun's start-up, reading, checking every row, writing) is measured
# too. The runs alternate 1 and 2 ranks, REPEATS times each; the shared machine's other load
# makes single runs noisy, so the minimum (the least disturbed run) and the median are shown.
# Efficiency at 2 ranks = T(1 rank) / (2 T(2 ranks)). The two vCPUs of a VM need not be equally
# fast (on this machine the second one is at times ~45% slower, for seconds to minutes), so each
# repetition also runs one rank on the second core ("1b", started with taskset, unbound), and the
# capacity efficiency T_ideal / T(2 ranks), T_ideal = 1 / (1/T(1 rank) + 1/T(1b)), compares the
# 2-rank run with what the two cores did alone within the same few seconds.
# On a machine shared with other work, run it in a session of its own with a high group
# priority (Linux autogroups: nice values only count within a session), e.g. as root
#   setsid bash -c 'echo -19 > /proc/$$/autogroup; bash tests/bench/mpi_scaling.sh build/pendavg 7'
# (that is how the README's numbers were taken).
# Finally the per-row costs of the 77-digit sweep (--timing-rows) go to mpi_model.py, which
# estimates the efficiency of a 10^6-row 77-digit sweep on 1,000 ranks.
#
#   bash tests/bench/mpi_scaling.sh build/pendavg [REPEATS]     (REPEATS default 7)
#
# Needs the build's tests/bench_double_pendulum (writes the cases) and mpirun (OpenMPI).
set -euo pipefail

if (($# < 1)); then
  echo "usage: $0 PENDAVG [REPEATS]" >&2
  exit 2
fi
pendavg=$(realpath "$1")
repeats=${2:-7}
writer=$(dirname "$pendavg")/tests/bench_double_pendulum
here=$(dirname "$(realpath "$0")")
[ -x "$writer" ] || { echo "not executable: $writer" >&2; exit 2; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
mpirun=(mpirun --bind-to core --map-by core --mca btl self,vader --mca plm isolated
        -x OMP_NUM_THREADS=1 -x PENDAVG_SWEEP_REPORT=1)

"$writer" --write-cases "$work/cases.csv" --replicate 20 >/dev/null
"$writer" --write-cases "$work/cases10x.csv" --replicate 200 >/dev/null
mu1=0.001,0.05,0.5,0.95,0.999
workloads=(
  "cases|average --cases $work/cases.csv --output $work/out.csv"
  "sweep|table --beta log:1e-3:1e3:100 --mu1 $mu1 --digits 77 --output $work/out.csv"
  "cases10x|average --cases $work/cases10x.csv --output $work/out.csv"
  "sweep10x|table --beta log:1e-3:1e3:1000 --mu1 $mu1 --digits 77 --output $work/out.csv"
)
echo "machine: $(nproc) cores, load average $(cut -d' ' -f1-3 /proc/loadavg) at the start"
echo "workload ranks run sweep_s command_s per_rank(rows/chunks/busy_s)"
for workload in "${workloads[@]}"; do
  name=${workload%%|*}
  read -r -a args <<<"${workload#*|}"
  for ((k = 0; k < repeats; ++k)); do
    for ranks in 1 1b 2; do
      start=$(date +%s.%N)
      if [ "$ranks" = 1b ]; then
        report=$(taskset -c 1 "${mpirun[@]}" --bind-to none -n 1 "$pendavg" "${args[@]}" 2>&1 >/dev/null |
                 grep '^pendavg: sweep:')
      else
        report=$("${mpirun[@]}" -n "$ranks" "$pendavg" "${args[@]}" 2>&1 >/dev/null | grep '^pendavg: sweep:')
      fi
      end=$(date +%s.%N)
      seconds=$(sed 's/.* seconds=\([0-9.]*\) .*/\1/' <<<"$report")
      per_rank=$(sed 's/.*per_rank(rows\/chunks\/busy_s)=//' <<<"$report")
      echo "$name $ranks $k $seconds $(awk -v a="$start" -v b="$end" 'BEGIN { printf "%.4f", b - a }') $per_rank"
    done
  done
done | tee "$work/runs.txt"
echo "load average $(cut -d' ' -f1-3 /proc/loadavg) at the end"
python3 - "$work/runs.txt" <<'PY'
import statistics, sys
runs = {}
for line in open(sys.argv[1]):
    parts = line.split()
    if len(parts) < 5 or parts[0] not in ("cases", "sweep", "cases10x", "sweep10x"):
        continue
    runs.setdefault((parts[0], parts[1]), {})[int(parts[2])] = (float(parts[3]), float(parts[4]))
for name in ("cases", "sweep", "cases10x", "sweep10x"):
    one, other, two = runs[(name, "1")], runs[(name, "1b")], runs[(name, "2")]
    for what, col in (("sweep phase", 0), ("whole command", 1)):
        t1 = [r[col] for r in one.values()]
        t2 = [r[col] for r in two.values()]
        print(f"{name:8s} {what:13s}: 1 rank min {min(t1):.4f} s median {statistics.median(t1):.4f} s; "
              f"2 ranks min {min(t2):.4f} s median {statistics.median(t2):.4f} s; efficiency "
              f"{min(t1) / (2 * min(t2)):.1%} (minima), {statistics.median(t1) / (2 * statistics.median(t2)):.1%} (medians)")
    # Capacity efficiency, repetition by repetition (sweep phase).
    capacity = [1 / (1 / one[k][0] + 1 / other[k][0]) / two[k][0] for k in two if k in one and k in other]
    t1b = [r[0] for r in other.values()]
    print(f"{name:8s} second core alone: min {min(t1b):.4f} s median {statistics.median(t1b):.4f} s; "
          f"capacity efficiency median {statistics.median(capacity):.1%}, best {max(capacity):.1%}")
PY

# Per-row costs of the 77-digit sweep (the same points as cases, thread CPU time per row), and
# the model of 1,000 ranks.
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
