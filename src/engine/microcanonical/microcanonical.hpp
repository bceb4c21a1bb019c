// SPDX-License-Identifier: GPL-3.0-or-later
// engine/microcanonical/microcanonical.hpp -- the microcanonical engine's internals; the entry
// points and what they compute are declared in include/pendavg/microcanonical.hpp, the math of
// the method is src/engine/microcanonical/README.md.
//
// Equations. Per angle node at energy E (momenta uniform on the ellipsoid p^T A^{-1} p / 2 = E - U):
//     weight            sqrt(det A) (E - U)_+^{N/2 - 1}        (times (2 pi)^{N/2} / Gamma(N/2))
//     <K_i | phi, E>    = tr(X_i) (E - U) / N
//     <K_i^2 | phi, E>  = (E - U)^2 [(tr X_i)^2 + 2 tr(X_i^2)] / (N (N + 2))
//     Omega(E)          = the integral of the weight over the angles (density of states)
// The psi integral is done in closed form per shell (microcanonical/shell.hpp); the remaining
// N - 1 relative angles by one of three rules: a nested tanh-sinh integral over the cuts of the
// allowed region (microcanonical/nested_integral.hpp), the torus trapezoid, or randomized QMC
// (both in microcanonical.cpp, on the torus and qmc engines' rules and shifts).
#pragma once

#include "engine/microcanonical/nested_integral.hpp"
#include "engine/microcanonical/shell.hpp"
