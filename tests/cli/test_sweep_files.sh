#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# tests/cli/test_sweep_files.sh -- sweeps and their files never lose work (issues 26 and 28): a
# row that fails while the sweep runs becomes a '# failed:' line and the others are kept (exit 3),
# --resume keeps only whole rows and takes those of a run killed outright (SIGKILL) from its
# temporary, a full disk or a file size limit leaves one line and no
# temporary, long names, modes, hard links, FIFOs, the --timing-rows file, bounded cases reads,
# progress while a long sweep is checked, error lines safe for a terminal, cases files as
# pandas writes them, and files of another output schema (refused by --resume).
#
# Usage: test_sweep_files.sh PATH/TO/pendavg CASE PATH/TO/pendavg_row_faults
#        (test_sweep_files.sh --list: the cases)
# pendavg_row_faults is the test build of the same command whose rows listed in
# PENDAVG_TEST_FAILING_ROWS (indices from 0) throw when they are computed: a row that fails
# late, after the check before the sweep passed it.
# Prints "CASE: N passed, M failed" last and exits non-zero on any failure.
set -u

usage="usage: test_sweep_files.sh PATH/TO/pendavg CASE PATH/TO/pendavg_row_faults, or test_sweep_files.sh --list"
pendavg=${1:?$usage}
faulty=${3:-}
[ "$pendavg" = --list ] || [ -n "$faulty" ] || { echo "$usage" >&2; exit 2; }
progress_lines_allowed=1
# shellcheck source=sweep_harness.sh
source "$(cd "$(dirname "$0")" && pwd)/sweep_harness.sh"
source "$(cd "$(dirname "$0")" && pwd)/sweep_harness.sh"
# faulty_run ROWS ARGS...: the test build with rows ROWS failing late
faulty_run() {
  local rows=$1
  shift
  PENDAVG_TEST_FAILING_ROWS=$rows "$faulty" "$@" >"$work/out" 2>"$work/err"
  rc=$?
}
# data_rows FILE: the lines that are neither '#' lines nor the column line
data_rows() { grep -v '^#' "$1" | tail -n +2; }
table=(table --beta log:0.1:10:20 --mu1 0.1,0.5 --digits 16)
# the uninterrupted runs: $work/cases_reference.csv (of $work/cases.csv) and table_reference.csv
cases_reference() { "$pendavg" "${cases[@]}" --output "$work/cases_reference.csv" 2>/dev/null; }
table_reference() { "$pendavg" "${table[@]}" --output "$work/table_reference.csv" 2>/dev/null; }
# dead_writer: $dead_pid, the pid of a process that has ended, and $host, as temporaries name it
dead_writer() {
  true &
  dead_pid=$!
  wait "$dead_pid"
  host=$(hostname | tr -cd 'A-Za-z0-9-' | cut -c1-64)
}

# cases.csv: 120 good N = 3 rows
cases_setup() {
"$python" - "$work/cases.csv" <<'PY'
import sys
with open(sys.argv[1], "w") as f:
    f.write("beta,g,m1,m2,m3,l1,l2,l3\n")
    for i in range(120):
        f.write(f"{1 + i % 7},1,1,{1 + i % 3},1,1,1,{1 + i % 5}\n")
PY
cases=(average --cases "$work/cases.csv")
}
# ---------------------------------------------------------------- 1. no sweep row lost
# Rows 5 and 119 of cases.csv (file lines 7 and 121) fail while they are computed.
case:rows_lost.cases() {
cases_reference
"$pendavg" "${cases[@]}" >"$work/cases_reference_stdout.csv" 2>/dev/null
faulty_run 5,119 "${cases[@]}" --output "$work/cases_failed.csv"
check "failed rows: exit status 3 (was 2 and no file)" test "$rc" -eq 3
check "failed rows: one error line" one_error_line
check "failed rows: the line names the count and the first row's line and reason" \
  grep -q "average: 2 of 120 rows failed .* the first: $work/cases.csv line 7: a failure injected" "$work/err"
check "failed rows: the line says --resume computes them" grep -q -- "--resume '$work/cases_failed.csv'" "$work/err"
check "failed rows: nothing on stdout" test ! -s "$work/out"
check "failed rows: every other row kept, in place" \
  cmp -s <(grep -v '^# failed: ' "$work/cases_failed.csv" | grep -v '^[^#]*$' ) \
         <(grep '^#' "$work/cases_reference.csv")
check "failed rows: the 118 finished rows equal the full run's" \
  cmp -s <(data_rows "$work/cases_failed.csv") \
         <(data_rows "$work/cases_reference.csv" | sed -e '6d' -e '120d')
head_lines=$(($(grep -c '^#' "$work/cases_reference.csv") + 1))  # the '#' lines and the column line
check "failed rows: a '# failed:' line in each failed row's place, naming its line" \
  test "$(grep -n '^# failed: ' "$work/cases_failed.csv" | cut -d: -f1,3 | tr '\n' ' ')" = \
       "$((head_lines + 6)): $work/cases.csv line 7 $((head_lines + 120)): $work/cases.csv line 121 "
check "failed rows: no temporary" no_temporaries
run "${cases[@]}" --resume "$work/cases_failed.csv"
check "failed rows resumed: exit 0" test "$rc" -eq 0
check "failed rows resumed = a full run" cmp -s "$work/cases_failed.csv" "$work/cases_reference.csv"
# To stdout: the same rows and lines, exit 3.
first_row=$(($(grep -c '^#' "$work/cases_reference_stdout.csv") + 2))  # after the '#' and column lines
faulty_run 0 "${cases[@]}"
check "failed first row to stdout: exit 3" test "$rc" -eq 3
check "failed first row to stdout: the other rows" \
  cmp -s <(grep -v '^# failed: ' "$work/out") <(sed "${first_row}d" "$work/cases_reference_stdout.csv")
check "failed first row to stdout: its line in place" \
  test "$(sed -n "${first_row}p" "$work/out" | cut -c1-10)" = "# failed: "
# Every row failing: still a complete file of '# failed:' lines, exit 3.
faulty_run "$(seq -s, 0 119)" "${cases[@]}" --output "$work/cases_all_failed.csv"
check "every row failed: exit 3, 120 '# failed:' lines" \
  test "$rc" -eq 3 -a "$(grep -c '^# failed: ' "$work/cases_all_failed.csv")" -eq 120
}
# table likewise: a '# failed: point (...)' line, resumed = a full run.
case:rows_lost.table() {
table_reference
faulty_run 3,39 "${table[@]}" --output "$work/table_failed.csv"
check "table failed points: exit 3, one error line" test "$rc" -eq 3
check "table failed points: one error line" one_error_line
check "table failed points: the line" grep -q "table: 2 of 40 points failed .* the first: point (" "$work/err"
check "table failed points: two '# failed: point' lines" \
  test "$(grep -c '^# failed: point (' "$work/table_failed.csv")" -eq 2
check "table failed points: the finished rows equal the full run's" \
  cmp -s <(data_rows "$work/table_failed.csv") <(data_rows "$work/table_reference.csv" | sed -e '4d' -e '40d')
run "${table[@]}" --resume "$work/table_failed.csv"
check "table failed points resumed = a full run" cmp -s "$work/table_failed.csv" "$work/table_reference.csv"
}
case:rows_lost.sigterm() {
# A failed row and an interruption (SIGTERM once the progress line shows rows being computed, at
# 2 s; the last row sleeps 60 s first, so that the run is still going however fast the others
# are -- 400 rows at 1000 digits took 1.9-2.7 s -- and is abandoned after the grace): the file
# has both lines and --resume completes it.
"$python" - "$work/cases_slow.csv" <<'PY'
import sys
with open(sys.argv[1], "w") as f:
    f.write("beta,g,m1,m2,l1,l2\n")
    for i in range(400):
        f.write(f"{1 + i % 7},1,1,{1 + i % 3},1,{1 + i % 5}\n")
PY
slow=(average --cases "$work/cases_slow.csv" --digits 1000)
PENDAVG_TEST_FAILING_ROWS=1 PENDAVG_TEST_SLOW_ROW=399:60 "$faulty" "${slow[@]}" \
  --output "$work/slow_failed.csv" \
  >"$work/out" 2>"$work/err" &
pid=$!
for ((k = 0; k < 300; ++k)); do
  grep -q '^\[average\] [0-9]*/400 rows' "$work/err" && break
  sleep 0.1
done
kill -TERM "$pid" 2>/dev/null
wait "$pid"
rc=$?
check "failed row then SIGTERM: exit 3, the failed line and the interrupted line" \
  test "$rc" -eq 3 -a "$(grep -c '^# failed: ' "$work/slow_failed.csv")" -eq 1 \
       -a "$(grep -c '^# interrupted: ' "$work/slow_failed.csv")" -eq 1
"$pendavg" "${slow[@]}" --output "$work/slow_reference.csv" 2>/dev/null
run "${slow[@]}" --resume "$work/slow_failed.csv"
check "failed row and interruption resumed = a full run" \
  cmp -s "$work/slow_failed.csv" "$work/slow_reference.csv"
}

# ---------------------------------------------------------------- 2. --resume keeps whole rows only
case:resume.damaged_rows() {
cases_reference
cp "$work/cases_reference.csv" "$work/damaged.csv"
# Row 50 cut to 9 of its fields, row 80 with a field that is no number, the last row cut
# mid-number and without its newline (a file cut short).
"$python" - "$work/damaged.csv" <<'PY'
import sys
lines = open(sys.argv[1]).read().split("\n")
header = sum(1 for l in lines if l.startswith("#")) + 1
lines[header + 49] = ",".join(lines[header + 49].split(",")[:9])
fields = lines[header + 79].split(",")
fields[12] = fields[12][:3] + "e"
lines[header + 79] = ",".join(fields)
text = "\n".join(lines).rstrip("\n")
open(sys.argv[1], "w").write(text[:-5])
PY
check "damaged rows: row 50 has 9 fields" \
  test "$(data_rows "$work/damaged.csv" | sed -n 50p | tr ',' '\n' | wc -l)" -eq 9
PENDAVG_SWEEP_REPORT=1 faulty_run "" "${cases[@]}" --resume "$work/damaged.csv"  # the report
check "damaged rows resumed: exit 0" test "$rc" -eq 0
check "damaged rows resumed: the 3 damaged rows computed, the others kept" \
  grep -q '^pendavg: test: sweep of 120 rows, 3 computed,' "$work/err"
check "damaged rows resumed = a full run" cmp -s "$work/damaged.csv" "$work/cases_reference.csv"
table_reference
cp "$work/table_reference.csv" "$work/table_whole.csv"
PENDAVG_SWEEP_REPORT=1 faulty_run "" "${table[@]}" --resume "$work/table_whole.csv"
check "a whole file resumed: every row kept" grep -q '^pendavg: test: sweep of 40 rows, 0 computed,' "$work/err"
}

# ---------------------------------------------------------------- 3. a file size limit
case:limits.file_size() {
big_table=(table --beta log:0.1:10:2000 --mu1 0.1,0.5 --digits 16)
(
  ulimit -f 8  # 8 blocks of 512 bytes: the table is ~1 MB
  exec "$pendavg" "${big_table[@]}" --output "$work/limited.csv" >"$work/out" 2>"$work/err"
)
rc=$?
check "ulimit -f: exit 2 (not killed by SIGXFSZ)" test "$rc" -eq 2
check "ulimit -f: one error line naming the limit" \
  sh -c "[ \$(wc -l <'$work/err') -eq 1 ] && grep -q 'File too large' '$work/err'"
check "ulimit -f: no file" test ! -e "$work/limited.csv"
check "ulimit -f: no temporary" no_temporaries
}

# ---------------------------------------------------------------- 4. long output names
case:output.long_name() {
table_reference
long_name=$(printf 'x%.0s' $(seq 1 251)).csv  # 255 characters, NAME_MAX
run "${table[@]}" --output "$work/$long_name"
check "a 255-character output name is written" cmp -s "$work/$long_name" "$work/table_reference.csv"
run "${table[@]}" --resume "$work/$long_name"
check "a 255-character output name is resumed" test "$rc" -eq 0
check "long name: no temporary" no_temporaries
rm -f "$work/$long_name"
}

# ---------------------------------------------------------------- 5. modes and hard links
case:output.modes_and_links() {
echo old >"$work/private.csv"
chmod 600 "$work/private.csv"
run "${table[@]}" --output "$work/private.csv"
check "a rewritten 0600 file stays 0600" test "$(stat -c %a "$work/private.csv")" = 600
chmod 640 "$work/private.csv"
run "${table[@]}" --resume "$work/private.csv"
check "a resumed 0640 file stays 0640" test "$(stat -c %a "$work/private.csv")" = 640
if [ "$(id -u)" -eq 0 ]; then  # only root may give a file to another owner
  chown 12345:12346 "$work/private.csv"
  run "${table[@]}" --output "$work/private.csv"
  check "a rewritten file keeps its owner and group" test "$(stat -c %u:%g "$work/private.csv")" = 12345:12346
fi
echo old >"$work/linked.csv"
ln "$work/linked.csv" "$work/link2.csv"
bad "an output with two hard links is refused" "${table[@]}" --output "$work/linked.csv"
check "hard links: the line says why" grep -q "2 hard links" "$work/err"
check "hard links: both names keep their content" \
  sh -c "[ \"\$(cat '$work/linked.csv')\" = old ] && [ \"\$(cat '$work/link2.csv')\" = old ]"
}

# ---------------------------------------------------------------- 6. --timing-rows on a full disk
case:timing_rows.full_disk() {
bad "--timing-rows /dev/full fails before any row reaches stdout" \
  "${cases[@]}" --timing-rows /dev/full
run "${cases[@]}" --timing-rows "$work/timing.csv"
check "--timing-rows: a row,line,us line per row" \
  test "$(head -1 "$work/timing.csv")" = "row,line,us" -a "$(wc -l <"$work/timing.csv")" -eq 121
check "--timing-rows: rows in order, lines from the file" \
  test "$(sed -n '2p;121p' "$work/timing.csv" | cut -d, -f1,2 | tr '\n' ' ')" = "0,2 119,121 "
faulty_run 7 "${cases[@]}" --timing-rows "$work/timing_failed.csv"
check "--timing-rows with a failed row: the row is left out" \
  test "$rc" -eq 3 -a "$(wc -l <"$work/timing_failed.csv")" -eq 120 -a \
       -z "$(cut -d, -f1 "$work/timing_failed.csv" | grep -x 7)"
}

# ---------------------------------------------------------------- 7. endless input, FIFOs
case:input.endless() {
bad "--cases /dev/zero is refused at once (a NUL byte)" average --cases /dev/zero
check "/dev/zero: the line says why" grep -q "line 1 holds a NUL byte: not a text file" "$work/err"
bad "--cases /dev/urandom is refused at once" average --cases /dev/urandom
"$python" -c 'import sys; sys.stdout.write("beta,g,m1,l1\n" + "1" * (65 << 20))' >"$work/long_line.csv"
bad "a cases line longer than 64 MB is refused" average --cases "$work/long_line.csv"
check "long line: the line says why" grep -q "line 2 is longer than 64 MB" "$work/err"
rm -f "$work/long_line.csv"
bad "an endless line from a pipe is refused" average --cases <(yes 1,1,1,1 | tr -d '\n')
check "endless line: the line says why" grep -q "line 1 is longer than 64 MB" "$work/err"
}
case:output.fifo() {
table_reference
mkfifo "$work/fifo"
bad "--output to a FIFO nobody reads is refused" "${table[@]}" --output "$work/fifo"
check "FIFO: the line says why" grep -q "FIFO that no process reads" "$work/err"
cat "$work/fifo" >"$work/from_fifo.csv" &
reader=$!
for ((k = 0; k < 50; ++k)); do  # until the reader has the FIFO open
  [ -n "$(find /proc/$reader/fd -lname "$work/fifo" 2>/dev/null | head -1)" ] && break
  sleep 0.1
done
run "${table[@]}" --output "$work/fifo"
wait "$reader"
check "--output to a FIFO with a reader writes through it" \
  cmp -s "$work/from_fifo.csv" "$work/table_reference.csv"
}

# ---------------------------------------------------------------- 8. progress while checking
case:checking.progress() {
# 1e8 points take minutes to check: a progress line comes within seconds; SIGINT then ends the
# run (no row was computed).
"$pendavg" table --beta lin:0.1:10:10000 --mu1 lin:0.01:0.99:10000 --output "$work/huge.csv" \
  >"$work/out" 2>"$work/err" &
pid=$!
for ((k = 0; k < 300; ++k)); do
  grep -q '^\[table\] checking the points: ' "$work/err" && break
  sleep 0.2
done
kill -INT "$pid" 2>/dev/null
wait "$pid"
check "a long check prints progress" grep -q '^\[table\] checking the points: [0-9]*/100000000' "$work/err"
}

# ---------------------------------------------------------------- 9. error lines safe for a terminal
case:errors.terminal_safe() {
one=(average --masses 1,1 --lengths 1,1)
bad "ESC and CR in an argument" "${one[@]}" --beta $'1\e[31m\r2'
check "ESC and CR are escaped" grep -qF -- "--beta: malformed number '1\x1b[31m\x0d2'" "$work/err"
check "no raw control character on stderr" sh -c "! LC_ALL=C grep -q '[[:cntrl:]]' '$work/err'"
bad "U+2028, VT, DEL and a C1 control in an argument" "${one[@]}" --beta $'1\u2028\v\x7f\u0085'
check "U+2028, VT, DEL, C1 escaped" grep -qF '1\u2028\x0b\x7f\u0085' "$work/err"
bad "bytes that are not UTF-8" "${one[@]}" --beta $'1\xff\xc3'
check "invalid UTF-8 escaped" grep -qF '1\xff\xc3' "$work/err"
"$python" - "$work/long_field.csv" <<'PY'
import sys
with open(sys.argv[1], "w") as f:
    f.write("beta,g,m1,l1\n" + "1" + "x" * 1000000 + ",1,1,1\n")
PY
bad "a 1 MB field of a cases file" average --cases "$work/long_field.csv"
check "a 1 MB field makes a short error line" test "$(wc -c <"$work/err")" -lt 3000
check "a 1 MB field is cut after 40 characters, its length said" \
  grep -qF "'1xxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxx... (1000003 characters)" "$work/err"
printf 'beta,g,m1,l1\n1,1,1\x1b]0;owned\x07,1\n' >"$work/control_field.csv"
bad "control characters in a cases field" average --cases "$work/control_field.csv"
check "cases field's control characters escaped" grep -qF '\x1b]0;owned\x07' "$work/err"
}

# ---------------------------------------------------------------- 10. cases files as pandas writes them
case:cases_files.pandas() {
printf 'beta,g,m1,m2,l1,l2\n1,1,1,1,1,1\n2.5,9.81,0.3,1,2,0.5\n' >"$work/plain.csv"
run average --cases "$work/plain.csv"
cp "$work/out" "$work/plain_out.csv"
# df.to_csv("f.csv"): the index first, under an empty name
printf ',beta,g,m1,m2,l1,l2\n0,1,1,1,1,1,1\n1,2.5,9.81,0.3,1,2,0.5\n' >"$work/pandas_index.csv"
run average --cases "$work/pandas_index.csv"
check "pandas' index column is left out" cmp -s "$work/out" "$work/plain_out.csv"
# df.to_csv("f.csv", encoding="utf-8-sig", quoting=csv.QUOTE_NONNUMERIC): a byte order mark,
# quoted names
printf '\xef\xbb\xbf"","beta","g","m1","m2","l1","l2"\n0,1,1,1,1,1,1\n1,2.5,9.81,0.3,1,2,0.5\n' \
  >"$work/pandas_bom.csv"
run average --cases "$work/pandas_bom.csv"
check "a byte order mark, quoted names and the index" cmp -s "$work/out" "$work/plain_out.csv"
printf '\xef\xbb\xbfbeta,g,m1,m2,l1,l2\n1,1,1,1,1,1\n2.5,9.81,0.3,1,2,0.5\n' >"$work/bom.csv"
run average --cases "$work/bom.csv"
check "a byte order mark alone" cmp -s "$work/out" "$work/plain_out.csv"
printf ',beta,g,m1,l1\nfirst,1,1,1,1\n' >"$work/not_index.csv"
bad "an unnamed first column that is not a row number" average --cases "$work/not_index.csv"
check "not an index: the line names the row" grep -q "line 2: the first column" "$work/err"
if "$python" -c 'import pandas' 2>/dev/null; then
  "$python" - "$work/pandas_real.csv" <<'PY'
import sys, pandas
pandas.DataFrame({"beta": [1, 2.5], "g": [1, 9.81], "m1": [1, 0.3], "m2": [1, 1],
                  "l1": [1, 2], "l2": [1, 0.5]}).to_csv(sys.argv[1])
PY
  run average --cases "$work/pandas_real.csv"
  check "a file pandas wrote" test "$rc" -eq 0 -a "$(grep -v '^#' "$work/out" | grep -c .)" -eq 3
fi
}

# ---------------------------------------------------------------- killed outright
case:resume.killed() {
# SIGKILL (the OOM killer, kill -9: no handler runs) at a random moment once rows are written,
# then --resume: the killed run's rows are taken from its temporary (the reference on one thread,
# the killed and resumed runs on two: the same bytes).
killed=(table --beta log:1:1000:30 --mu1 0.001,0.05 --digits 1000)
OMP_NUM_THREADS=1 "$pendavg" "${killed[@]}" --output "$work/killed_reference.csv" 2>/dev/null
OMP_NUM_THREADS=2 killed_and_resumed "table" "$work/killed_reference.csv" "$work/killed.csv" \
  "$faulty" "${killed[@]}"
}
# The rows finished ahead of an unfinished one (rank 0's reorder buffer) survive a SIGKILL, in
# every format.
case:resume.killed_ahead_csv() { killed_ahead "rows ahead kept (csv)" csv "$faulty"; }
case:resume.killed_ahead_json() { killed_ahead "rows ahead kept (json)" json "$faulty"; }
case:resume.killed_ahead_text() { killed_ahead "rows ahead kept (text)" text "$faulty"; }
case:resume.dead_writer() {
# Temporaries of a writer that has ended (made here, named with the pid of a process that
# exited): one cut within its header has no rows (the sweep is written, the temporary removed
# once it is); one of another sweep is refused in one line that names it, and nothing is written.
dead_writer
quick=(table --beta log:0.1:10:20 --mu1 0.1,0.5)
"$pendavg" "${quick[@]}" --output "$work/quick_reference.csv" 2>/dev/null
head -c 30 "$work/quick_reference.csv" >"$work/quick.csv.tmp.$host.$dead_pid.aaaaaa"
run "${quick[@]}" --resume "$work/quick.csv"
check "a dead writer's temporary cut within its header: the sweep is written" \
  cmp -s "$work/quick.csv" "$work/quick_reference.csv"
check "... and that temporary removed" test ! -e "$work/quick.csv.tmp.$host.$dead_pid.aaaaaa"
"$pendavg" table --beta log:0.1:10:20 --mu1 0.1,0.6 --output "$work/quick_other.csv" 2>/dev/null
cp "$work/quick_other.csv" "$work/quick2.csv.tmp.$host.$dead_pid.bbbbbb"
bad "a dead writer's temporary of another sweep" "${quick[@]}" --resume "$work/quick2.csv"
check "... named in the refusal" grep -q "quick2.csv.tmp.$host.$dead_pid.bbbbbb', left by a killed run" "$work/err"
check "... and nothing written" test ! -e "$work/quick2.csv"
rm -f "$work/quick2.csv.tmp."*
}

# ---------------------------------------------------------------- 11. files of another output schema
case:schema.other_schemas() {
# Files pendavg 0.2.0 wrote with output schema 0 (tests/cli/schema0/: interrupted files of a
# table and of average --cases, and the two shards of a table; other column names and number
# formats, no '# schema:' line) are never completed with schema 1 rows: --resume refuses them in
# one line that names the schemata, and leaves them as they were; so does a file of a later
# schema, and a killed old run's temporary. merge joins shards of one schema only.
schema0="$(cd "$(dirname "$0")" && pwd)/schema0"
dead_writer
mkdir "$work/old" "$work/schema0" && cp "$schema0"/*.csv "$work/old/" && cp "$schema0"/*.csv "$work/schema0/"
schema0_reason="was written with output schema 0 (pendavg 0.2.0: it has no '# schema:' line); this pendavg writes schema 1 -- "
old_table=(table --beta log:0.1:10:3 --mu1 0.5 --l1 1,2 --g 1,9.81)
bad "table --resume of a schema 0 file" "${old_table[@]}" --resume "$work/old/table.csv"
check "table --resume of a schema 0 file: the line names the schemata" \
  grep -qF "table: --resume '$work/old/table.csv' $schema0_reason" "$work/err"
check "table --resume of a schema 0 file: the file is left as it was" cmp -s "$work/old/table.csv" "$work/schema0/table.csv"
bad "average --cases --resume of a schema 0 file" average --cases "$work/old/cases_n2.csv" --resume "$work/old/cases.csv"
check "average --cases --resume of a schema 0 file: the line names the schemata" \
  grep -qF "average: --resume '$work/old/cases.csv' $schema0_reason" "$work/err"
check "average --cases --resume of a schema 0 file: the file is left as it was" \
  cmp -s "$work/old/cases.csv" "$work/schema0/cases.csv"
old_shards=(table --beta 0.5,1,2 --mu1 0.25,0.5)
bad "table --shard --resume of a schema 0 shard" "${old_shards[@]}" --shard 2/2 --resume "$work/old/table_shard2.csv"
check "table --shard --resume of a schema 0 shard: the line names the schemata" \
  grep -qF "table: --resume '$work/old/table_shard2.csv' $schema0_reason" "$work/err"
check "table --shard --resume of a schema 0 shard: the file is left as it was" \
  cmp -s "$work/old/table_shard2.csv" "$work/schema0/table_shard2.csv"
# A later schema: the same sweep's file with another '# schema:' line.
"$pendavg" "${old_table[@]}" --output "$work/old/later.csv" 2>/dev/null
sed -i 's/^# schema: 1$/# schema: 2/' "$work/old/later.csv"
cp "$work/old/later.csv" "$work/old/later_copy.csv"
bad "table --resume of a schema 2 file" "${old_table[@]}" --resume "$work/old/later.csv"
check "table --resume of a schema 2 file: the line names the schemata" \
  grep -qF "table: --resume '$work/old/later.csv' was written with output schema 2 (pendavg " "$work/err"
check "table --resume of a schema 2 file: ... this pendavg writes schema 1" grep -qF "; this pendavg writes schema 1 -- " "$work/err"
check "table --resume of a schema 2 file: the file is left as it was" cmp -s "$work/old/later.csv" "$work/old/later_copy.csv"
# A schema 0 run killed outright: its temporary is refused, named, and nothing is written.
cp "$work/schema0/table.csv" "$work/old/old_run.csv.tmp.$host.$dead_pid.cccccc"
bad "--resume with a killed schema 0 run's temporary" "${old_table[@]}" --resume "$work/old/old_run.csv"
check "... the line names the temporary and the schemata" grep -qF \
  "old_run.csv.tmp.$host.$dead_pid.cccccc', left by a killed run, was written with output schema 0 (pendavg 0.2.0" "$work/err"
check "... and nothing written" test ! -e "$work/old/old_run.csv"
rm -f "$work/old/old_run.csv.tmp."*
# merge: a schema 0 shard with a schema 1 shard of the same sweep is refused; schema 0 shards
# alone are joined as they are (a schema 0 file: its header without the shard line, the rows in
# the sweep's order), never labelled schema 1.
"$pendavg" "${old_shards[@]}" --shard 2/2 --output "$work/old/new_shard2.csv" 2>/dev/null
bad "merge of a schema 0 shard and a schema 1 shard" merge --output "$work/old/mixed.csv" \
  "$work/old/table_shard1.csv" "$work/old/new_shard2.csv"
check "merge of mixed schemata: nothing written" test ! -e "$work/old/mixed.csv"
run merge --output "$work/old/old_merged.csv" "$work/old/table_shard2.csv" "$work/old/table_shard1.csv"
check "merge of schema 0 shards: the schema 0 file of the sweep" "$python" - "$work/old/old_merged.csv" "$rc" \
  "$work/schema0/table_shard1.csv" "$work/schema0/table_shard2.csv" <<'PY'
import sys
assert sys.argv[2] == "0", sys.argv[2]
shards = [open(p).read().splitlines(keepends=True)[1:] for p in sys.argv[3:5]]
assert shards[0][:11] == shards[1][:11]  # the same header up to the column line
rows = [shards[0][11:], shards[1][11:]]
expected = shards[0][:11] + [rows[k % 2][k // 2] for k in range(6)]  # blocks of 1 row
merged = open(sys.argv[1]).read().splitlines(keepends=True)
assert not any(l.startswith("# schema:") for l in merged), "a schema line"
assert merged == expected, merged
PY
}


cases_main "$@"
