// SPDX-License-Identifier: GPL-3.0-or-later
// engine/certified/fast_double.cpp -- the certified N = 2 fast path for double
// (engine/detail/certified_fast.hpp; derivations in engine/certified.md, Sec. 10). The body,
// fast_double_body.inc, is compiled twice: as baseline x86-64 code and, on x86-64 with GCC,
// with fused multiply-adds (`#pragma GCC target` after every include, so that library templates
// stay baseline code; 128-bit vectors only, so that no 256-bit register is left dirty for the
// baseline SSE code that runs after it); the variant is chosen once at run time from the CPU.
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
#pragma GCC target("fma,prefer-vector-width=128")
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

bool fma_chosen(Variant v) { return v == Variant::fma || (v == Variant::automatic && use_fma()); }

#if PENDAVG_FAST_HAS_FMA_VARIANT
/// Runs a call of the fma body and clears the upper halves of the AVX registers after it. With
/// 256-bit moves in the body (before prefer-vector-width=128) they were left dirty, and every
/// later SSE instruction of the baseline code paid for it (measured: the uncertified double
/// call 5-8x slower after a certified one); kept as a guard. VZEROUPPER keeps the 128-bit
/// halves, so baseline code sees no change; only executed on CPUs with FMA (hence AVX).
template <class F>
auto clean_after(F&& call) {
  auto out = call();
  __asm__ __volatile__("vzeroupper" ::: "memory");
  return out;
}
#endif

std::optional<FastResult> fast_double_average(const Chain<double>& chain, double beta,
                                              Variant variant) {
#if PENDAVG_FAST_HAS_FMA_VARIANT
  if (fma_chosen(variant)) return clean_after([&] { return fused::run(chain, beta); });
#else
  if (variant == Variant::fma) return std::nullopt;
#endif
  return baseline::run(chain, beta);
}

std::optional<std::vector<Enclosure>> fast_double_bessel(double a, std::size_t count,
                                                         Variant variant) {
#if PENDAVG_FAST_HAS_FMA_VARIANT
  if (fma_chosen(variant)) return clean_after([&] { return fused::bessel_part(a, count); });
#else
  if (variant == Variant::fma) return std::nullopt;
#endif
  return baseline::bessel_part(a, count);
}

std::optional<std::array<std::vector<Enclosure>, 3>> fast_double_moments(double m1, double m2,
                                                                         std::size_t K,
                                                                         Variant variant) {
#if PENDAVG_FAST_HAS_FMA_VARIANT
  if (fma_chosen(variant)) return clean_after([&] { return fused::moments_part(m1, m2, K); });
#else
  if (variant == Variant::fma) return std::nullopt;
#endif
  return baseline::moments_part(m1, m2, K);
}

bool fast_double_has_fma() { return use_fma(); }

const char* fast_double_variant() { return use_fma() ? "fma" : "baseline"; }

int fast_double_last_refusal() {
#if PENDAVG_FAST_HAS_FMA_VARIANT
  if (use_fma()) return fused::last_refusal_line;
#endif
  return baseline::last_refusal_line;
}

}  // namespace pendavg::certified_fast

#endif  // PENDAVG_HAS_ARB
