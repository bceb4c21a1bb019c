# SPDX-License-Identifier: GPL-3.0-or-later
# Type stubs of the package pendavg (the documented API of __init__.py; see its docstrings).
from collections.abc import Callable, Sequence
from decimal import Decimal
from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt

from ._pendavg import Averages as Averages
from ._pendavg import MicrocanonicalResult as MicrocanonicalResult
from ._pendavg import SimulationResult as SimulationResult

__version__: str
__all__ = ["average", "sweep", "limit", "series", "microcanonical", "simulate", "poincare",
           "Averages", "Limits", "SeriesResult", "MicrocanonicalResult", "SimulationResult",
           "PoincareSection", "dynamics_instruction_set"]

# A number: read as the `pendavg` command reads the same text (float: its repr; str: as
# written; Decimal; mpmath.mpf: its binary value; int: exactly).
_Number = float | int | str | Decimal | Any
# A number, or (for broadcasting) an array or a sequence of them.
_Numbers = _Number | npt.ArrayLike | Sequence[Any]
_Progress = bool | Callable[[float], object] | None

def dynamics_instruction_set() -> str: ...
def average(masses: _Numbers, lengths: _Numbers, beta: _Numbers, g: _Numbers = ...,
            digits: int = ..., method: str = ..., tol: _Number | None = ...,
            samples: int | None = ..., shifts: int | None = ..., seed: int | None = ...,
            progress: _Progress = ..., certified: bool = ...) -> Averages: ...
def sweep(beta: _Numbers, mu1: _Numbers = ..., l1: _Numbers = ..., l2: _Numbers = ...,
          g: _Numbers = ..., digits: int = ..., method: str = ...,
          progress: _Progress = ...) -> Averages: ...

class Limits(NamedTuple):
    high_temperature: Averages
    low_temperature: Averages
    def to_dict(self) -> dict[str, dict[str, Any]]: ...
    def to_dataframe(self) -> Any: ...

def limit(masses: _Numbers, lengths: _Numbers | None = ..., g: _Number = ..., digits: int = ...,
          progress: _Progress = ..., certified: bool = ...) -> Limits: ...

class _Record:
    def __init__(self, fields: dict[str, Any]) -> None: ...
    def as_dict(self) -> dict[str, Any]: ...
    def to_dict(self) -> dict[str, Any]: ...
    def to_dataframe(self) -> Any: ...

class SeriesResult(_Record):
    N: int
    digits: int
    beta: float
    g: float
    m: npt.NDArray[np.float64]
    l: npt.NDArray[np.float64]
    terms: int
    certified: bool
    beta_K1_error_kind: str
    n: npt.NDArray[np.int64]
    R_n: npt.NDArray[np.float64]
    term: npt.NDArray[np.float64]
    numerator: npt.NDArray[np.float64]
    denominator: npt.NDArray[np.float64]
    beta_K1: npt.NDArray[np.float64]
    beta_K1_error: npt.NDArray[np.float64]
    decimal: dict[str, Any]
    exact: dict[str, list[Any]]
    @staticmethod
    def fields() -> tuple[list[tuple[str, str, bool, str, bool]],
                          list[tuple[str, str, bool, str, bool]]]: ...
    @property
    def mpf(self) -> dict[str, list[Any]]: ...

def series(masses: _Numbers, lengths: _Numbers, beta: _Number, g: _Number = ..., digits: int = ...,
           terms: int = ..., progress: _Progress = ...) -> SeriesResult: ...
def microcanonical(masses: _Numbers, lengths: _Numbers, energy: _Number | None = ...,
                   g: _Number = ..., digits: int = ..., method: str = ...,
                   tol: _Number | None = ..., samples: int | None = ..., shifts: int | None = ...,
                   seed: int | None = ...,
                   excitation: _Number | None = ...) -> MicrocanonicalResult: ...

class PoincareSection(_Record):
    N: int
    g: float
    m: npt.NDArray[np.float64]
    l: npt.NDArray[np.float64]
    energy: float
    orbits: int
    points_per_orbit: int
    dt: float
    steps: int
    energy_error_max: float
    interrupted: bool
    orbit: npt.NDArray[np.int64]
    phi2: npt.NDArray[np.float64]
    p2: npt.NDArray[np.float64]
    time: npt.NDArray[np.float64]
    start_phi2: npt.NDArray[np.float64]
    start_p2: npt.NDArray[np.float64]
    seconds: float
    decimal: dict[str, Any]
    @staticmethod
    def fields() -> tuple[list[tuple[str, str, bool, str, bool]],
                          list[tuple[str, str, bool, str, bool]],
                          list[tuple[str, str, bool, str, bool]]]: ...

def simulate(masses: _Numbers, lengths: _Numbers, g: _Number = ..., *, theta: _Number | None = ...,
             phi: _Numbers | None = ..., phidot: _Numbers | None = ..., time: _Number,
             dt: _Number | None = ..., burn_in: _Number | None = ..., integrator: str | None = ...,
             thermostat: str | None = ..., beta: _Number | None = ...,
             friction: _Number | None = ...,
             seed: int | None = ..., exact: bool | str = ..., every: int | None = ...,
             progress: _Progress = ...) -> SimulationResult: ...
def poincare(masses: _Numbers, lengths: _Numbers, energy: _Number, g: _Number = ..., *,
             orbits: int | None = ..., points: int | None = ..., dt: _Number | None = ...,
             progress: _Progress = ...) -> PoincareSection: ...
