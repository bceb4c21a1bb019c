#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# tests/bench/cli_cases_bench.sh -- times the CLI path `pendavg average --cases FILE` on the
# 1000 benchmark cases of tests/bench/cases.hpp repeated 100 times (100,000 rows), two ways:
#
#  1. whole runs (hyperfine, or a `date` loop): median seconds per run and the mean us per row
#     (everything included: reading, all rows on all cores, writing);
#  2. per row (`--timing-rows`): each row's thread CPU time to its formatted output line (a
#     double row's numbers are parsed by the check before the run), the timer's own cost
#     subtracted (see `pendavg average --help`). Printed per
#     run as pendavg's summary (rows: median, p90, worst), and per parameter set: the median
#     over a case's replicas, then the median, p90 and worst over the 1000 cases -- the
#     statistics of BM_double_case_distribution. Worst single rows are mostly noise (interrupts,
#     other processes); the per-case median is robust to it. Reported: the median over the
#     timing runs of each statistic.
#
#   bash tests/bench/cli_cases_bench.sh PENDAVG [BENCH_DOUBLE_PENDULUM]
#
#   PENDAVG                 the pendavg CLI binary (e.g. build/pendavg)
#   BENCH_DOUBLE_PENDULUM   the bench_double_pendulum binary that writes the cases
#                           (default: tests/bench_double_pendulum next to PENDAVG, as in a CMake
#                           build tree)
# Environment: PENDAVG_BENCH_RUNS (default 5), PENDAVG_BENCH_REPLICATE (default 100),
#              PENDAVG_BENCH_DIGITS (default 16, passed as --digits),
#              PENDAVG_BENCH_COLUMNS (passed as --columns: e.g. beta_K,beta_K_error,ratio,cos_phi,
#              method,evaluations, the columns of 9ae1382; default: every column),
#              PENDAVG_BENCH_FORMAT (passed as --format: csv, json or text; default: none, csv),
#              PENDAVG_BENCH_NO_HYPERFINE=1 (use the date loop even when hyperfine is installed),
#              PENDAVG_BENCH_TIMING_RUNS (default 3; 0 skips the per-row timing),
#              PENDAVG_BENCH_TIMING_THREADS (default 1: OMP_NUM_THREADS of the timing runs),
#              PENDAVG_BENCH_LAYOUT=interleaved (default: the list repeated, as files usually
#              are: the caches hold other cases' data) or grouped (each case's replicas in a
#              row: the library benchmarks' repeated calls, warm caches).
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
timing_runs=${PENDAVG_BENCH_TIMING_RUNS:-3}
timing_threads=${PENDAVG_BENCH_TIMING_THREADS:-1}
layout=${PENDAVG_BENCH_LAYOUT:-interleaved}

[ -x "$pendavg" ] || { echo "not executable: $pendavg" >&2; exit 2; }
[ -x "$writer" ] || { echo "not executable: $writer (pass bench_double_pendulum as \$2)" >&2; exit 2; }
case "$layout" in
  interleaved) layout_flag=() ;;
  grouped) layout_flag=(--grouped) ;;
  *) echo "PENDAVG_BENCH_LAYOUT must be interleaved or grouped" >&2; exit 2 ;;
esac

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cases="$work/cases.csv"
"$writer" --write-cases "$cases" --replicate "$replicate" "${layout_flag[@]}"
rows=$(($(grep -c . "$cases") - 1))
count=$((rows / replicate))
echo "cases file: $rows rows ($count cases x $replicate, $layout)" >&2

cmd=("$pendavg" average --cases "$cases" --digits "$digits")
if [ -n "${PENDAVG_BENCH_COLUMNS:-}" ]; then cmd+=(--columns "$PENDAVG_BENCH_COLUMNS"); fi
if [ -n "${PENDAVG_BENCH_FORMAT:-}" ]; then cmd+=(--format "$PENDAVG_BENCH_FORMAT"); fi

# One checked run first: the command must succeed and print one line per row plus a header
# (after its '#' lines: the schema line; JSON: a {...} line per row after the first line).
"${cmd[@]}" >"$work/out.csv"
if [ "${PENDAVG_BENCH_FORMAT:-csv}" = json ]; then
  out_rows=$(($(grep -c '^,\?{"' "$work/out.csv") - 1))  # without the document's first line
else
  out_rows=$(($(grep -vc '^#' "$work/out.csv") - 1))
fi
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

((timing_runs > 0)) || exit 0

# Median of the numbers on stdin.
median_of() {
  sort -g | awk '{ v[NR] = $1 } END { if (NR == 0) print "nan"; else print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2 }'
}
echo "per-row timing: $timing_runs runs, OMP_NUM_THREADS=$timing_threads" >&2
: >"$work/summary.txt"
for ((i = 0; i < timing_runs; ++i)); do
  OMP_NUM_THREADS=$timing_threads "${cmd[@]}" --timing-rows "$work/rows.csv" \
    2>"$work/timing.txt" >/dev/null
  cat "$work/timing.txt" >&2
  # pendavg's summary: rows=... median_us=X p90_us=Y worst_us=Z ...
  row_stats=$(sed -n 's/.*median_us=\([0-9.]*\) p90_us=\([0-9.]*\) worst_us=\([0-9.]*\).*/\1 \2 \3/p' \
    "$work/timing.txt")
  # Per case: data row r is case r % count (interleaved) or r / replicate (grouped); the median
  # over its replicas, then the median, p90 (nearest rank) and worst over the cases.
  case_stats=$(awk -F, -v count="$count" -v rep="$replicate" -v layout="$layout" \
    'NR > 1 { c = (layout == "grouped") ? int($1 / rep) : $1 % count; print c, $3 }' \
    "$work/rows.csv" | sort -k1,1n -k2,2g |
    awk 'function med() { return (n % 2) ? v[(n + 1) / 2] : (v[n / 2] + v[n / 2 + 1]) / 2 }
         { if ($1 != c && n) { print med(), c; n = 0 } c = $1; v[++n] = $2 }
         END { if (n) print med(), c }' |
    sort -g | awk '{ v[NR] = $1; k[NR] = $2 }
      END { p = int(0.9 * NR); if (p < 0.9 * NR) p++;
            printf "%s %s %s %s\n", (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2, v[p], v[NR], k[NR] }')
  echo "$row_stats $case_stats" >>"$work/summary.txt"
  echo "  per case (median over its $replicate replicas): median/p90/worst/worst case = $case_stats" >&2
done
for column in 1 2 3 4 5 6; do
  stat[column]=$(awk -v c="$column" '{ print $c }' "$work/summary.txt" | median_of)
done
printf 'row_median_us=%s\nrow_p90_us=%s\nrow_worst_us=%s\n' "${stat[1]}" "${stat[2]}" "${stat[3]}"
printf 'case_median_us=%s\ncase_p90_us=%s\ncase_worst_us=%s\n' "${stat[4]}" "${stat[5]}" "${stat[6]}"
printf 'timing_runs=%d\nlayout=%s\n' "$timing_runs" "$layout"
