#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# tests/consumer/add_spdx.sh [SOURCE_DIR] -- adds "SPDX-License-Identifier: GPL-3.0-or-later" to
# every tracked source and script file that lacks it (the files tests/consumer/spdx.sh checks), in
# the file's comment syntax (// for C++, # otherwise), as the first line or right after a shebang
# line. Idempotent: a file that names the license in its first 5 lines is left as it is.
set -euo pipefail
cd "${1:-$(dirname "$0")/../..}"
added=0
while IFS= read -r -d '' file; do
  head -n 5 "$file" | grep -q 'SPDX-License-Identifier: GPL-3.0-or-later' && continue
  case "$file" in
    *.cpp | *.hpp | *.hpp.in | *.cpp.in | *.h.in) line='// SPDX-License-Identifier: GPL-3.0-or-later' ;;
    *) line='# SPDX-License-Identifier: GPL-3.0-or-later' ;;
  esac
  tmp=$(mktemp)
  if head -n 1 "$file" | grep -q '^#!'; then
    { head -n 1 "$file"; printf '%s\n' "$line"; tail -n +2 "$file"; } >"$tmp"
  else
    { printf '%s\n' "$line"; cat "$file"; } >"$tmp"
  fi
  cat "$tmp" >"$file"  # keeps the file's mode (executable scripts stay executable)
  rm -f "$tmp"
  added=$((added + 1))
done < <(git ls-files -z -- '*.cpp' '*.hpp' '*.in' '*.py' '*.pyi' '*.sh' '*.cmake' '*CMakeLists.txt' '*.slurm')
echo "added the license line to $added files"
