// SPDX-License-Identifier: GPL-3.0-or-later
// pendavg/pendavg.hpp -- the whole public API of pendavg in double precision: thermal averages of
// the kinetic energy of each particle of a planar N-link pendulum (Konishi & Yanagita), exactly
// and with honest errors, and the trajectories that confirm them.
//
//   pendavg::Chain<double> chain({1.0, 1.0}, {1.0, 1.0});         // masses, lengths (g = 1)
//   pendavg::Averages<double> a = pendavg::average(chain, 1.0);   // beta = 1
//   a.beta_kinetic[0].value, a.beta_kinetic[0].error, a.error_kind, a.method, ...
//
// Headers: chain.hpp (the model), result.hpp (Estimate, Averages), average.hpp (canonical
// averages and limits, any N), series.hpp (the paper's series term by term), microcanonical.hpp
// (fixed energy), dynamics.hpp (RATTLE trajectories, Langevin, Poincare sections),
// trace_formula.hpp (the O(N) node traces). For 17..1000 digits include pendavg/mpfr.hpp too.
// The library does no I/O; bad input throws pendavg::invalid_input with a one-line message.
#pragma once

#include "pendavg/average.hpp"
#include "pendavg/chain.hpp"
#include "pendavg/dynamics.hpp"
#include "pendavg/microcanonical.hpp"
#include "pendavg/result.hpp"
#include "pendavg/series.hpp"
#include "pendavg/trace_formula.hpp"
#include "pendavg/version.hpp"
