#!/usr/bin/env bash
# SPDX-License-Identifier: GPL-3.0-or-later
# tests/consumer/spdx.sh SOURCE_DIR -- every tracked source and script file (*.cpp *.hpp *.in *.py
# *.pyi *.sh *.cmake CMakeLists.txt *.slurm) names its license, SPDX-License-Identifier:
# GPL-3.0-or-later, in its first 5 lines (tests/consumer/add_spdx.sh adds the line). Outside a
# git checkout (a source archive) the files on disk are checked instead.
set -euo pipefail
cd "$1"
list_files() {
  if git rev-parse --is-inside-work-tree >/dev/null 2>&1; then
    git ls-files -z -- '*.cpp' '*.hpp' '*.in' '*.py' '*.pyi' '*.sh' '*.cmake' '*CMakeLists.txt' '*.slurm'
  else
    find . -path ./build -prune -o -path './build-*' -prune -o -type f \( -name '*.cpp' -o -name '*.hpp' \
      -o -name '*.in' -o -name '*.py' -o -name '*.pyi' -o -name '*.sh' -o -name '*.cmake' \
      -o -name CMakeLists.txt -o -name '*.slurm' \) -print0
  fi
}
missing=0 count=0
while IFS= read -r -d '' file; do
  count=$((count + 1))
  if ! head -n 5 "$file" | grep -q 'SPDX-License-Identifier: GPL-3.0-or-later'; then
    echo "no SPDX-License-Identifier: GPL-3.0-or-later in the first lines of $file" >&2
    missing=$((missing + 1))
  fi
done < <(list_files)
[ "$count" -gt 0 ] || { echo "FAIL: no source files found" >&2; exit 1; }
if [ "$missing" -gt 0 ]; then
  echo "FAIL: $missing of $count files lack the license line (bash tests/consumer/add_spdx.sh adds it)" >&2
  exit 1
fi
echo "all $count source and script files carry SPDX-License-Identifier: GPL-3.0-or-later"
