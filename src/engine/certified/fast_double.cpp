// SPDX-License-Identifier: GPL-3.0-or-later
// engine/certified/fast_double.cpp -- the certified N = 2 fast path for double
// (engine/detail/certified_fast.hpp; derivations in engine/certified.md, Sec. 10). The body,
// fast_double_body.inc, is compiled twice: as baseline x86-64 code and, on x86-64 with GCC,
// with fused multiply-adds (`#pragma GCC target("fma")` after every include, so that library
// templates stay baseline code); the variant is chosen once at run time from the CPU.
// This file is compiled with -ffp-contract=off (CMakeLists.txt): the error-free transformations
// need every product and sum rounded as written.
#include "engine/detail/certified_fast.hpp"

#ifdef PENDAVG_HAS_ARB

#include "engine/certified.hpp"
#include "engine/detail/graf_rows.hpp"

#include <arb.h>

#include <array>
#include <cstddef>
#include <optional>
#include <vector>

#if defined(__GNUC__) && !defined(__clang__) && (defined(__x86_64__) || defined(__i386__))
#define PENDAVG_FAST_HAS_FMA_VARIANT 1
#else
#define PENDAVG_FAST_HAS_FMA_VARIANT 0
#endif

namespace pendavg::certified_fast {
namespace {

namespace baseline {
#define PENDAVG_FAST_FMA 0
#include "engine/certified/fast_double_body.inc"
#undef PENDAVG_FAST_FMA
}  // namespace baseline

#if PENDAVG_FAST_HAS_FMA_VARIANT
#pragma GCC push_options
#pragma GCC target("fma")
namespace fused {
#define PENDAVG_FAST_FMA 1
#include "engine/certified/fast_double_body.inc"
#undef PENDAVG_FAST_FMA
}  // namespace fused
#pragma GCC pop_options
#endif

bool use_fma() {
#if PENDAVG_FAST_HAS_FMA_VARIANT
  static const bool yes = __builtin_cpu_supports("fma");
  return yes;
#else
  return false;
#endif
}

}  // namespace

std::optional<FastResult> fast_double_average(const Chain<double>& chain, double beta) {
#if PENDAVG_FAST_HAS_FMA_VARIANT
  if (use_fma()) return fused::run(chain, beta);
#endif
  return baseline::run(chain, beta);
}

const char* fast_double_variant() { return use_fma() ? "fma" : "baseline"; }

int fast_double_last_refusal() {
#if PENDAVG_FAST_HAS_FMA_VARIANT
  if (use_fma()) return fused::last_refusal_line;
#endif
  return baseline::last_refusal_line;
}

}  // namespace pendavg::certified_fast

#endif  // PENDAVG_HAS_ARB
