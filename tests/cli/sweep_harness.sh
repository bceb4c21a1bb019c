# SPDX-License-Identifier: GPL-3.0-or-later
# tests/cli/sweep_harness.sh -- the set-up and checks the sweep scripts (test_sweeps.sh,
# test_sweep_files.sh, test_shards.sh, test_mpi.sh, test_no_silent_copies.sh) share, sourced
# after they set $pendavg (and $faulty, the test build, if they take it): the named cases, the
# scratch directory $work and the checks of case_harness.sh, and the sweep checks below.
# progress_lines_allowed=1 lets "[command] ..." progress lines stand before a refusal's one error
# line (sweeps whose check shows progress).
# shellcheck source=case_harness.sh
source "$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)/case_harness.sh"
record_commands pendavg faulty
export SOURCE_DATE_EPOCH=1767225600  # the files' date line, so that whole files compare

# one_error_line: stderr is one line "pendavg: error: ..." (after progress lines if allowed)
one_error_line() {
  local others
  if [ "${progress_lines_allowed:-0}" = 1 ]; then
    others=$(grep -vc '^\[[a-z]*\] ' "$work/err")
  else
    others=$(wc -l <"$work/err")
  fi
  [ "$others" -eq 1 ] && tail -1 "$work/err" | grep -q '^pendavg: error: '
}
# bad NAME ARGS...: exit 2, one stderr line "pendavg: error: ...", empty stdout, within 20 s
# (nothing is computed before the input is refused).
bad() {
  local name=$1
  shift
  timeout 20 "$pendavg" "$@" >"$work/out" 2>"$work/err"
  rc=$?
  local expected="exit 2 within 20 s, nothing on stdout, one stderr line 'pendavg: error: ...'"
  if [ "$rc" -ne 2 ]; then
    fail "$name" "$expected" "exit $rc"
  elif [ -s "$work/out" ]; then
    fail "$name" "$expected" "output on stdout"
  elif ! one_error_line; then
    fail "$name" "$expected" "$(wc -l <"$work/err") stderr lines"
  else
    pass
  fi
}
no_temporaries() { [ -z "$(find "$work" -name '*.tmp.*' | head -1)" ]; }
# row_count FILE...: the row lines the sweep files hold, in any format (JSON: the lines of
# "rows", each '{' or ',{'; CSV and text: the lines after the column line that are not '#' lines);
# files that do not exist count none.
row_count() {
  local file n=0 lines
  for file in "$@"; do
    [ -e "$file" ] || continue
    if [ "$(head -c 1 "$file")" = "{" ]; then
      n=$((n + $(grep -c '^,\?{"' "$file")))
    else
      lines=$(grep -vc '^#' "$file")
      ((lines > 1)) && n=$((n + lines - 1))
    fi
  done
  echo "$n"
}
# resumed_whole NAME REFERENCE OUT MOST WHAT COMMAND...: COMMAND --resume OUT after WHAT (a
# kill) must exit 0, leave OUT equal to REFERENCE byte for byte and no temporary of OUT, and have
# computed at most MOST rows (the test build's PENDAVG_SWEEP_REPORT=1 says how many): the rest
# it took from the killed run's files.
resumed_whole() {
  local name=$1 reference=$2 out=$3 most=$4 what=$5 computed
  shift 5
  PENDAVG_SWEEP_REPORT=1 "$@" --resume "$out" >"$work/out" 2>"$work/err"
  rc=$?
  computed=$(sed -n 's/^pendavg: test: sweep of [0-9]* rows, \([0-9]*\) computed.*/\1/p' "$work/err")
  local expected="$what and resumed: exit 0, the uninterrupted file, no temporary, at most $most rows computed"
  if [ "$rc" -ne 0 ]; then
    fail "$name" "$expected" "the resumed run exited $rc"
  elif ! cmp -s "$out" "$reference"; then
    fail "$name" "$expected" "a file that differs from an uninterrupted run's"
  elif [ -n "$(find "$(dirname "$out")" -name "$(basename "$out").tmp.*" | head -1)" ]; then
    fail "$name" "$expected" "a temporary left"
  elif ! [ "${computed:-$((most + 1))}" -le "$most" ]; then
    fail "$name" "$expected" "${computed:-?} rows computed"
  else
    pass
  fi
}
# killed_and_resumed NAME REFERENCE OUT COMMAND...: runs COMMAND --output OUT in the background
# (COMMAND: the test build pendavg_row_faults with its arguments, alone or under mpiexec; any
# --format), kills it with SIGKILL once OUT's temporary holds a row and a random 0 to
# $kill_delay_max (default 1) s more (no handler runs: the rows it had written are all that is
# left; under mpiexec every process of the job is killed), then runs COMMAND --resume OUT. Its
# last row sleeps 60 s first (PENDAVG_TEST_SLOW_ROW), so that it cannot finish before the kill
# however fast the other rows are. OUT must be REFERENCE byte for byte, no temporary may be
# left, and the resumed run must have computed fewer rows than the sweep has: it took the killed
# run's rows from its temporary (the test build's PENDAVG_SWEEP_REPORT=1 says how many it
# computed).
killed_and_resumed() {
  local name=$1 reference=$2 out=$3 k rows delay
  shift 3
  rows=$(row_count "$reference")
  rm -f "$out"
  PENDAVG_TEST_SLOW_ROW=$((rows - 1)):60 "$@" --output "$out" >/dev/null 2>&1 &
  local pid=$!
  for ((k = 0; k < 600; ++k)); do
    [ "$(row_count "$out".tmp.*)" -ge 1 ] && break
    sleep 0.1
  done
  delay=$("$python" -c "import random; print(round(random.uniform(0, ${kill_delay_max:-1}), 2))")
  sleep "$delay"
  { kill -KILL "$pid" && wait "$pid"; } 2>/dev/null  # (no "Killed" job notice)
  # The whole job goes, as when its node is lost: the ranks of a SIGKILLed mpirun can live on as
  # orphans (once for over a minute, finishing the sweep), so they are killed too.
  pkill -KILL -f -- "--output $out" 2>/dev/null
  for ((k = 0; k < 100; ++k)); do pgrep -f -- "--output $out" >/dev/null || break; sleep 0.1; done
  if [ -e "$out" ] || [ -z "$(find "$(dirname "$out")" -name "$(basename "$out").tmp.*" | head -1)" ]; then
    fail "$name" "a temporary left by the run killed after $delay s" "the run had finished or left no temporary (too fast a sweep?)"
    return
  fi
  resumed_whole "$name" "$reference" "$out" $((rows - 1)) "killed (SIGKILL) after $delay s" "$@"
}
# killed_ahead NAME FORMAT LAUNCH...: a sweep killed outright keeps the rows it finished ahead of
# an unfinished one. LAUNCH starts the test build (alone, or under mpiexec); its row 0 sleeps
# (PENDAVG_TEST_SLOW_ROW=0:60), so every other finished row waits behind it and the file's own
# temporary holds only the header: rank 0 copies the waiting rows to a second temporary about
# every second. Once the copy holds rows the run is killed (SIGKILL); --resume must then compute
# only what the copy did not hold (row 0 among them) and write the uninterrupted run's file.
killed_ahead() {
  local name=$1 format=$2 k rows copy temporary
  shift 2
  local sweep=(table --beta log:0.01:100:120 --mu1 0.3 --digits 24 --format "$format")
  local out=$work/ahead.$format reference=$work/ahead_reference.$format
  local row='^,\?{"N"\|^[0-9 ]'  # a row's line in csv, json (after the first: a comma) and text
  OMP_NUM_THREADS=2 "$@" "${sweep[@]}" --output "$reference" 2>/dev/null ||
    { fail "$name" "the uninterrupted run exits 0" "it failed"; return; }
  rows=$(row_count "$reference")
  PENDAVG_TEST_SLOW_ROW=0:60 OMP_NUM_THREADS=2 "$@" "${sweep[@]}" --output "$out" >/dev/null 2>&1 &
  local pid=$!
  copy=
  for ((k = 0; k < 300; ++k)); do
    [ -n "$copy" ] && break
    for temporary in "$out".tmp.*; do
      [ "$(row_count "$temporary")" -ge 2 ] && copy=$temporary
    done
    sleep 0.1
  done
  { kill -KILL "$pid" && wait "$pid"; } 2>/dev/null  # (no "Killed" job notice)
  for ((k = 0; k < 100; ++k)); do pgrep -f -- "--output $out" >/dev/null || break; sleep 0.1; done
  if [ -z "$copy" ] || [ -e "$out" ]; then
    fail "$name" "a temporary with rows ahead of the slow row 0 within 30 s" "none (or the run finished)"
    return
  fi
  OMP_NUM_THREADS=2 resumed_whole "$name" "$reference" "$out" $((rows - 2)) \
    "killed (SIGKILL) with the rows ahead of row 0 finished" "$@" "${sweep[@]}"
}
