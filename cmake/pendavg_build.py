# SPDX-License-Identifier: GPL-3.0-or-later
"""The PEP 517 build backend of `pip install .` (pyproject.toml: backend-path = ["cmake"]).

CMake stays the one description of the build: this backend configures the project for the
interpreter that runs it (-DPython_EXECUTABLE=sys.executable), builds the Python module alone
(static libpendavg, no CLI, tests or benchmarks), installs only the install COMPONENT `python`
(the package pendavg: *.py, *.pyi, py.typed and the extension) into a staging directory and packs
that as a wheel. The version is CMake's project(VERSION).

Why a backend of our own: Debian 12 packages no scikit-build-core (nor scikit-build), and the
setuptools it packages would need a setup.py (not allowed at the top level) and a second
description of the extension. Packing a wheel is a zip file with three metadata files (PEP 427),
which the standard library does. Everything it needs is in the standard library, so that
`pip install --no-build-isolation .` works without a package index (and with build isolation too:
it requires nothing).

Settings: CMAKE_ARGS (extra configure arguments, as scikit-build-core reads them),
CMAKE_BUILD_PARALLEL_LEVEL (build jobs; default: the CPU count), CMAKE_CXX_COMPILER_LAUNCHER
(e.g. ccache) are taken from the environment, and PENDAVG_PIP_BUILD_DIR: a build directory to use
and keep (default: a temporary one), for incremental rebuilds.
"""

import base64
import csv
import hashlib
import io
import os
import re
import shlex
import subprocess
import sys
import sysconfig
import tarfile
import tempfile
import zipfile
from pathlib import Path

try:
    import tomllib
except ImportError:  # Python < 3.11
    import tomli as tomllib

_SOURCE = Path.cwd()  # PEP 517: hooks run in the source tree


def _version():
    """project(pendavg VERSION x.y.z ...) of CMakeLists.txt."""
    text = (_SOURCE / "CMakeLists.txt").read_text()
    found = re.search(r"project\(\s*pendavg\s+VERSION\s+([0-9][0-9.]*)", text)
    if not found:
        raise RuntimeError("no project(pendavg VERSION ...) in CMakeLists.txt")
    return found.group(1)


def _project():
    return tomllib.loads((_SOURCE / "pyproject.toml").read_text())["project"]


def _metadata():
    """METADATA (core metadata 2.1) from pyproject.toml's [project] table and the version."""
    p = _project()
    lines = ["Metadata-Version: 2.1", f"Name: {p['name']}", f"Version: {_version()}",
             f"Summary: {p['description']}"]
    if "license" in p:
        lines.append(f"License: {p['license']['text']}")
    if "requires-python" in p:
        lines.append(f"Requires-Python: {p['requires-python']}")
    for classifier in p.get("classifiers", []):
        lines.append(f"Classifier: {classifier}")
    for author in p.get("authors", []):
        lines.append(f"Author: {author['name']}")
    for label, url in p.get("urls", {}).items():
        lines.append(f"Project-URL: {label}, {url}")
    for requirement in p.get("dependencies", []):
        lines.append(f"Requires-Dist: {requirement}")
    lines.append("License-File: LICENSE")
    body = ""
    if "readme" in p:
        lines.append("Description-Content-Type: text/markdown")
        body = "\n" + (_SOURCE / p["readme"]).read_text()
    return "\n".join(lines) + "\n" + body


def _tag():
    """cpXY-cpXY<abiflags>-<platform>: the extension is built for this interpreter only."""
    interpreter = f"cp{sys.version_info[0]}{sys.version_info[1]}"
    abi = interpreter + getattr(sys, "abiflags", "")
    platform = re.sub(r"[-.]", "_", sysconfig.get_platform())
    return f"{interpreter}-{abi}-{platform}"


def _dist_info_name():
    return f"{_project()['name']}-{_version()}.dist-info"


def _write_dist_info(directory):
    dist_info = Path(directory) / _dist_info_name()
    dist_info.mkdir(parents=True, exist_ok=True)
    (dist_info / "METADATA").write_text(_metadata())
    (dist_info / "WHEEL").write_text(
        f"Wheel-Version: 1.0\nGenerator: pendavg_build\nRoot-Is-Purelib: false\nTag: {_tag()}\n")
    (dist_info / "LICENSE").write_bytes((_SOURCE / "LICENSE").read_bytes())
    return dist_info


def _run(command, **kwargs):
    print("pendavg_build:", shlex.join(str(c) for c in command), flush=True)
    subprocess.run(command, check=True, **kwargs)


def _build_package(build_dir, staging):
    """Configure, build and install the component `python` into `staging`."""
    configure = [
        "cmake", "-S", str(_SOURCE), "-B", str(build_dir), "-DCMAKE_BUILD_TYPE=Release",
        f"-DPython_EXECUTABLE={sys.executable}", "-DPENDAVG_BUILD_PYTHON=ON",
        "-DPENDAVG_BUILD_CLI=OFF", "-DPENDAVG_BUILD_TESTS=OFF", "-DPENDAVG_BUILD_BENCHMARKS=OFF",
        "-DBUILD_SHARED_LIBS=OFF", "-DPENDAVG_PYTHON_INSTALL_DIR=.",
    ]
    configure += shlex.split(os.environ.get("CMAKE_ARGS", ""))
    _run(configure)
    jobs = os.environ.get("CMAKE_BUILD_PARALLEL_LEVEL") or str(os.cpu_count() or 1)
    _run(["cmake", "--build", str(build_dir), "--target", "pendavg_python", "-j", jobs])
    _run(["cmake", "--install", str(build_dir), "--component", "python", "--prefix", str(staging)])
    files = sorted(p for p in Path(staging).rglob("*") if p.is_file())
    names = {p.relative_to(staging).as_posix() for p in files}
    if "pendavg/__init__.py" not in names or not any(n.startswith("pendavg/_pendavg") for n in names):
        raise RuntimeError(f"the python component installed {sorted(names)}, not the package")
    outside = [n for n in names if not n.startswith("pendavg/")]
    if outside:
        raise RuntimeError(f"the python component installed files outside pendavg/: {outside}")
    return files


def _record_line(name, data):
    digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
    return [name, f"sha256={digest}", str(len(data))]


# ---------------------------------------------------------------- PEP 517 hooks

def get_requires_for_build_wheel(config_settings=None):
    return []


def get_requires_for_build_sdist(config_settings=None):
    return []


def prepare_metadata_for_build_wheel(metadata_directory, config_settings=None):
    return _write_dist_info(metadata_directory).name


def build_wheel(wheel_directory, config_settings=None, metadata_directory=None):
    name = f"{_project()['name']}-{_version()}-{_tag()}.whl"
    with tempfile.TemporaryDirectory(prefix="pendavg-wheel-") as work:
        staging = Path(work) / "staging"
        build_dir = os.environ.get("PENDAVG_PIP_BUILD_DIR") or Path(work) / "build"
        files = _build_package(Path(build_dir).absolute(), staging)
        dist_info = _write_dist_info(Path(work) / "meta")
        records = []
        with zipfile.ZipFile(Path(wheel_directory) / name, "w", zipfile.ZIP_DEFLATED) as wheel:
            def add(path, arcname):
                data = Path(path).read_bytes()
                info = zipfile.ZipInfo(arcname, date_time=(2020, 1, 1, 0, 0, 0))
                info.external_attr = (os.stat(path).st_mode & 0o777 | 0o100000) << 16
                info.compress_type = zipfile.ZIP_DEFLATED
                wheel.writestr(info, data)
                records.append(_record_line(arcname, data))
            for path in files:
                add(path, path.relative_to(staging).as_posix())
            for path in sorted(dist_info.iterdir()):
                add(path, f"{dist_info.name}/{path.name}")
            record = io.StringIO()
            csv.writer(record, lineterminator="\n").writerows(
                records + [[f"{dist_info.name}/RECORD", "", ""]])
            wheel.writestr(f"{dist_info.name}/RECORD", record.getvalue())
    return name


def build_sdist(sdist_directory, config_settings=None):
    """The tracked files of the git checkout (as `git archive` would pack them) and PKG-INFO."""
    base = f"{_project()['name']}-{_version()}"
    listed = subprocess.run(["git", "ls-files", "-z"], cwd=_SOURCE, check=True,
                            capture_output=True).stdout.decode().split("\0")
    name = f"{base}.tar.gz"
    with tarfile.open(Path(sdist_directory) / name, "w:gz", format=tarfile.PAX_FORMAT) as sdist:
        for relative in filter(None, listed):
            if (_SOURCE / relative).is_file():
                sdist.add(_SOURCE / relative, f"{base}/{relative}", recursive=False)
        data = _metadata().encode()
        info = tarfile.TarInfo(f"{base}/PKG-INFO")
        info.size = len(data)
        sdist.addfile(info, io.BytesIO(data))
    return name
