// SPDX-License-Identifier: GPL-3.0-or-later
// Dynamics targets (issue 4), measured with Google Benchmark:
//  * the cost of one Yoshida-4 (and Yoshida-6) RATTLE step for N = 2 .. 1024 (unit chain, the
//    paper's start phi_i = pi/2 at rest, after a 2000-step warm-up): time per step (and per
//    particle) -- fit the exponent of t(N) from the CPU times;
//  * the same for the other compositions and for the constrained BAOAB Langevin step (N = 16);
//  * the paper's full run, N = 16, T = 1e4, dt = 1e-3 (1e7 steps, one thread), with its time
//    averages, energy error and constraint residual as counters:
//      bench_dynamics --benchmark_filter=paper_run
//    (one iteration each; N = 7 as well; /16/4 = yoshida6, the default, /16/1 = the paper's
//    yoshida4, /16/3 = kahan_li6).
#include <benchmark/benchmark.h>

#include "pendavg/dynamics.hpp"

#include <cmath>
#include <numbers>
#include <random>
#include <vector>

namespace {

pendavg::Chain<double> unit_chain(std::size_t n) {
  return pendavg::Chain<double>(std::vector<double>(n, 1.0), std::vector<double>(n, 1.0), 1.0);
}

pendavg::ChainState<double> paper_start(const pendavg::Chain<double>& chain) {
  const std::size_t n = chain.size();
  return pendavg::state_from_angles(chain, std::vector<double>(n, std::numbers::pi / 2),
                                    std::vector<double>(n, 0.0));
}

void BM_step(benchmark::State& state, pendavg::Integrator integrator) {
  const auto n = static_cast<std::size_t>(state.range(0));
  const auto chain = unit_chain(n);
  auto s = paper_start(chain);
  pendavg::DynamicsWorkspace<double> ws(chain);
  for (int k = 0; k < 2000; ++k) pendavg::composition_step(chain, s, 1e-3, integrator, ws);
  for (auto _ : state) {
    pendavg::composition_step(chain, s, 1e-3, integrator, ws);
    benchmark::DoNotOptimize(s.position.data());
  }
  // Seconds per step and particle (printed with an SI prefix, e.g. 60n = 60 ns).
  state.counters["per_particle"] = benchmark::Counter(
      static_cast<double>(n), benchmark::Counter::kIsIterationInvariantRate |
                                  benchmark::Counter::kInvert);
  state.counters["solves_per_stage"] =
      static_cast<double>(ws.newton_solves) / static_cast<double>(ws.position_stages);
}
BENCHMARK_CAPTURE(BM_step, yoshida4, pendavg::Integrator::yoshida4)
    ->RangeMultiplier(2)->Range(2, 1024)->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_step, rattle2, pendavg::Integrator::rattle2)->Arg(16)->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_step, suzuki4, pendavg::Integrator::suzuki4)->Arg(16)->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_step, kahan_li6, pendavg::Integrator::kahan_li6)->Arg(16)->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_step, yoshida6, pendavg::Integrator::yoshida6)
    ->RangeMultiplier(2)->Range(2, 1024)->Unit(benchmark::kMicrosecond);

void BM_langevin_step(benchmark::State& state) {
  const auto chain = unit_chain(16);
  auto s = paper_start(chain);
  pendavg::DynamicsWorkspace<double> ws(chain);
  std::mt19937_64 rng(1);
  for (auto _ : state) {
    pendavg::baoab_step(chain, s, 1e-3, 1.0, 1.0, rng, ws);
    benchmark::DoNotOptimize(s.position.data());
  }
}
BENCHMARK(BM_langevin_step)->Unit(benchmark::kMicrosecond);

/// The paper's run with the time averages (simulate), one iteration.
void BM_paper_run(benchmark::State& state) {
  const auto n = static_cast<std::size_t>(state.range(0));
  const auto chain = unit_chain(n);
  pendavg::SimulationOptions options;
  options.duration = 1e4;
  options.integrator = static_cast<pendavg::Integrator>(state.range(1));
  pendavg::SimulationResult<double> r;
  for (auto _ : state) {
    r = pendavg::simulate(chain, paper_start(chain), options);
    benchmark::DoNotOptimize(r.kinetic.data());
  }
  state.counters["steps"] = static_cast<double>(r.steps);
  state.counters["energy_error_max"] = r.energy_error_max;
  state.counters["energy_error_rms"] = r.energy_error_rms;
  state.counters["energy_drift"] = r.energy_drift;
  state.counters["constraint_residual"] = r.constraint_residual;
  state.counters["K1"] = r.kinetic.front().value;
  state.counters["K1_error"] = r.kinetic.front().error;
  state.counters["KN"] = r.kinetic.back().value;
  state.counters["KN_error"] = r.kinetic.back().error;
}
BENCHMARK(BM_paper_run)
    ->Args({16, static_cast<int>(pendavg::Integrator::yoshida6)})
    ->Args({7, static_cast<int>(pendavg::Integrator::yoshida6)})
    ->Args({16, static_cast<int>(pendavg::Integrator::yoshida4)})
    ->Args({7, static_cast<int>(pendavg::Integrator::yoshida4)})
    ->Args({16, static_cast<int>(pendavg::Integrator::kahan_li6)})
    ->Iterations(1)
    ->Unit(benchmark::kSecond);

}  // namespace

BENCHMARK_MAIN();
