#!/usr/bin/env bash
# tests/bench/cli_cases_bench.sh -- times the CLI path `pendavg average --cases FILE` on the
# 1000 benchmark cases of tests/bench/cases.hpp repeated 100 times (100,000 rows).
#
#   bash tests/bench/cli_cases_bench.sh PENDAVG [BENCH_DOUBLE_PENDULUM]
#
#   PENDAVG                 the pendavg CLI binary (e.g. build/pendavg)
#   BENCH_DOUBLE_PENDULUM   the bench_double_pendulum binary that writes the cases
#                           (default: tests/bench_double_pendulum next to PENDAVG, as in a CMake
#                           build tree)
# Environment: PENDAVG_BENCH_RUNS (default 5), PENDAVG_BENCH_REPLICATE (default 100),
#              PENDAVG_BENCH_DIGITS (default 16, passed as --digits),
#              PENDAVG_BENCH_NO_HYPERFINE=1 (use the date loop even when hyperfine is installed).
#
# Uses hyperfine when it is installed (1 warm-up run, PENDAVG_BENCH_RUNS measured runs), else a
# loop timed with `date +%s.%N`. Prints the median seconds per run and microseconds per row.
set -euo pipefail

if (($# < 1)); then
  echo "usage: $0 PENDAVG [BENCH_DOUBLE_PENDULUM]" >&2
  exit 2
fi
pendavg=$(realpath "$1")
writer=${2:-$(dirname "$pendavg")/tests/bench_double_pendulum}
runs=${PENDAVG_BENCH_RUNS:-5}
replicate=${PENDAVG_BENCH_REPLICATE:-100}
digits=${PENDAVG_BENCH_DIGITS:-16}

[ -x "$pendavg" ] || { echo "not executable: $pendavg" >&2; exit 2; }
[ -x "$writer" ] || { echo "not executable: $writer (pass bench_double_pendulum as \$2)" >&2; exit 2; }

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cases="$work/cases.csv"
"$writer" --write-cases "$cases" --replicate "$replicate"
rows=$(($(grep -c . "$cases") - 1))
echo "cases file: $rows rows ($replicate x $((rows / replicate)))" >&2

cmd=("$pendavg" average --cases "$cases" --digits "$digits")

# One checked run first: the command must succeed and print one line per row plus a header.
"${cmd[@]}" >"$work/out.csv"
out_rows=$(($(wc -l <"$work/out.csv") - 1))
if ((out_rows != rows)); then
  echo "pendavg printed $out_rows rows for $rows input rows" >&2
  exit 1
fi

if [ "${PENDAVG_BENCH_NO_HYPERFINE:-0}" != 1 ] && command -v hyperfine >/dev/null 2>&1; then
  echo "timing with hyperfine ($runs runs)" >&2
  printf -v quoted '%q ' "${cmd[@]}"
  hyperfine --warmup 1 --runs "$runs" --style basic \
    --export-json "$work/hyperfine.json" "$quoted >/dev/null" >&2
  # hyperfine's JSON has "median": <seconds> per command.
  median=$(grep -o '"median": *[0-9.eE+-]*' "$work/hyperfine.json" | head -n1 | sed 's/.*: *//')
else
  echo "timing with date +%s.%N ($runs runs)" >&2
  times=()
  for ((i = 0; i < runs; ++i)); do
    start=$(date +%s.%N)
    "${cmd[@]}" >/dev/null
    end=$(date +%s.%N)
    times+=("$(awk -v a="$start" -v b="$end" 'BEGIN { printf "%.6f", b - a }')")
  done
  echo "run times (s): ${times[*]}" >&2
  median=$(printf '%s\n' "${times[@]}" | sort -g |
    awk '{ v[NR] = $1 } END { print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2 }')
fi

awk -v m="$median" -v r="$rows" \
  'BEGIN { printf "median_seconds_per_run=%.6f\nus_per_row=%.4f\nrows=%d\n", m, m * 1e6 / r, r }'
