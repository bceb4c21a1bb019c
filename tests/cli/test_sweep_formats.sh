#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# tests/cli/test_sweep_formats.sh -- the streamed sweeps (table, average --cases) in every
# --format (issue 27): json (one document; a row an object, in order; failed rows and the
# interruption after the rows) and text (fixed-width columns) hold the CSV's texts, value for
# value, and do everything CSV does: --output, stdout, --resume (files cut short, killed
# writers' temporaries, a resume of another format refused), --shard and merge (byte for byte
# the serial file; shards of different formats refused), MPI (1, 2, 3 ranks byte for byte the
# serial run), SIGTERM/SIGINT (a valid, closed document), failed rows (exit 3), --columns and
# --timing.
#
# Usage: test_sweep_formats.sh --list                 the case names, one a line
#        test_sweep_formats.sh PENDAVG CASE [PENDAVG_ROW_FAULTS [MPIEXEC]]
# PENDAVG_ROW_FAULTS: the test build whose rows listed in PENDAVG_TEST_FAILING_ROWS fail and
# which reports the rows it computed (PENDAVG_SWEEP_REPORT=1); MPIEXEC: for the mpi case.
# Prints "N passed, M failed" last and exits non-zero on any failure.
set -u

pendavg=${1:?usage: test_sweep_formats.sh PENDAVG CASE [PENDAVG_ROW_FAULTS [MPIEXEC]], or --list}
faulty=${3:-}
mpiexec=${4:-}
progress_lines_allowed=1
# shellcheck source=sweep_harness.sh
source "$(cd "$(dirname "$0")" && pwd)/sweep_harness.sh"
formats=(csv json text)
host=$(hostname | tr -cd 'A-Za-z0-9-' | cut -c1-64)

cases_setup() {
# Cases files: N = 2 with inputs as people write them (".5", "+1", "2.", "007"), N = 3, and an
# energy column.
"$python" - "$work" <<'PY'
import sys
work = sys.argv[1]
with open(work + "/n2.csv", "w") as f:
    f.write("beta,g,m1,m2,l1,l2\n")
    for i, beta in enumerate([".5", "+1", "2.", "007", "1e-1", "3.25E+0"] * 4):
        f.write(f"{beta},1,{['0.5', '.25', '1'][i % 3]},1,1,{['1', '2.', '0.75'][i % 3]}\n")
with open(work + "/n3.csv", "w") as f:
    f.write("beta,g,m1,m2,m3,l1,l2,l3\n")
    for i in range(12):
        f.write(f"{1 + i % 5},1,1,{1 + i % 3},1,1,1,{1 + i % 4}\n")
with open(work + "/energy.csv", "w") as f:
    f.write("energy,g,m1,m2,l1,l2\n")
    for e in ["-1.5", "0", ".5", "+2", "10"]:
        f.write(f"{e},1,1,1,1,1\n")
PY

# sweepfile.py: a sweep file's header, rows (a failed row's line too) and end, in any format;
#   cut IN OUT N BYTES    the header and the first N rows, less the last BYTES bytes
#   damage IN OUT K       row K without its last quarter (its newline kept)
#   gaps IN OUT K,L,...   the header and rows K, L, ... (a dead writer's rows, with gaps)
cat >"$work/sweepfile.py" <<'PY'
import sys
def split(path):
    lines = open(path).read().split("\n")[:-1]
    if lines[0].startswith("{"):
        h = lines.index('"rows": [') + 1
        e = next(i for i in range(h, len(lines)) if lines[i].startswith("]"))
    else:
        h = next(i for i, l in enumerate(lines) if not l.startswith("#")) + 1
        e = len(lines) - (lines[-1].startswith("# interrupted: "))
    return lines[:h], lines[h:e], lines[e:]
command, source, target, arg = sys.argv[1:5]
header, rows, end = split(source)
if command == "cut":
    text = "\n".join(header + rows[:int(arg)]) + "\n"
    text = text[:len(text) - int(sys.argv[5])]
elif command == "damage":
    k = int(arg)
    rows[k] = rows[k][:3 * len(rows[k]) // 4]
    text = "\n".join(header + rows + end) + "\n"
else:
    text = "\n".join(header + [rows[int(k)] for k in arg.split(",")]) + "\n"
open(target, "w").write(text)
PY
}
sweepfile() { "$python" "$work/sweepfile.py" "$@"; }
# same_values CSV JSON TEXT [DIGITS]: the JSON document and the text file hold the CSV file's
# header, columns, rows and values: every JSON value is the CSV text (a number written as the
# same text, or the same exact decimal where the CSV's text is no JSON number: ".5" -> 0.5), a
# string in an MPFR row (DIGITS > 16, or the row's digits column) but for the integer columns,
# null for an empty cell; every text row has the column line's length, each cell right-aligned
# under its column's name, "-" for an empty cell. '# failed:' lines are the JSON's "failed"
# entries (their row and text), '# interrupted:' its "interrupted".
same_values() {
  "$python" - "$@" <<'PY'
import json, re, sys
from decimal import Decimal
csv_path, json_path, text_path = sys.argv[1:4]
digits = int(sys.argv[4]) if len(sys.argv) > 4 and sys.argv[4] else None
integers = {"N", "digits", "evaluations"}
number = re.compile(r"-?(0|[1-9][0-9]*)(\.[0-9]+)?([eE][+-]?[0-9]+)?$")

lines = open(csv_path).read().split("\n")
assert lines[-1] == "", "the CSV does not end with a newline"
lines = lines[:-1]
header = [l for l in lines if l.startswith("#") and not l.startswith(("# failed: ", "# interrupted: "))]
body = [l for l in lines if not l.startswith("#")]
columns, rows = body[0].split(","), [r.split(",") for r in body[1:]]
csv_failed = [(i, l) for i, l in enumerate(l for l in lines[len(header) + 1:] if not l.startswith("# interrupted: ")) if l.startswith("# failed: ")]
interrupted = [l[len("# interrupted: "):] for l in lines if l.startswith("# interrupted: ")]

# JSON: every number's text as written (parse_float/parse_int see it).
raw = lambda text: ("number", text)
text = open(json_path).read()
doc = json.loads(text, parse_float=raw, parse_int=raw)
assert list(doc) == ["schema", "command", "header", "columns", "rows", "failed", "interrupted"], list(doc)
assert doc["schema"] == ("number", "1"), doc["schema"]
assert doc["header"] == [l[2:] for l in header if not l.startswith("# schema: ")], doc["header"]
assert doc["columns"] == columns, doc["columns"]
assert len(doc["rows"]) == len(rows), (len(doc["rows"]), len(rows))
for r, (obj, row) in enumerate(zip(doc["rows"], rows)):
    assert list(obj) == columns, (r, list(obj))
    mpfr = (digits or int(row[columns.index("digits")] if "digits" in columns else 16)) > 16
    for name, cell in zip(columns, row):
        value = obj[name]
        where = f"row {r} {name}: CSV {cell!r}, JSON {value!r}"
        if cell == "":
            assert value is None, where
        elif cell in ("true", "false"):
            assert value is (cell == "true"), where
        elif cell[0].isalpha():
            assert value == cell, where
        elif mpfr and name not in integers:
            assert value == cell, where
        else:
            assert isinstance(value, tuple), where
            if number.match(cell):
                assert value[1] == cell, where
            else:
                assert Decimal(value[1]) == Decimal(cell), where
# Failed rows: their row (in the sweep: the CSV's line among the rows) and the CSV line's text.
json_failed = [(f["row"][1] if isinstance(f["row"], tuple) else f["row"], f["message"]) for f in doc["failed"]]
assert [m for _, m in json_failed] == [l[len("# failed: "):] for _, l in csv_failed], (json_failed, csv_failed)
if not interrupted:  # rows numbered as in the CSV (an interrupted file's missing rows shift them)
    assert [int(k) for k, _ in json_failed] == [i for i, _ in csv_failed], (json_failed, csv_failed)
assert doc["interrupted"] == (interrupted[0] if interrupted else None), doc["interrupted"]
assert text.endswith("}\n") and text.count("\n") == 8 + len(doc["header"]) + len(rows) + \
    (len(doc["failed"]) + 1 if doc["failed"] else 0), "not one line a header item, a row, a failed row"

# Text: the CSV's '#' lines, then the aligned columns.
tl = open(text_path).read().split("\n")[:-1]
assert [l for l in tl if l.startswith("#")] == [l for l in lines if l.startswith("#")], "text's '#' lines"
assert [i for i, l in enumerate(tl) if l.startswith("#")] == [i for i, l in enumerate(lines) if l.startswith("#")]
body = [l for l in tl if not l.startswith("#")]
ends = [m.end() for m in re.finditer(r"\S+", body[0])]
assert body[0].split() == columns, body[0]
assert len(body) == len(rows) + 1
for r, (line, row) in enumerate(zip(body[1:], rows)):
    assert len(line) == len(body[0]), (r, len(line), len(body[0]))
    assert [m.end() for m in re.finditer(r"\S+", line)] == ends, (r, line)
    assert line.split() == [c if c else "-" for c in row], (r, line)
PY
}

# three_formats NAME ARGS...: pendavg ARGS --format F --output NAME.F for each format (each
# must succeed), then same_values on the three files.
three_formats() {
  local name=$1 f
  shift
  for f in "${formats[@]}"; do
    run "$@" --format "$f" --output "$work/$name.$f"
    [ "$rc" -eq 0 ] || { fail "$name: --format $f exited $rc"; return 1; }
  done
  check "$name: json and text hold the CSV's values" \
    same_values "$work/$name.csv" "$work/$name.json" "$work/$name.text" "${DIGITS:-}"
}

case:values() {
  three_formats table_inputs table --beta .5,+1,2.,007 --mu1 0.1,.25 --l2 1,2.
  three_formats table_digits table --beta 0.5,1 --mu1 0.3,0.5 --digits 16,20
  three_formats table_chains table --chain 3,5 --beta 0.5,2 --digits 16
  three_formats table_energy table --energy=-1.4,0,2 --mu1 0.5,0.25
  three_formats table_excitation table --excitation 0.5,3 --digits 20
  three_formats cases_double average --cases "$work/n2.csv"
  DIGITS=24 three_formats cases_mpfr average --cases "$work/n2.csv" --digits 24
  three_formats cases_energy average --cases "$work/energy.csv"
  # pandas reads the rows as the CSV's table (where it is installed)
  if "$python" -c 'import pandas' 2>/dev/null; then
    check "pandas.DataFrame(doc['rows']) is the CSV's table" "$python" - "$work" <<'PY'
import json, sys, pandas
work = sys.argv[1]
for name in ["table_inputs", "table_chains", "cases_double", "cases_energy"]:
    doc = json.load(open(f"{work}/{name}.json"))
    frame = pandas.DataFrame(doc["rows"])
    csv = pandas.read_csv(f"{work}/{name}.csv", comment="#", float_precision="round_trip")
    assert list(frame.columns) == list(csv.columns) == doc["columns"], name
    assert frame.shape == csv.shape, name
    numeric = [c for c in csv.columns if csv[c].dtype.kind == "f"]
    assert (frame[numeric].fillna(0).astype(float) == csv[numeric].fillna(0)).all().all(), name
PY
  fi
}

case:output() {
  local f
  for f in "${formats[@]}"; do
    # stdout and --output: the same bytes (table's header names no file)
    run table --beta 0.5,1,2 --mu1 0.25 --format "$f"
    cp "$work/out" "$work/stdout.$f"
    echo old >"$work/old.$f"
    run table --beta 0.5,1,2 --mu1 0.25 --format "$f" --output "$work/old.$f"
    check "table --format $f: --output writes what stdout gets" cmp -s "$work/old.$f" "$work/stdout.$f"
    check "table --format $f: nothing on stdout with --output" test ! -s "$work/out"
    # bad input leaves the old file as it was and no temporary
    bad "table --format $f: a bad point" table --beta 0.5,-1 --format "$f" --output "$work/old.$f"
    check "table --format $f: the old file kept after a refusal" cmp -s "$work/old.$f" "$work/stdout.$f"
    check "table --format $f: no temporary" no_temporaries
    run average --cases "$work/n3.csv" --format "$f"
    check "average --cases --format $f to stdout: exit 0" test "$rc" -eq 0
    cp "$work/out" "$work/cases_stdout.$f"
    run average --cases "$work/n3.csv" --format "$f" --output "$work/cases.$f"
    check "average --cases --format $f --output: exit 0, nothing on stdout" test "$rc" -eq 0 -a ! -s "$work/out"
  done
  check "stdout: json and text hold the CSV's values (table)" \
    same_values "$work/stdout.csv" "$work/stdout.json" "$work/stdout.text"
  check "stdout: json and text hold the CSV's values (cases)" \
    same_values "$work/cases_stdout.csv" "$work/cases_stdout.json" "$work/cases_stdout.text" 16
  check "--output: json and text hold the CSV's values (cases, with the file's header)" \
    same_values "$work/cases.csv" "$work/cases.json" "$work/cases.text" 16
  bad "table --format xml" table --beta 1 --format xml
  bad "average --cases --format xml" average --cases "$work/n3.csv" --format xml
}

case:resume() {
  local f g
  table=(table --beta log:0.1:10:15 --mu1 0.1,0.5)
  cases=(average --cases "$work/n2.csv" --digits 20)
  for f in "${formats[@]}"; do
    "$pendavg" "${table[@]}" --format "$f" --output "$work/table.$f" 2>/dev/null
    "$pendavg" "${cases[@]}" --format "$f" --output "$work/cases.$f" 2>/dev/null
    # A file cut in the middle of its 11th row: 10 rows kept, the rest computed.
    sweepfile cut "$work/table.$f" "$work/cut.$f" 11 40
    PENDAVG_SWEEP_REPORT=1 "$faulty" "${table[@]}" --format "$f" --resume "$work/cut.$f" >"$work/out" 2>"$work/err"
    check "table --format $f: a file cut mid-row resumed = an uninterrupted run" cmp -s "$work/cut.$f" "$work/table.$f"
    check "table --format $f: the cut file's 10 whole rows kept" \
      grep -q '^pendavg: test: sweep of 30 rows, 20 computed' "$work/err"
    # A damaged row (the file's row 5 without its last quarter): computed again.
    sweepfile damage "$work/cases.$f" "$work/damaged.$f" 5
    PENDAVG_SWEEP_REPORT=1 "$faulty" "${cases[@]}" --format "$f" --resume "$work/damaged.$f" >"$work/out" 2>"$work/err"
    check "average --cases --format $f: a damaged row computed again" \
      grep -q '^pendavg: test: sweep of 24 rows, 1 computed' "$work/err"
    check "average --cases --format $f: resumed = an uninterrupted run" \
      cmp -s "$work/damaged.$f" "$work/cases.$f"
    # --resume of a file that does not exist: written
    rm -f "$work/new.$f"
    run "${table[@]}" --format "$f" --resume "$work/new.$f"
    check "table --format $f: --resume of a new file writes it" cmp -s "$work/new.$f" "$work/table.$f"
  done
  # A file of another format: one line naming both, the file left as it was.
  for f in "${formats[@]}"; do
    for g in "${formats[@]}"; do
      [ "$f" = "$g" ] && continue
      cp "$work/table.$f" "$work/other"
      bad "a $f file resumed with --format $g" "${table[@]}" --format "$g" --resume "$work/other"
      check "... the line names both formats" \
        grep -qF "holds --format $f output; this run writes --format $g (give --format $f to continue it)" "$work/err"
      check "... the file left as it was" cmp -s "$work/other" "$work/table.$f"
    done
  done
  # the default format is csv: a json file needs --format json
  cp "$work/cases.json" "$work/other"
  bad "a json file resumed without --format" "${cases[@]}" --resume "$work/other"
  # A JSON file of another output schema: named.
  sed '1s/^{"schema": 1,/{"schema": 2,/' "$work/table.json" >"$work/later.json"
  bad "a json file of schema 2" "${table[@]}" --format json --resume "$work/later.json"
  check "... the line names the schema" grep -qF "was written with output schema '2'; this pendavg writes schema 1" "$work/err"
}

# The interrupted sweeps (one thread: 30 rows at 1000 digits, ~1-2 s: long enough that a kill lands mid-run): SIGTERM and SIGINT leave a
# closed file with the finished rows; SIGKILL leaves the temporary; a dead writer's temporary
# holding rows in increasing order with gaps (rows it had waiting to be written); each resumed
# = an uninterrupted run.
case:interrupted() {
  local f signal pid k rows
  slow=(table --beta log:1:1000:15 --mu1 0.001,0.05 --digits 1000)
  true &
  dead=$!
  wait "$dead"
  for f in json text; do
    signal=$([ "$f" = json ] && echo TERM || echo INT)
    OMP_NUM_THREADS=1 "$pendavg" "${slow[@]}" --format "$f" --output "$work/slow.$f" 2>/dev/null
    rows=30
    OMP_NUM_THREADS=1 "$pendavg" "${slow[@]}" --format "$f" --output "$work/stopped.$f" >"$work/out" 2>"$work/err" &
    pid=$!
    for ((k = 0; k < 300; ++k)); do  # a data row in the temporary
      [ "$(row_count "$work/stopped.$f".tmp.*)" -ge 1 ] && break
      sleep 0.05
    done
    kill "-$signal" "$pid"
    wait "$pid"
    rc=$?
    check "SIG$signal --format $f: exit 0 and a file" test "$rc" -eq 0 -a -s "$work/stopped.$f"
    if [ "$f" = json ]; then
      check "SIGTERM --format json: a valid document, its finished rows and \"interrupted\"" \
        "$python" - "$work/stopped.json" "$work/slow.json" <<'PY'
import json, sys
doc, full = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
kept = len(doc["rows"])
assert 0 < kept < 30, kept
assert doc["interrupted"] == f"{kept} of 30 points computed; the rows of the others are left out", doc["interrupted"]
assert all(row in full["rows"] for row in doc["rows"])
assert doc["failed"] == []
PY
    else
      check "SIGINT --format text: the '# interrupted:' line last" \
        grep -q '^# interrupted: [0-9]* of 30 points computed' <(tail -1 "$work/stopped.text")
    fi
    run "${slow[@]}" --format "$f" --resume "$work/stopped.$f"
    check "SIG$signal --format $f, resumed = an uninterrupted run" cmp -s "$work/stopped.$f" "$work/slow.$f"
    OMP_NUM_THREADS=1 kill_delay_max=0.3 killed_and_resumed "SIGKILL --format $f" "$work/slow.$f" "$work/killed.$f" \
      "$faulty" "${slow[@]}" --format "$f"
    # A dead writer's temporary: the header, then rows 3, 4, 10..19 and 25 (in order, gaps; the
    # rows a writer had waiting to be written).
    sweepfile gaps "$work/slow.$f" "$work/gaps.$f.tmp.$host.$dead.abcdef" 3,4,10,11,12,13,14,15,16,17,18,19,25
    PENDAVG_SWEEP_REPORT=1 "$faulty" "${slow[@]}" --format "$f" --resume "$work/gaps.$f" >"$work/out" 2>"$work/err"
    check "--format $f: a dead temporary's rows with gaps kept" \
      grep -q "^pendavg: test: sweep of $rows rows, 17 computed" "$work/err"
    check "--format $f: rows with gaps resumed = an uninterrupted run" cmp -s "$work/gaps.$f" "$work/slow.$f"
    check "--format $f: the dead temporary removed" test -z "$(ls "$work"/gaps.$f.tmp.* 2>/dev/null)"
  done
}

case:failed() {
  local f last
  table=(table --beta log:0.1:10:10 --mu1 0.1,0.5)
  cases=(average --cases "$work/n3.csv")
  for f in "${formats[@]}"; do
    "$pendavg" "${table[@]}" --format "$f" --output "$work/table_full.$f" 2>/dev/null
    # rows 0 (the first: JSON's first row is then another), 7 and 19 (the last) fail
    PENDAVG_TEST_FAILING_ROWS=0,7,19 "$faulty" "${table[@]}" --format "$f" --output "$work/table_failed.$f" \
      >"$work/out" 2>"$work/err"
    rc=$?
    check "table --format $f: failed rows exit 3" test "$rc" -eq 3
    check "table --format $f: one error line" one_error_line
    [ "$f" = json ] && check "json: the error line names the \"failed\" entries" \
      grep -qF 'has every other finished row and an entry in "failed" for each' "$work/err"
    PENDAVG_TEST_FAILING_ROWS=0,5,11 "$faulty" "${cases[@]}" --format "$f" >"$work/cases_failed.$f" 2>"$work/err"
    rc=$?
    check "average --cases --format $f to stdout: failed rows exit 3" test "$rc" -eq 3
    PENDAVG_TEST_FAILING_ROWS=$(seq -s, 0 11) "$faulty" "${cases[@]}" --format "$f" --output "$work/all_failed.$f" \
      >"$work/out" 2>"$work/err"
    rc=$?
    check "average --cases --format $f: every row failed: exit 3, a file" test "$rc" -eq 3 -a -s "$work/all_failed.$f"
    run "${table[@]}" --format "$f" --resume "$work/table_failed.$f"
    check "table --format $f: failed rows resumed = a full run" cmp -s "$work/table_failed.$f" "$work/table_full.$f"
  done
  check "failed rows: json and text hold the CSV's rows and failures (table)" \
    same_values "$work/table_failed.csv" "$work/table_failed.json" "$work/table_failed.text"
  check "failed rows: json and text hold the CSV's rows and failures (cases, stdout)" \
    same_values "$work/cases_failed.csv" "$work/cases_failed.json" "$work/cases_failed.text" 16
  check "every row failed: json and text hold the CSV's failures" \
    same_values "$work/all_failed.csv" "$work/all_failed.json" "$work/all_failed.text" 16
}

# shard_rows ROWS N K:L...: the sweep's rows (comma-separated) of shard K's row L (shard.hpp:
# blocks of B = ceil(ROWS / (16 N)) rows, shard K taking blocks K-1, K-1+N, ...)
shard_rows() {
  "$python" - "$@" <<'PY'
import sys
rows, n = int(sys.argv[1]), int(sys.argv[2])
block = max(1, -(-rows // (16 * n)))
out = []
for item in sys.argv[3:]:
    k, local = map(int, item.split(":"))
    out.append((k - 1 + n * (local // block)) * block + local % block)
print(",".join(map(str, sorted(out))))
PY
}

case:shards() {
  local f k
  table=(table --beta log:0.1:10:17 --mu1 0.1,0.5 --digits 16,18)
  cases=(average --cases "$work/n2.csv")
  for f in "${formats[@]}"; do
    "$pendavg" "${table[@]}" --format "$f" --output "$work/table.$f" 2>/dev/null
    "$pendavg" "${cases[@]}" --format "$f" --output "$work/cases.$f" 2>/dev/null
    for k in 1 2 3; do
      "$pendavg" "${table[@]}" --format "$f" --shard $k/3 --output "$work/table_$k.$f" 2>/dev/null
      "$pendavg" "${cases[@]}" --format "$f" --shard $k/3 --output "$work/cases_$k.$f" 2>/dev/null
    done
    run merge --output "$work/table_merged.$f" "$work/table_3.$f" "$work/table_1.$f" "$work/table_2.$f"
    check "table --format $f: merged shards = the serial run" cmp -s "$work/table_merged.$f" "$work/table.$f"
    run merge --output "$work/cases_merged.$f" "$work/cases_2.$f" "$work/cases_3.$f" "$work/cases_1.$f"
    check "average --cases --format $f: merged shards = the serial run" cmp -s "$work/cases_merged.$f" "$work/cases.$f"
    # a shard cut short, resumed as the same shard
    truncate -s -300 "$work/table_2.$f"
    run "${table[@]}" --format "$f" --shard 2/3 --resume "$work/table_2.$f"
    run merge --output "$work/table_merged2.$f" "$work/table_1.$f" "$work/table_2.$f" "$work/table_3.$f"
    check "table --format $f: a resumed shard merges into the serial run" cmp -s "$work/table_merged2.$f" "$work/table.$f"
    # failed rows: rows 0, 1 and 3 of shards 1, 2 and 3 fail (the sweep's rows shard_rows
    # names); the merged file is the serial run's with those rows failing
    PENDAVG_TEST_FAILING_ROWS=$(shard_rows 68 3 1:0 2:1 3:3) "$faulty" "${table[@]}" --format "$f" \
      --output "$work/failed.$f" 2>/dev/null
    for k in 1 2 3; do
      PENDAVG_TEST_FAILING_ROWS=$((k == 3 ? 3 : k - 1)) \
        "$faulty" "${table[@]}" --format "$f" --shard $k/3 --output "$work/failed_$k.$f" 2>/dev/null
    done
    run merge --output "$work/failed_merged.$f" "$work/failed_1.$f" "$work/failed_2.$f" "$work/failed_3.$f"
    check "table --format $f: shards with failed rows merge into the serial run, exit 3" \
      test "$rc" -eq 3 -a "$(cmp "$work/failed_merged.$f" "$work/failed.$f" 2>&1)" = ""
  done
  check "three failed rows" test "$(grep -c '^# failed: point' "$work/failed.csv")" -eq 3
  bad "merge of a csv shard and a json shard" merge --output "$work/mixed" "$work/table_1.csv" \
    "$work/table_2.json" "$work/table_3.csv"
  check "... the line names both formats" grep -qF "is a json shard, '$work/table_1.csv' a csv shard" "$work/err"
  check "... nothing written" test ! -e "$work/mixed"
  bad "merge of a text shard and a csv shard" merge --output "$work/mixed" "$work/table_1.text" "$work/table_2.csv" "$work/table_3.text"
  # an interrupted JSON shard: refused
  "$python" - "$work/table_3.json" "$work/stopped_3.json" <<'PY'
import sys
text = open(sys.argv[1]).read().replace('"interrupted": null}', '"interrupted": "5 of 30 points computed; the rows of the others are left out"}')
open(sys.argv[2], "w").write(text)
PY
  bad "merge of an interrupted json shard" merge --output "$work/m.json" "$work/table_1.json" "$work/table_2.json" "$work/stopped_3.json"
  check "... named as incomplete" grep -q "stopped_3.json' is incomplete (interrupted: " "$work/err"
}

case:columns() {
  local f
  cases=(average --cases "$work/n2.csv" --columns beta_K,error_K,ratio,cos_phi,method,evaluations,converged)
  for f in "${formats[@]}"; do
    run "${cases[@]}" --format "$f" --output "$work/cols.$f"
    check "--columns --format $f: exit 0" test "$rc" -eq 0
    run "${cases[@]}" --format "$f" --digits 20 --output "$work/cols20.$f"
    run average --cases "$work/energy.csv" --columns K,K_total,density_of_states_error --format "$f" --output "$work/micro.$f"
  done
  check "--columns: json and text hold the chosen columns' values" \
    same_values "$work/cols.csv" "$work/cols.json" "$work/cols.text" 16
  check "--columns, 20 digits: json and text hold the chosen columns' values" \
    same_values "$work/cols20.csv" "$work/cols20.json" "$work/cols20.text" 20
  check "--columns, microcanonical: json and text hold the chosen columns' values" \
    same_values "$work/micro.csv" "$work/micro.json" "$work/micro.text" 16
  check "--columns: the JSON rows have the input columns and the chosen ones (old names as given)" \
    "$python" -c 'import json, sys; d = json.load(open(sys.argv[1])); assert list(d["rows"][0]) == ["beta", "g", "m1", "m2", "l1", "l2", "beta_K1", "beta_K2", "error_K1", "error_K2", "ratio", "cos_phi1", "cos_phi2", "method", "evaluations", "converged"], list(d["rows"][0])' "$work/cols.json"
  # --resume needs the same --columns in every format
  bad "--columns: --resume with other columns" average --cases "$work/n2.csv" --columns ratio --format json --resume "$work/cols.json"
}

case:timing() {
  local f
  for f in "${formats[@]}"; do
    run average --cases "$work/n3.csv" --format "$f"
    cp "$work/out" "$work/plain.$f"
    run average --cases "$work/n3.csv" --format "$f" --timing --timing-rows "$work/rows.$f"
    check "--timing --format $f: stdout as without it" cmp -s "$work/out" "$work/plain.$f"
    check "--timing --format $f: the timing line" grep -q '^pendavg: timing: rows=12 median_us=' "$work/err"
    check "--timing-rows --format $f: a line per row" test "$(wc -l <"$work/rows.$f")" -eq 13
  done
}

case:mpi() {
  [ -n "$mpiexec" ] || { fail "mpi: no MPIEXEC given"; return; }
  local launcher=("$mpiexec") f ranks
  if "$mpiexec" --version 2>&1 | grep -q "Open MPI\|OpenRTE"; then
    export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
    export OMPI_MCA_btl_vader_single_copy_mechanism=none
    launcher+=(--oversubscribe --bind-to none --mca btl self,vader --mca plm isolated)
  fi
  for f in json text; do  # a table of double and MPFR rows, and cases files
    for sweep in "table --beta log:0.1:10:30 --mu1 0.1,0.5 --digits 16,20" \
                 "average --cases $work/$([ $f = json ] && echo n2.csv --digits 20 || echo n3.csv)"; do
      # shellcheck disable=SC2086
      OMP_NUM_THREADS=2 "$pendavg" $sweep --format "$f" >"$work/serial" 2>/dev/null
      for ranks in 1 2 3; do  # threads 2, 1, 2
        # shellcheck disable=SC2086
        OMP_NUM_THREADS=$((ranks % 2 + 1)) "${launcher[@]}" -n "$ranks" "$pendavg" $sweep --format "$f" >"$work/ranks" 2>"$work/err"
        check "${sweep%% *} --format $f on $ranks ranks = the serial run" cmp -s "$work/ranks" "$work/serial"
      done
    done
  done
}

cases_main "$@"
