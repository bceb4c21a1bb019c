// SPDX-License-Identifier: GPL-3.0-or-later
// src/python/bindings.hpp -- the extension pendavg._pendavg, one binding file per algorithm
// (Pinocchio's bindings/python/algorithm/expose-*.cpp): each expose_* adds its functions and
// result classes to the module. The documented API is pendavg/__init__.py, which calls these.
#pragma once

#include <pybind11/pybind11.h>

namespace pendavg::python {

void expose_average(pybind11::module_& m);         // average (one point or a grid), limit
void expose_series(pybind11::module_& m);          // the paper's series term by term
void expose_microcanonical(pybind11::module_& m);  // fixed-energy averages
void expose_dynamics(pybind11::module_& m);        // simulate, poincare

}  // namespace pendavg::python
