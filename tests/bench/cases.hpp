// SPDX-License-Identifier: GPL-3.0-or-later
// tests/bench/cases.hpp -- the fixed, seeded parameter cases shared by the benchmark programs
// and by tests/bench/cli_cases_bench.sh (through `bench_double_pendulum --write-cases FILE`).
//
// Case i (seed 2026, std::mt19937_64), in this order of draws:
//   beta          log-uniform in [1e-8, 1e8]
//   x             log-uniform in [1e-12, 0.5];  even i: mu1 = x, mu2 = 1 - x
//                                               odd  i: mu2 = x, mu1 = 1 - x
//                 (so mu1 covers [1e-12, 1 - 1e-12]; m1 = mu1, m2 = mu2, M = 1 up to rounding)
//   l2 / l1       log-uniform in [1e-4, 1e4], with l1 = 1
//   g = 1.
// Uniform variates come from the top 53 bits of the generator (not from
// std::uniform_real_distribution), so the cases are identical with every standard library.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

namespace pendavg_bench {

struct Case {
  double beta, g, m1, m2, l1, l2;
};

inline constexpr std::uint64_t case_seed = 2026;
inline constexpr std::size_t case_count = 1000;

/// A uniform double in [0, 1) from the top 53 bits of one draw.
inline double unit_uniform(std::mt19937_64& rng) {
  return static_cast<double>(rng() >> 11) * 0x1.0p-53;
}

/// exp(uniform(log lo, log hi)).
inline double log_uniform(std::mt19937_64& rng, double lo, double hi) {
  const double a = std::log(lo), b = std::log(hi);
  return std::exp(a + (b - a) * unit_uniform(rng));
}

inline std::vector<Case> make_cases(std::size_t count = case_count,
                                    std::uint64_t seed = case_seed) {
  std::mt19937_64 rng(seed);
  std::vector<Case> cases;
  cases.reserve(count);
  for (std::size_t i = 0; i < count; ++i) {
    Case c{};
    c.beta = log_uniform(rng, 1e-8, 1e8);
    const double x = log_uniform(rng, 1e-12, 0.5);
    if (i % 2 == 0) {
      c.m1 = x;
      c.m2 = 1.0 - x;
    } else {
      c.m1 = 1.0 - x;
      c.m2 = x;
    }
    c.g = 1.0;
    c.l1 = 1.0;
    c.l2 = log_uniform(rng, 1e-4, 1e4);
    cases.push_back(c);
  }
  return cases;
}

/// One case as "beta=... g=... m1=... m2=... l1=... l2=..." (%.17g, round-trips).
inline std::string describe(const Case& c) {
  char buffer[256];
  std::snprintf(buffer, sizeof buffer, "beta=%.17g g=%.17g m1=%.17g m2=%.17g l1=%.17g l2=%.17g",
                c.beta, c.g, c.m1, c.m2, c.l1, c.l2);
  return buffer;
}

/// The cases as a CSV text: header beta,g,m1,m2,l1,l2, values with %.17g, the whole list
/// repeated `replicate` times (for CLI throughput runs: data row r is case r % count), or with
/// `grouped` each case `replicate` times in a row (row r is case r / replicate: the repeated
/// calls of the library benchmarks, warm caches).
inline std::string cases_csv(const std::vector<Case>& cases, std::size_t replicate = 1,
                             bool grouped = false) {
  std::string out = "beta,g,m1,m2,l1,l2\n";
  out.reserve(out.size() + cases.size() * replicate * 120);
  char line[256];
  const std::size_t rows = cases.size() * replicate;
  for (std::size_t r = 0; r < rows; ++r) {
    const Case& c = cases[grouped ? r / replicate : r % cases.size()];
    std::snprintf(line, sizeof line, "%.17g,%.17g,%.17g,%.17g,%.17g,%.17g\n", c.beta, c.g, c.m1,
                  c.m2, c.l1, c.l2);
    out += line;
  }
  return out;
}

/// Writes cases_csv(cases, replicate, grouped) to `path`; throws std::runtime_error on failure.
inline void write_cases_csv(const std::string& path, const std::vector<Case>& cases,
                            std::size_t replicate = 1, bool grouped = false) {
  const std::string text = cases_csv(cases, replicate, grouped);
  std::FILE* file = std::fopen(path.c_str(), "wb");
  if (!file) throw std::runtime_error("cannot open " + path + " for writing");
  const bool ok = std::fwrite(text.data(), 1, text.size(), file) == text.size();
  if (std::fclose(file) != 0 || !ok) throw std::runtime_error("cannot write " + path);
}

}  // namespace pendavg_bench
