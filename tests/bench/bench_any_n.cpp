// SPDX-License-Identifier: GPL-3.0-or-later
// Any-N targets (issue 3), measured with Google Benchmark:
//  * the torus trapezoid for N = 3 to 1e-13 and N = 4 to 1e-11 (unit chain, beta = 1);
//  * the O(N) per-node traces for N = 8 .. 4096: ns per node (fit the exponent from the
//    reported per_node_ns counters: log(t) against log(N));
//  * randomized lattice QMC (issue 3 target: a bar <= 1e-4 on every beta<K_i> in <= 10 s on 2
//    threads for N = 16 and N = 64 at beta = 1, unit chain, g = 1):
//      BM_qmc_to_target/N/beta*10: doubles the points per shift from 2^12 (16 shifts) until the
//        largest bar over the beta<K_i> (the default multiplier, qmc_default_sigmas) is <= 1e-4;
//        the time is that of the whole ladder
//        (every smaller run included), counters: points per shift needed, the bar, the
//        effective sample fraction;
//      BM_qmc_fixed/N/log2(points)/proposal: one run (proposal 0 = pivot_sequential, 1 =
//        von_mises) for the efficiency comparison.
//    Run: build/tests/bench_any_n --benchmark_filter=qmc --benchmark_repetitions=3
#include <benchmark/benchmark.h>

#include "pendavg/chain.hpp"
#include "engine/qmc/qmc.hpp"
#include "engine/torus/torus.hpp"
#include "pendavg/trace_formula.hpp"

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

namespace {

pendavg::Chain<double> unit_chain(std::size_t n) {
  return pendavg::Chain<double>(std::vector<double>(n, 1.0), std::vector<double>(n, 1.0), 1.0);
}

void BM_torus_trapezoid(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  const double tol = n == 3 ? 1e-13 : 1e-11;
  const auto chain = unit_chain(n);
  pendavg::TorusOptions options;
  options.tolerance = tol;
  pendavg::Averages<double> r;
  for (auto _ : state) {
    r = pendavg::torus_average(chain, 1.0, options);
    benchmark::DoNotOptimize(r.beta_kinetic.data());
  }
  state.counters["tolerance"] = tol;
  state.counters["nodes"] = static_cast<double>(r.evaluations);
  state.counters["error_K1"] = r.beta_kinetic[0].error;
  state.counters["converged"] = r.converged;
}
BENCHMARK(BM_torus_trapezoid)->Arg(3)->Arg(4)->Unit(benchmark::kMillisecond);

void BM_node_traces(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  const auto chain = unit_chain(n);
  pendavg::TraceWorkspace<double> ws(chain);
  // 64 random configurations, cycled, so the angles change from node to node.
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> angle(0.0, 2 * M_PI);
  std::vector<std::vector<double>> deltas(64, std::vector<double>(n > 1 ? n - 1 : 1));
  for (auto& d : deltas)
    for (auto& x : d) x = angle(rng);
  std::size_t i = 0;
  for (auto _ : state) {
    const auto& t = pendavg::node_traces_relative(chain, deltas[i++ & 63].data(), ws);
    benchmark::DoNotOptimize(t.trace_X.data());
  }
  state.counters["N"] = static_cast<double>(n);
  state.counters["per_particle_ns"] =
      benchmark::Counter(static_cast<double>(state.iterations() * n),
                         benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_node_traces)->RangeMultiplier(8)->Range(8, 4096);

double largest_bar(const pendavg::Averages<double>& r) {
  double bar = 0;
  for (const pendavg::Estimate<double>& k : r.beta_kinetic) bar = std::max(bar, k.error);
  return bar;
}

void BM_qmc_to_target(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  const double beta = static_cast<double>(state.range(1)) / 10;
  const auto chain = unit_chain(n);
  pendavg::QmcOptions options;
  options.shifts = 16;
  options.seed = 1;
  options.threads = 2;
  pendavg::Averages<double> r;
  std::size_t points = 0;
  for (auto _ : state) {
    for (points = std::size_t(1) << 12; points <= (std::size_t(1) << 20); points *= 2) {
      options.points = points;
      r = pendavg::qmc_average(chain, beta, options);
      if (largest_bar(r) <= 1e-4) break;
    }
    benchmark::DoNotOptimize(r.beta_kinetic.data());
  }
  state.counters["N"] = static_cast<double>(n);
  state.counters["beta"] = beta;
  state.counters["points_per_shift"] = static_cast<double>(std::min(points, std::size_t(1) << 20));
  state.counters["max_bar"] = largest_bar(r);
  state.counters["error_K1"] = r.beta_kinetic[0].error;
  state.counters["effective_fraction"] = r.qmc->effective_sample_fraction;
}
BENCHMARK(BM_qmc_to_target)
    ->Args({8, 10})
    ->Args({16, 10})
    ->Args({32, 10})
    ->Args({64, 10})
    ->Args({16, 1})
    ->Args({16, 100})
    ->Unit(benchmark::kSecond)
    ->Iterations(1)
    ->UseRealTime();

void BM_qmc_fixed(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  const auto chain = unit_chain(n);
  pendavg::QmcOptions options;
  options.points = std::size_t(1) << state.range(1);
  options.shifts = 16;
  options.seed = 1;
  options.threads = 2;
  options.proposal = state.range(2) == 0 ? pendavg::QmcProposal::pivot_sequential
                                         : pendavg::QmcProposal::von_mises;
  pendavg::Averages<double> r;
  for (auto _ : state) {
    r = pendavg::qmc_average(chain, 1.0, options);
    benchmark::DoNotOptimize(r.beta_kinetic.data());
  }
  state.counters["N"] = static_cast<double>(n);
  state.counters["max_bar"] = largest_bar(r);
  state.counters["effective_fraction"] = r.qmc->effective_sample_fraction;
  state.counters["per_particle_point_ns"] =
      benchmark::Counter(static_cast<double>(state.iterations() * n * options.points * 16),
                         benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_qmc_fixed)
    ->Args({16, 14, 0})
    ->Args({16, 14, 1})
    ->Args({64, 14, 0})
    ->Args({64, 14, 1})
    ->Unit(benchmark::kSecond)
    ->Iterations(1)
    ->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
