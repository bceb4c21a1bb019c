# SPDX-License-Identifier: GPL-3.0-or-later
"""A sweep file as an interrupted run might have left it, for --resume tests: every third row
left out, and the last K rows (default 2), then an '# interrupted' line.

    python3 punch_holes.py FILE OUT [K]
"""
import sys

lines = open(sys.argv[1]).read().splitlines(keepends=True)
last = int(sys.argv[3]) if len(sys.argv) > 3 else 2
head = [l for l in lines if l.startswith("#")]
body = [l for l in lines if not l.startswith("#")]
rows = [r for k, r in enumerate(body[1:]) if k % 3 != 1][:-last]
open(sys.argv[2], "w").write("".join(head + body[:1] + rows) + "# interrupted: x\n")
