#!/usr/bin/env python3
# SPDX-License-Identifier: GPL-3.0-or-later
"""tests/golden/golden.py -- golden outputs of the pendavg CLI and Python module (issue 27 item
1): every command, method and format run on fixed inputs and compared byte for byte with
tests/golden/expected/, so that every later move of the front ends is checked.

    golden.py --pendavg build/pendavg --python-path build/python [CASE ...]   check
    golden.py --pendavg build/pendavg --python-path build/python --update [CASE ...]
    golden.py --list          every case's name, label and kind (cli or python), for CMake

Without CASE every case runs (--update then also deletes the expected files of removed cases);
--python-path is needed only by the python cases; --times prints each case's wall and CPU time.

CASE is a case name or a shell pattern (`average.n2.*`). ctest runs each case as its own test,
golden.<case> (`ctest -R golden` lists them). After a deliberate change of the output (a renamed
key, a new column), `--update` rewrites the expected files and `git diff tests/golden/expected`
shows exactly what changed, for review.

The cases are in tests/golden/cases.txt (its head documents the format). Each case runs in a
fresh temporary directory holding copies of its `input` files from tests/golden/inputs/, so file
names in the output are the same everywhere; in an environment without PENDAVG_* and OMP_*
variables (but OMP_NUM_THREADS, which the case's `threads` line may set), with LC_ALL=C and
SOURCE_DATE_EPOCH=0 (the sweep files' date line). The expected file holds the command, its exit
code, its stdout, its stderr without progress lines, and every `file` the case names, each after
the normalizations below. A difference is reported with the case, the section and line, the
character and the JSON key or CSV column there, and both lines around it. A case with `threads 1 2` runs once per thread count, each run checked.

Normalizations (what legitimately varies between two runs of the same command; nothing else is
touched, so any other difference fails):
  seconds   the wall-clock time: JSON "seconds": X, text `seconds = X`, a Python repr's
            seconds=X and field `seconds: X`, and a CSV column named seconds become <seconds>
  version   the version in the sweep files' provenance line `# pendavg 0.2.0, generated ...`
            (JSON: the header item "pendavg 0.2.0, generated ...") becomes <version> (a release changes it; the date is pinned by SOURCE_DATE_EPOCH)
  progress  stderr lines `[command] ...` (progress of runs over 2 s) are dropped
  timing    the numbers of `--timing`'s stderr line but rows= (CPU times, the thread count)
            become <n>
Only the standard library is used.
"""
import argparse
import fnmatch
import os
import re
import resource
import shlex
import shutil
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
CASES_FILE = os.path.join(HERE, "cases.txt")
INPUTS = os.path.join(HERE, "inputs")
EXPECTED = os.path.join(HERE, "expected")
TIMEOUT = 300  # seconds per run: a hang fails its case instead of the whole suite


# ---------------------------------------------------------------- the cases file

class Case:
    def __init__(self, name, line):
        self.name = name
        self.line = line  # where the case starts in cases.txt, for messages
        self.args = None    # pendavg's arguments, or
        self.python = None  # a Python statement run with `pendavg` and `show` imported
        self.inputs = []
        self.files = []
        self.env = {}
        self.threads = [None]  # None: inherit OMP_NUM_THREADS
        self.label = "default"


def read_cases(path=CASES_FILE):
    cases, case = [], None
    with open(path, encoding="utf-8") as f:
        for number, raw in enumerate(f, 1):
            text = raw.strip()
            if not text or text.startswith("#"):
                continue
            word, _, rest = text.partition(" ")
            rest = rest.strip()
            where = f"{path}:{number}"
            if word == "case":
                if not re.fullmatch(r"[a-z0-9][a-z0-9_.-]*", rest):
                    sys.exit(f"{where}: bad case name {rest!r} (lower case, digits, _ . -)")
                if any(c.name == rest for c in cases):
                    sys.exit(f"{where}: case {rest} named twice")
                case = Case(rest, number)
                cases.append(case)
                continue
            if case is None:
                sys.exit(f"{where}: {word!r} before the first case line")
            if word == "run":
                case.args = shlex.split(rest)
            elif word == "python":
                case.python = rest
            elif word == "input":
                case.inputs += rest.split()
            elif word == "file":
                case.files += rest.split()
            elif word == "env":
                for item in shlex.split(rest):
                    key, equals, value = item.partition("=")
                    if not equals:
                        sys.exit(f"{where}: env wants KEY=VALUE, not {item!r}")
                    case.env[key] = value
            elif word == "threads":
                case.threads = [int(t) for t in rest.split()]
            elif word == "label":
                case.label = rest
            else:
                sys.exit(f"{where}: unknown line {word!r}")
    for c in cases:
        if (c.args is None) == (c.python is None):
            sys.exit(f"{path}:{c.line}: case {c.name} needs one run or python line")
    return cases


# ---------------------------------------------------------------- normalizations

SECONDS_JSON = re.compile(r'("seconds": )-?[0-9][0-9.eE+-]*')
SECONDS_TEXT = re.compile(r"(\bseconds(?: = |=|: ))-?[0-9][0-9.eE+-]*")
VERSION_LINE = re.compile(r"^(# pendavg |\"pendavg )\S+(, generated )", re.M)
PROGRESS_LINE = re.compile(r"^\[[a-z-]+\] ")
TIMING_LINE = re.compile(r"^pendavg: timing: ")
TIMING_NUMBER = re.compile(r"\b(?!rows=)([a-z0-9_]+=)[0-9][0-9.eE+-]*")


def normalize_csv_seconds(text):
    """A CSV column named `seconds` (the first line not starting with '#' is the header)."""
    lines = text.split("\n")
    column = None
    for i, line in enumerate(lines):
        if not line or line.startswith("#"):
            continue
        cells = line.split(",")
        if column is None:
            if "seconds" not in cells:
                return text
            column = cells.index("seconds")
        elif column < len(cells) and cells[column]:
            cells[column] = "<seconds>"
            lines[i] = ",".join(cells)
    return "\n".join(lines)


def normalize_output(text):
    text = SECONDS_JSON.sub(r"\1<seconds>", text)
    text = SECONDS_TEXT.sub(r"\1<seconds>", text)
    text = VERSION_LINE.sub(r"\1<version>\2", text)
    return normalize_csv_seconds(text)


def normalize_stderr(text):
    kept = []
    for line in text.splitlines(keepends=True):
        if PROGRESS_LINE.match(line):
            continue
        if TIMING_LINE.match(line):
            line = TIMING_NUMBER.sub(r"\1<n>", line)
        kept.append(line)
    return "".join(kept)


# ---------------------------------------------------------------- running and rendering

def clean_environment(case, threads):
    env = {k: v for k, v in os.environ.items()
           if not k.startswith("PENDAVG_") and not (k.startswith("OMP_") and k != "OMP_NUM_THREADS")}
    env.update(LC_ALL="C", SOURCE_DATE_EPOCH="0")
    if threads is not None:
        env["OMP_NUM_THREADS"] = str(threads)
    env.update(case.env)
    return env


def section(title, text):
    """A titled block; text that does not end in a newline is marked so (bytes stay exact)."""
    if text and not text.endswith("\n"):
        text += "\n--- (no newline at the end)\n"
    return f"--- {title}\n{text}"


def run_case(tools, case, threads):
    """The rendered document of one run of `case`: what its expected file holds."""
    env = clean_environment(case, threads)
    if case.python is None:
        command, title = [tools.pendavg] + case.args, f"$ pendavg {shlex.join(case.args)}"
    else:
        command = [sys.executable, "-c", "import pendavg\nfrom show import refusal, show\n" + case.python]
        title = f">>> {case.python}"
        env["PYTHONPATH"] = os.pathsep.join([tools.python_path, HERE])
    with tempfile.TemporaryDirectory(prefix="pendavg-golden-") as work:
        for name in case.inputs:
            shutil.copy(os.path.join(INPUTS, name), os.path.join(work, name))
        try:
            done = subprocess.run(command, cwd=work, stdin=subprocess.DEVNULL,
                                  capture_output=True, env=env, timeout=TIMEOUT)
            code, out, err = done.returncode, done.stdout, done.stderr
        except subprocess.TimeoutExpired:
            code, out, err = "timeout", b"", f"killed after {TIMEOUT} s\n".encode()
        doc = [title + "\n"]
        doc += [f"env {k}={v}\n" for k, v in sorted(case.env.items())]
        doc.append(f"exit {code}\n")
        doc.append(section("stdout", normalize_output(out.decode("utf-8", "backslashreplace"))))
        stderr = normalize_stderr(err.decode("utf-8", "backslashreplace"))
        if stderr:
            doc.append(section("stderr", stderr))
        for name in case.files:
            path = os.path.join(work, name)
            if os.path.exists(path):
                with open(path, "rb") as f:
                    content = f.read().decode("utf-8", "backslashreplace")
                doc.append(section(f"file {name}", normalize_output(content)))
            else:
                doc.append(f"--- file {name} (missing)\n")
        return "".join(doc)


JSON_KEY = re.compile(r'"([^"]+)": ')


def first_difference(expected, got):
    """Where two rendered documents first differ: the section's title, the line number in the
    section, both lines, the column of the first differing character and the field there (a
    JSON key, or a CSV column named by the section's header line), or None."""
    title, number, header = "header", 0, None
    exp_lines, got_lines = expected.split("\n"), got.split("\n")
    for i in range(max(len(exp_lines), len(got_lines))):
        e = exp_lines[i] if i < len(exp_lines) else "<end of file>"
        g = got_lines[i] if i < len(got_lines) else "<end of file>"
        if e != g:
            if header is None and title != "header" and not e.startswith(("#", "{")):
                header = e  # the CSV's column line itself differs
            column = next((k for k, (a, b) in enumerate(zip(e, g)) if a != b), min(len(e), len(g)))
            field = None
            keys = JSON_KEY.findall(e[:column])
            if e.startswith("{") and keys:
                field = f"JSON key {keys[-1]}"
            elif header is not None and "," in e:
                index = e[:column].count(",")
                names = header.split(",")
                field = f"CSV column {index + 1}" + (f" ({names[index]})" if index < len(names) else "")
            return title, number + 1, e, g, column, field
        if e.startswith("--- "):
            title, number, header = e[4:], 0, None
        else:
            number += 1
            if header is None and title != "header" and not e.startswith("#"):
                header = e  # a CSV's column line (or a JSON document: then unused)
    return None


def window(line, column, width=60):
    """The part of `line` around `column`, marked where it is cut."""
    start = max(0, column - width // 2)
    text = line[start:start + width]
    return ("..." if start > 0 else "") + text + ("..." if start + width < len(line) else "")


def report(case, threads, against, expected, got, tools):
    """Prints which case differs from what, where first, and how to accept the change."""
    title, line, e, g, column, field = first_difference(expected, got)
    where = "" if threads is None else f" (OMP_NUM_THREADS={threads})"
    text = [f"golden {case.name}{where}: differs from {against}",
            f"  command:  {got.split(chr(10), 1)[0]}",
            f"  first difference: {title}, line {line}, character {column + 1}"
            + (f", {field}" if field else ""),
            f"  expected: {window(e, column)}",
            f"  got:      {window(g, column)}"]
    if title == "header" and "\n--- stderr\n" in got:  # another exit code: what it said
        text += [f"  stderr:   {l}" for l in got.split("\n--- stderr\n", 1)[1].splitlines()[:3]]
    text.append(f"  if the change is intended: {os.path.relpath(__file__)} {tools.options()}"
                f" --update {case.name}, then review git diff tests/golden/expected")
    print("\n".join(text))


def check(tools, case, update):
    """Runs `case` (once per thread count): "passed", "failed", or with update "written" or
    "unchanged" (runs that differ between thread counts are "failed" and not written)."""
    path = os.path.join(EXPECTED, case.name + ".out")
    docs = [(threads, run_case(tools, case, threads)) for threads in case.threads]
    if update:
        first = docs[0][1]
        for threads, doc in docs[1:]:
            if doc != first:
                report(case, threads, f"the run with OMP_NUM_THREADS={docs[0][0]} (not written)",
                       first, doc, tools)
                return "failed"
        old = open(path, encoding="utf-8").read() if os.path.exists(path) else None
        if old != first:
            with open(path, "w", encoding="utf-8") as f:
                f.write(first)
            print(f"golden {case.name}: {'written' if old is None else 'updated'} {path}")
            return "written"
        return "unchanged"
    if not os.path.exists(path):
        print(f"golden {case.name}: no expected file {path} (write it with --update {case.name})")
        return "failed"
    expected = open(path, encoding="utf-8").read()
    status = "passed"
    for threads, doc in docs:
        if doc != expected:
            status = "failed"
            report(case, threads, os.path.relpath(path), expected, doc, tools)
    return status


def children_cpu_seconds():
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


class Tools:
    """What the cases run: the pendavg binary and the directory of the Python module."""
    def __init__(self, pendavg, python_path):
        self.pendavg = os.path.abspath(pendavg)
        self.python_path = python_path and os.path.abspath(python_path)

    def options(self):
        return f"--pendavg {self.pendavg}" + (f" --python-path {self.python_path}"
                                              if self.python_path else "")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--pendavg", help="the pendavg binary (build/pendavg)")
    parser.add_argument("--python-path", help="the Python module's directory (build/python), "
                        "for the cases with a python line")
    parser.add_argument("--update", action="store_true", help="rewrite the expected files")
    parser.add_argument("--list", action="store_true",
                        help="print each case's name, label and kind (cli or python)")
    parser.add_argument("--times", action="store_true", help="print each case's wall and CPU time")
    parser.add_argument("cases", nargs="*", help="case names or shell patterns (default: all)")
    options = parser.parse_args()
    cases = read_cases()
    if options.list:
        for case in cases:
            print(case.name, case.label, "cli" if case.python is None else "python")
        return 0
    if not options.pendavg:
        parser.error("--pendavg is required")
    tools = Tools(options.pendavg, options.python_path)
    chosen = cases
    if options.cases:
        chosen = [c for c in cases if any(fnmatch.fnmatchcase(c.name, p) for p in options.cases)]
        unmatched = [p for p in options.cases
                     if not any(fnmatch.fnmatchcase(c.name, p) for c in cases)]
        if unmatched:
            sys.exit(f"no case matches {', '.join(unmatched)}")
    if not tools.python_path and any(c.python is not None for c in chosen):
        sys.exit("the python cases need --python-path (build/python); "
                 "or name only the cli cases")
    if options.update:
        os.makedirs(EXPECTED, exist_ok=True)
    failed, written = [], 0
    for case in chosen:
        start, cpu = time.monotonic(), children_cpu_seconds()
        status = check(tools, case, options.update)
        if status == "failed":
            failed.append(case.name)
        written += status == "written"
        if options.times:
            print(f"golden {case.name}: {time.monotonic() - start:.2f} s wall, "
                  f"{children_cpu_seconds() - cpu:.2f} s CPU")
    if options.update and not options.cases:
        known = {c.name + ".out" for c in cases}
        for stale in sorted(set(os.listdir(EXPECTED)) - known):
            os.remove(os.path.join(EXPECTED, stale))
            print(f"golden: removed {stale} (no such case)")
    if failed:
        print(f"golden: {len(failed)} of {len(chosen)} cases failed: {' '.join(failed)}")
        return 1
    if options.update:
        print(f"golden: {len(chosen)} cases run, {written} expected files written")
    else:
        print(f"golden: {len(chosen)} cases passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
