#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# tests/consumer/cli_docs.sh PENDAVG BUILD_DIR SOURCE_DIR VERSION -- what `pendavg --version`
# prints (every field, the git revision of the checkout), the man page pendavg.1 (renders with
# groff -man -ww without a warning, holds every command's usage text) and the bash completion
# (offers each command's options: exactly the --words of `pendavg COMMAND --help` that the
# command accepts, asked here of the command itself).
set -uo pipefail
pendavg=$1 build=$2 source=$3 version=$4
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
failures=0
fail() { echo "FAIL: $*" >&2; failures=$((failures + 1)); }

# ---------------------------------------------------------------- --version
"$pendavg" --version >"$work/version" 2>"$work/err" || fail "--version exits $?"
[ -s "$work/err" ] && fail "--version wrote to stderr: $(cat "$work/err")"
[ "$(head -n 1 "$work/version")" = "pendavg $version" ] ||
  fail "--version's first line is '$(head -n 1 "$work/version")', not 'pendavg $version'"
field() { sed -n "s/^$1: //p" "$work/version"; }
revision=$(field "git revision")
if git -C "$source" rev-parse --show-toplevel >/dev/null 2>&1 &&
   [ "$(realpath "$(git -C "$source" rev-parse --show-toplevel)")" = "$(realpath "$source")" ]; then
  head=$(git -C "$source" rev-parse --short=12 HEAD)
  # The build may predate the last commit or edit: the revision is HEAD's or an ancestor's.
  [[ $revision =~ ^[0-9a-f]{12}(-dirty)?$ ]] && git -C "$source" merge-base --is-ancestor \
    "${revision%-dirty}" "$head" 2>/dev/null || fail "git revision '$revision' is not of this checkout ($head)"
else
  [ "$revision" = unknown ] || fail "git revision '$revision' outside a git checkout"
fi
mpi=$(field MPI)
[[ $mpi == "no MPI" || $mpi =~ \(MPI\ standard\ [0-9]+\.[0-9]+\)$ ]] || fail "MPI: '$mpi'"
isa=$(field "dynamics instruction sets")
[[ $isa =~ ^built\ base(,\ x86-64-v3)?\;\ selected\ (base|x86-64-v3)$ ]] ||
  fail "dynamics instruction sets: '$isa'"
forced=$(PENDAVG_DYNAMICS_ISA=base "$pendavg" --version | sed -n 's/^dynamics instruction sets: //p')
[[ $forced == *"; selected base" ]] || fail "PENDAVG_DYNAMICS_ISA=base: '$forced'"
[[ $(field Boost) =~ ^1\.[0-9]+\.[0-9]+$ ]] || fail "Boost: '$(field Boost)'"
for library in MPFR GMP GSL; do
  [[ $(field $library) =~ ^[0-9][0-9.]*[0-9]\ \(compiled\ against\ [0-9][0-9.]*[0-9]\)$ ]] ||
    fail "$library: '$(field $library)'"
done
# The run-time versions are those of the libraries on this system.
[ "$(field MPFR | cut -d' ' -f1)" = "$(pkg-config --modversion mpfr)" ] || fail "MPFR run-time version"
[ "$(field GSL | cut -d' ' -f1)" = "$(pkg-config --modversion gsl)" ] || fail "GSL run-time version"
[ -n "$(field compiler)" ] || fail "no compiler line"

# ---------------------------------------------------------------- the commands and their options
commands=$("$pendavg" --help | sed -n 's/^  pendavg \([a-z]*\) .*/\1/p' | grep -vx help | sort -u)
[ "$(echo "$commands" | wc -l)" -ge 6 ] || fail "commands in --help: $commands"
accepted_options() {  # the --words of `pendavg $1 --help` that `pendavg $1` accepts
  local word
  for word in $("$pendavg" "$1" --help | grep -o -- '--[a-z][a-z0-9-]*' | sort -u); do
    "$pendavg" "$1" "$word=@" 2>&1 >/dev/null | grep -q "unknown option" || echo "$word"
  done
}

# ---------------------------------------------------------------- man page
man="$build/pendavg.1"
[ -s "$man" ] || fail "no $man"
groff -man -Tutf8 -ww "$man" >"$work/man.txt" 2>"$work/man.err" || fail "groff exits $?"
[ -s "$work/man.err" ] && fail "groff warns: $(head -5 "$work/man.err")"
MANWIDTH=120 man -l "$man" >/dev/null 2>"$work/man-l.err" || fail "man -l: $(cat "$work/man-l.err")"
grep -q "pendavg $version" "$work/man.txt" || fail "the man page does not name version $version"
for command in $commands; do
  # Every line of the command's usage text is in the page, as it prints it.
  "$pendavg" "$command" --help | sed 's/^ *//; /^$/d' >"$work/usage"
  while IFS= read -r line; do
    grep -qF -- "$line" "$work/man.txt" || { fail "man page: $command: '$line' missing"; break; }
  done <"$work/usage"
done

# ---------------------------------------------------------------- bash completion
completion="$build/pendavg.bash-completion"
[ -s "$completion" ] || fail "no $completion"
complete_words() {  # complete_words WORD... : what completing the last word offers, sorted
  bash -c 'source "$1"; shift; COMP_WORDS=("$@"); COMP_CWORD=$(($# - 1)); _pendavg
           printf "%s\n" "${COMPREPLY[@]}"' _ "$completion" "$@" | sort
}
[ "$(complete_words pendavg "")" = "$(printf '%s\n' $commands help --help --version | sort)" ] ||
  fail "completion of the command: $(complete_words pendavg "" | tr '\n' ' ')"
for command in $commands; do
  expected=$( (accepted_options "$command"; echo --help) | sort)
  offered=$(complete_words pendavg "$command" --)
  [ "$offered" = "$expected" ] ||
    fail "completion of '$command --': $(diff <(echo "$expected") <(echo "$offered") | grep '^[<>]' | tr '\n' ' ')"
done
[ "$(complete_words pendavg average --masses 1,1 --format "" | tr '\n' ' ')" = "csv json text " ] ||
  fail "completion of average --format: $(complete_words pendavg average --format "" | tr '\n' ' ')"
[ "$(complete_words pendavg average --ma)" = "--masses" ] || fail "completion of --ma"

# ---------------------------------------------------------------- the output schema's document
# src/io/README.md holds the naming and migration tables as `pendavg help schema` and
# `pendavg help migration` print them (both generated from the field tables).
for topic in schema migration; do
  "$pendavg" help "$topic" >"$work/$topic" 2>"$work/err" || fail "help $topic exits $?"
  [ -s "$work/$topic" ] || fail "help $topic printed nothing"
  python3 - "$source/src/io/README.md" "$work/$topic" <<'PY' || fail "src/io/README.md lacks \`pendavg help $topic\`'s text (regenerate that part of it)"
import sys
readme, text = (open(p, encoding="utf-8").read() for p in sys.argv[1:3])
sys.exit(0 if text.strip() in readme else 1)
PY
done

[ "$failures" = 0 ] || exit 1
echo "--version, pendavg.1, the bash completion and src/io/README.md agree with the usage text ($(echo $commands))"
