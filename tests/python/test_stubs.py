# SPDX-License-Identifier: GPL-3.0-or-later
"""The type stubs (pendavg/__init__.pyi, pendavg/_pendavg.pyi, the PEP 561 marker py.typed) match
the module: mypy.stubtest against the built package, and an introspection check of what stubtest
cannot see (the fields of the result objects, which are instance attributes).
"""
import ast
import os
import subprocess
import sys
import warnings

import numpy as np

import pendavg

from test_pendavg import optional_module

PACKAGE = os.path.dirname(pendavg.__file__)
ALLOWLIST = os.path.join(os.path.dirname(__file__), "stubtest_allowlist.txt")


def stub(name):
    with open(os.path.join(PACKAGE, name)) as fh:
        return ast.parse(fh.read())


def top_level_names(tree):
    names = set()
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, ast.AnnAssign):
            names.add(node.target.id)
        elif isinstance(node, ast.Assign):
            names.update(t.id for t in node.targets)
        elif isinstance(node, ast.ImportFrom) and node.module == "_pendavg":
            names.update(a.asname for a in node.names if a.asname)
    return {n for n in names if not n.startswith("_")}


def class_members(tree, name):
    """{member: 'property' | 'method' | 'attribute'} of class `name` in a stub."""
    for node in tree.body:
        if isinstance(node, ast.ClassDef) and node.name == name:
            out = {}
            for item in node.body:
                if isinstance(item, ast.FunctionDef):
                    is_property = any(isinstance(d, ast.Name) and d.id == "property"
                                      for d in item.decorator_list)
                    out[item.name] = "property" if is_property else "method"
                elif isinstance(item, ast.AnnAssign):
                    out[item.target.id] = "attribute"
            return out
    raise AssertionError(f"no class {name} in the stub")


def test_the_package_ships_its_stubs():
    for name in ("__init__.pyi", "_pendavg.pyi", "py.typed"):
        assert os.path.isfile(os.path.join(PACKAGE, name)), name


def test_stubtest_finds_no_difference(tmp_path):
    optional_module("mypy.stubtest")
    env = dict(os.environ, PYTHONPATH=os.path.dirname(PACKAGE))
    done = subprocess.run([sys.executable, "-m", "mypy.stubtest", "pendavg", "--allowlist",
                           ALLOWLIST, "--mypy-config-file", os.devnull], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    assert "Success" in done.stdout


def test_every_public_name_has_a_stub_and_every_stub_a_name():
    public = {n for n in dir(pendavg) if not n.startswith("_")}
    assert top_level_names(stub("__init__.pyi")) == public
    assert set(pendavg.__all__) <= public
    core = {n for n in dir(pendavg._pendavg) if not n.startswith("_")}
    assert top_level_names(stub("_pendavg.pyi")) == core


def stub_order(tree, name):
    """The members of class `name` in a stub, in the stub's order."""
    for node in tree.body:
        if isinstance(node, ast.ClassDef) and node.name == name:
            return [item.name if isinstance(item, ast.FunctionDef) else item.target.id
                    for item in node.body if isinstance(item, (ast.FunctionDef, ast.AnnAssign))]
    raise AssertionError(f"no class {name} in the stub")


def test_table_class_stubs_list_every_field():
    """Averages, MicrocanonicalResult and SimulationResult (generated from the field tables): the
    stub has a property per runtime attribute -- the class's own (its fields first, in the
    tables' order) and their base _TableResult's, which the runtime classes share (the stub's
    base is the runtime's) -- and every stubbed property answers."""
    results = {"Averages": pendavg.average([0.5, 0.5], [1, 1], 1.0),
               "MicrocanonicalResult": pendavg.microcanonical([1, 1], [1, 1], 0.5),
               "SimulationResult": pendavg.simulate([1, 1], [1, 1], theta=1, time=0.5)}
    tree = stub("_pendavg.pyi")
    base = class_members(tree, "_TableResult")
    assert set(base) - {"__init__"} == {n for n in dir(pendavg._pendavg._TableResult)
                                        if not n.startswith("__")}
    for name, result in results.items():
        cls = getattr(pendavg, name)
        assert cls.__bases__ == (pendavg._pendavg._TableResult,), name
        assert stub_bases(tree, name) == ["_TableResult"], name
        own = class_members(tree, name)
        assert not set(own) & set(base), name  # shared members are stubbed once, on the base
        members = {**base, **own}
        runtime = {n for n in dir(cls) if not n.startswith("__")}
        assert set(members) - {"__init__"} == runtime, name
        fields = [f[0] for f in cls.fields()]
        assert stub_order(tree, name)[:len(fields)] == fields, name
        with warnings.catch_warnings():  # (the deprecated aliases answer with a warning)
            warnings.simplefilter("ignore", DeprecationWarning)
            for member, kind in members.items():
                if kind == "property":
                    getattr(result, member)  # every stubbed property answers


def stub_bases(tree, name):
    for node in tree.body:
        if isinstance(node, ast.ClassDef) and node.name == name:
            return [b.id for b in node.bases]
    raise AssertionError(f"no class {name} in the stub")


def test_result_stubs_list_every_field():
    """The attributes a result object has at runtime are the ones its stub annotates."""
    tree = stub("__init__.pyi")
    results = {
        "SeriesResult": pendavg.series(["0.8", "0.2"], [1, 1], 2, digits=20),
        "PoincareSection": pendavg.poincare([1, 1], [1, 1], -2, orbits=1, points=2),
    }
    record = class_members(tree, "_Record")
    for name, result in results.items():
        members = class_members(tree, name)
        attributes = {n for n, kind in members.items() if kind == "attribute"}
        assert attributes == set(result.__dict__), name
        for method in set(members) - attributes:
            assert callable(getattr(type(result), method)) or \
                isinstance(getattr(type(result), method), property), method
        assert {m for m in record if m != "__init__"} <= set(dir(result))
    limits = pendavg.limit([0.5, 0.5])
    assert set(class_members(tree, "Limits")) == {"high_temperature", "low_temperature",
                                                  "to_dict", "to_dataframe"}
    assert isinstance(limits.to_dict()["high_temperature"]["beta_K"], np.ndarray)
