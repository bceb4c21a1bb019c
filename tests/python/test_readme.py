# SPDX-License-Identifier: GPL-3.0-or-later
"""The Python examples of src/python/README.md run against the built module: every ```python
block, in order, in one namespace, with the package's DeprecationWarning an error (the examples
use schema 1's names, not the deprecated aliases of pendavg 0.2's)."""
import os
import re
import warnings

from test_pendavg import ROOT, optional_module

README = os.path.join(ROOT, "src", "python", "README.md")


def python_blocks():
    with open(README, encoding="utf-8") as fh:
        return re.findall(r"^```python\n(.*?)^```", fh.read(), flags=re.S | re.M)


def test_readme_python_examples_run():
    optional_module("pandas")  # (the examples convert to DataFrames)
    optional_module("mpmath")  # (and read .mpf)
    blocks = python_blocks()
    assert blocks, "src/python/README.md has no ```python block"
    namespace = {"__name__": "readme"}
    with warnings.catch_warnings():
        warnings.filterwarnings("error", r".* is deprecated \(pendavg 0\.2's name\)",
                                DeprecationWarning)
        for block in blocks:
            exec(compile(block, README, "exec"), namespace)  # noqa: S102 -- the README's own code
