# SPDX-License-Identifier: GPL-3.0-or-later
# tests/cli/sweep_harness.sh -- the set-up and checks test_sweeps.sh, test_sweep_files.sh and
# test_shards.sh share, sourced after they set $pendavg: $python, a scratch directory $work removed
# on exit, and the checks. progress_lines_allowed=1 lets "[command] ..." progress lines stand
# before a refusal's one error line (sweeps whose check shows progress).
python=/usr/bin/python3
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
passed=0
failed=0
export SOURCE_DATE_EPOCH=1767225600  # the files' date line, so that whole files compare

pass() { passed=$((passed + 1)); }
fail() {
  failed=$((failed + 1))
  echo "FAIL: $1"
  [ -s "$work/out" ] && head -c 2000 "$work/out" | sed 's/^/  stdout: /' | head -5
  [ -s "$work/err" ] && head -c 2000 "$work/err" | sed 's/^/  stderr: /' | head -5
}
run() {
  "$pendavg" "$@" >"$work/out" 2>"$work/err"
  rc=$?
}
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
  if [ "$rc" -ne 2 ]; then
    fail "$name: exit code $rc, expected 2"
  elif [ -s "$work/out" ]; then
    fail "$name: stdout not empty"
  elif ! one_error_line; then
    fail "$name: stderr is not one 'pendavg: error: ' line"
  else
    pass
  fi
}
check() { # NAME COMMAND...: the command succeeds
  local name=$1
  shift
  if "$@"; then pass; else fail "$name"; fi
}
no_temporaries() { [ -z "$(find "$work" -name '*.tmp.*' | head -1)" ]; }
# killed_and_resumed NAME REFERENCE OUT COMMAND...: runs COMMAND --output OUT in the background
# (COMMAND: the test build pendavg_row_faults with its arguments, alone or under mpiexec), kills
# it with SIGKILL once OUT's temporary holds a row and a random 0-1 s more (no handler runs: the
# rows it had written are all that is left), then runs COMMAND --resume OUT. OUT must be REFERENCE
# byte for byte, no temporary may be left, and the resumed run must have computed fewer rows than
# the sweep has: it took the killed run's rows from its temporary (the test build's
# PENDAVG_SWEEP_REPORT=1 says how many it computed).
killed_and_resumed() {
  local name=$1 reference=$2 out=$3 k rows computed delay
  shift 3
  rows=$(($(grep -vc '^#' "$reference") - 1))  # without the column line
  rm -f "$out"
  "$@" --output "$out" >/dev/null 2>&1 &
  local pid=$!
  for ((k = 0; k < 600; ++k)); do  # a data row after the header's '#' lines and column line
    [ "$(cat "$out".tmp.* 2>/dev/null | grep -vc '^#')" -ge 2 ] && break
    sleep 0.1
  done
  delay=$(/usr/bin/python3 -c 'import random; print(round(random.uniform(0, 1), 2))')
  sleep "$delay"
  { kill -KILL "$pid" && wait "$pid"; } 2>/dev/null  # (no "Killed" job notice)
  # The processes of the killed run (an orphaned rank) are gone before it is resumed.
  for ((k = 0; k < 100; ++k)); do pgrep -f -- "--output $out" >/dev/null || break; sleep 0.1; done
  if [ -e "$out" ] || [ -z "$(find "$(dirname "$out")" -name "$(basename "$out").tmp.*" | head -1)" ]; then
    fail "$name: the run killed after $delay s finished or left no temporary (too fast a sweep?)"
    return
  fi
  PENDAVG_SWEEP_REPORT=1 "$@" --resume "$out" >"$work/out" 2>"$work/err"
  rc=$?
  computed=$(sed -n 's/^pendavg: test: sweep of [0-9]* rows, \([0-9]*\) computed.*/\1/p' "$work/err")
  if [ "$rc" -ne 0 ]; then
    fail "$name: killed (SIGKILL) after $delay s, the resumed run exited $rc"
  elif ! cmp -s "$out" "$reference"; then
    fail "$name: killed (SIGKILL) after $delay s and resumed: differs from an uninterrupted run"
  elif [ -n "$(find "$(dirname "$out")" -name "$(basename "$out").tmp.*" | head -1)" ]; then
    fail "$name: killed (SIGKILL) after $delay s and resumed: a temporary is left"
  elif ! [ "${computed:-$rows}" -lt "$rows" ]; then
    fail "$name: killed (SIGKILL) after $delay s: the resume computed ${computed:-?} of $rows rows (none taken from the temporary)"
  else
    pass
  fi
}
