# SPDX-License-Identifier: GPL-3.0-or-later
# tests/cli/case_harness.sh -- named cases for the CLI test scripts, so that a failure names its
# case and ctest runs each case as its own test. A script sources this file first, defines its
# cases as functions named case:GROUP.WHAT (case:average.refusals, case:table.resume, ...) and
# ends with `cases_main "$@"`:
#
#   SCRIPT --list                   the case names, one a line, in the order of the script
#   SCRIPT PENDAVG CASE [EXTRA...]  runs that case alone, in a scratch directory $work of its own
#
# (tests/CMakeLists.txt registers one ctest test PREFIX.CASE per line of --list.) A function
# cases_setup, if the script has one, runs before the case (the files several cases read).
# Checks end in pass or fail, directly or through check and expect below and the scripts' own
# helpers. A failure prints the case, the check, the last pendavg command (record_commands:
# every run of the binaries, however started, leaves its arguments in $work/.last_command), what
# was expected and what was found, then the head of the last stdout and stderr. A case prints
# "CASE: N passed, M failed" last and exits non-zero on a failure, or when it made no check.
python=/usr/bin/python3
passed=0
failed=0
case_name=
if [ "${1:-}" != --list ]; then
  work=$(mktemp -d)
  trap 'rm -rf "$work"' EXIT
fi

pass() { passed=$((passed + 1)); }
# fail CHECK [EXPECTED [FOUND]]
fail() {
  failed=$((failed + 1))
  echo "FAIL [$case_name] $1"
  [ -s "$work/.last_command" ] && echo "  last command: $(head -c 2000 "$work/.last_command")"
  [ -n "${2:-}" ] && echo "  expected: $2"
  [ -n "${3:-}" ] && echo "  found:    $3"
  [ -s "$work/out" ] && head -c 2000 "$work/out" | sed 's/^/  stdout: /' | head -5
  [ -s "$work/err" ] && head -c 2000 "$work/err" | sed 's/^/  stderr: /' | head -5
  return 0
}
# quoted ARGS...: the arguments as a shell would read them back (for the messages)
quoted() { printf '%q ' "$@" | sed 's/ $//'; }
single_quoted() { local q="'\\''"; printf "'%s'" "${1//\'/$q}"; }
# record_commands VARIABLE...: each variable names a binary (pendavg, the test builds); it is
# replaced by a wrapper that writes its arguments to $work/.last_command and execs the binary
# (the same process: signals and pids are the binary's).
record_commands() {
  local variable binary
  [ -n "${work:-}" ] || return 0  # (--list)
  mkdir -p "$work/.bin"
  for variable in "$@"; do
    binary=${!variable:-}
    [ -n "$binary" ] || continue
    printf '#!/bin/sh\nprintf "%%s %%s\\n" %s "$*" >%s\nexec %s "$@"\n' \
      "$(single_quoted "$(basename "$binary")")" "$(single_quoted "$work/.last_command")" \
      "$(single_quoted "$binary")" >"$work/.bin/$variable"
    chmod +x "$work/.bin/$variable"
    printf -v "$variable" '%s' "$work/.bin/$variable"
  done
}
# run ARGS...: runs pendavg, leaves stdout/stderr in $work/out, $work/err and the code in $rc.
run() {
  "$pendavg" "$@" >"$work/out" 2>"$work/err"
  rc=$?
}
# check NAME COMMAND...: the command succeeds
check() {
  local name=$1 status
  shift
  "$@"
  status=$?
  if [ "$status" -eq 0 ]; then
    pass
  else
    fail "$name" "$(quoted "$@") succeeds" "exit status $status"
  fi
}
# expect NAME CONDITION: the shell condition (a string, eval'd) holds
expect() {
  if eval "$2"; then
    pass
  else
    fail "$1" "$2" "it does not hold"
  fi
}

# cases_list: the case functions' names without case:, in the order the script defines them
cases_list() {
  local name
  shopt -s extdebug
  for name in $(declare -F | sed -n 's/^declare -f case://p'); do
    declare -F "case:$name"
  done | sort -k2,2n | sed 's/^case://; s/ .*//'
  shopt -u extdebug
}
cases_main() {
  local names
  names=$(cases_list)
  if [ "${1:-}" = --list ]; then
    printf '%s\n' "$names"
    exit 0
  fi
  case_name=${2:-}
  if [ -z "${1:-}" ] || ! grep -qxF -- "$case_name" <<<"$names"; then
    echo "usage: $(basename "$0") PENDAVG CASE ... (or --list); no case '$case_name'" >&2
    exit 2
  fi
  if declare -F cases_setup >/dev/null; then cases_setup; fi
  "case:$case_name"
  echo "$case_name: $passed passed, $failed failed"
  [ "$failed" -eq 0 ] && [ "$passed" -gt 0 ]
}
