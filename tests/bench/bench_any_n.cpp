// Any-N targets (issue 3), measured with Google Benchmark:
//  * the torus trapezoid for N = 3 to 1e-13 and N = 4 to 1e-11 (unit chain, beta = 1);
//  * the O(N) per-node traces for N = 8 .. 4096: ns per node (fit the exponent from the
//    reported per_node_ns counters: log(t) against log(N));
//  * randomized lattice QMC for N = 16 and N = 64 at beta = 1 on 2 threads: the error bar on
//    beta<K_1> reached (counter error_K1) and the time.
#include <benchmark/benchmark.h>

#include "pendavg/chain.hpp"
#include "pendavg/torus.hpp"
#include "pendavg/trace_formula.hpp"

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
  state.counters["error_K1"] = r.beta_kinetic_error[0];
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

void BM_qmc(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  const auto chain = unit_chain(n);
  pendavg::QmcOptions options;
  options.points = std::size_t(1) << 16;
  options.shifts = 16;
  options.seed = 1;
  options.threads = 2;
  pendavg::QmcAverages<double> r;
  for (auto _ : state) {
    r = pendavg::qmc_average(chain, 1.0, options);
    benchmark::DoNotOptimize(r.averages.beta_kinetic.data());
  }
  state.counters["N"] = static_cast<double>(n);
  state.counters["error_K1"] = r.averages.beta_kinetic_error[0];
  state.counters["error_KN"] = r.averages.beta_kinetic_error.back();
  state.counters["effective_fraction"] = r.effective_sample_fraction;
}
BENCHMARK(BM_qmc)->Arg(16)->Arg(32)->Unit(benchmark::kSecond)->Iterations(1);

}  // namespace

BENCHMARK_MAIN();
