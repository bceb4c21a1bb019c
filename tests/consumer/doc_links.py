#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
# tests/consumer/doc_links.py -- every link of every Markdown document in the repository leads
# somewhere: a relative link names a file or folder that git tracks (or the build generates:
# none today), and a '#anchor' names a heading of its target (GitHub's slugs). A link that
# leaves the repository through '..' is refused: the documents explain everything in the
# repository's own words. Links with a scheme (https:, mailto:) are not followed. A path quoted
# as code (`src/engine/torus/README.md`, from the top) must name a tracked file or folder too,
# unless it is a build product (build/...), a pattern (*) or a placeholder (upper-case words).
#   python3 tests/consumer/doc_links.py SOURCE_DIR
import re
import subprocess
import sys
from pathlib import Path

root = Path(sys.argv[1]).resolve()
listing = subprocess.run(["git", "-C", str(root), "ls-files"], capture_output=True, text=True)
if listing.returncode != 0:
    print(f"doc_links: {root} is not a git checkout: skipped")
    sys.exit(77)
tracked = set(listing.stdout.split("\n"))
folders = {str(Path(f).parent) for f in tracked} | {"."}
for f in list(folders):
    parts = Path(f).parts
    folders.update(str(Path(*parts[:k])) for k in range(1, len(parts)))

link = re.compile(r"(?<!\!)\[[^\]]*\]\(([^)\s]+)\)|\!\[[^\]]*\]\(([^)\s]+)\)")
fence = re.compile(r"^\s*(```|~~~)")


def slugs(path):
    """GitHub's heading anchors of a Markdown file."""
    out, seen, code = set(), {}, False
    for line in (root / path).read_text(encoding="utf-8").splitlines():
        if fence.match(line):
            code = not code
            continue
        m = None if code else re.match(r"^#{1,6}\s+(.*?)\s*#*\s*$", line)
        if not m:
            continue
        text = re.sub(r"`|\*|_{2,}|\[([^\]]*)\]\([^)]*\)", lambda g: g.group(1) or "", m.group(1))
        slug = re.sub(r"[^\w\- ]", "", text.lower()).replace(" ", "-")
        n = seen.get(slug, 0)
        seen[slug] = n + 1
        out.add(slug if n == 0 else f"{slug}-{n}")
    return out


failures, checked = [], 0
for doc in sorted(f for f in tracked if f.endswith(".md")):
    code = False
    for number, line in enumerate((root / doc).read_text(encoding="utf-8").splitlines(), 1):
        if fence.match(line):
            code = not code
            continue
        if code:
            continue
        for quoted in re.findall(r"`((?:src|include|tests|tables|cmake|\.ci)/[^`\s]*)`", line):
            if "*" in quoted or re.search(r"[A-Z]{3,}", quoted) or "..." in quoted:
                continue
            checked += 1
            path = quoted.rstrip("/").split(":")[0]
            if path not in tracked and path not in folders:
                failures.append(f"{doc}:{number}: `{quoted}` names no file of the repository")
        for m in link.finditer(re.sub(r"`[^`]*`", "", line)):
            target = m.group(1) or m.group(2)
            if re.match(r"^[a-z][a-z0-9+.-]*:", target):
                continue
            checked += 1
            where = f"{doc}:{number}: ({target})"
            path, _, anchor = target.partition("#")
            resolved = (root / doc).parent / path if path else root / doc
            try:
                relative = str(resolved.resolve().relative_to(root))
            except ValueError:
                failures.append(f"{where} leaves the repository")
                continue
            relative = relative.rstrip("/") or "."
            if relative not in tracked and relative not in folders:
                failures.append(f"{where} names no file of the repository")
            elif anchor and relative.endswith(".md") and anchor not in slugs(relative):
                failures.append(f"{where} names no heading of {relative}")

for f in failures:
    print("FAIL", f)
print(f"doc_links: {checked} links checked, {len(failures)} broken")
sys.exit(1 if failures or checked == 0 else 0)
