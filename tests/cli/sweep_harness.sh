# SPDX-License-Identifier: GPL-3.0-or-later
# tests/cli/sweep_harness.sh -- the checks test_sweeps.sh and test_sweep_files.sh share, sourced
# after they set $pendavg and $work. progress_lines_allowed=1 lets "[command] ..." progress lines
# stand before a refusal's one error line (sweeps whose check shows progress).
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
