#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# tests/bench/merge_bench.sh -- how long `pendavg merge` takes to join 4 shards of a 100,000-row
# double table (49 MB as CSV, 126 MB as JSON), in CSV and in JSON: REPEATS runs each, the
# binaries alternating, medians and fastest runs. With a second binary (an earlier build, say)
# both are timed in the same run and their merged files compared.
#
#   bash tests/bench/merge_bench.sh build/pendavg [OTHER_PENDAVG] [REPEATS]
set -euo pipefail
(($# >= 1)) || { echo "usage: $0 PENDAVG [OTHER_PENDAVG] [REPEATS]" >&2; exit 2; }
binaries=("$(realpath "$1")")
[ -n "${2:-}" ] && binaries+=("$(realpath "$2")")
repeats=${3:-7}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mu1=$(python3 -c "print(','.join(str(round(0.01 + 0.98 * k / 49, 4)) for k in range(50)))")
for format in csv json; do
  for k in 1 2 3 4; do
    "${binaries[0]}" table --beta log:0.01:100:2000 --mu1 "$mu1" --format "$format" --shard "$k/4" \
      --output "$work/shard$k.$format" 2>/dev/null
  done
done
for format in csv json; do
  for ((r = 0; r < repeats; ++r)); do
    for b in "${!binaries[@]}"; do
      start=$(date +%s.%N)
      "${binaries[$b]}" merge --output "$work/merged$b.$format" "$work"/shard[1-4]."$format"
      echo "$format $b $(date +%s.%N) $start"
    done
  done
  if ((${#binaries[@]} > 1)); then
    cmp -s "$work/merged0.$format" "$work/merged1.$format" &&
      echo "$format: the merged files are identical" >&2 ||
      echo "$format: the merged files DIFFER" >&2
  fi
done | python3 -c '
import statistics, sys
runs = {}
for line in sys.stdin:
    fmt, b, end, start = line.split()
    runs.setdefault((fmt, int(b)), []).append(float(end) - float(start))
for (fmt, b), t in sorted(runs.items()):
    print(f"{fmt:4s} binary {b}: median {statistics.median(t):.3f} s, fastest {min(t):.3f} s "
          f"({len(t)} runs, 100,000 rows)")
'
