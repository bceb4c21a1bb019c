// SPDX-License-Identifier: GPL-3.0-or-later
// tests/bench/bench_print.cpp -- what printing an `average --cases` row costs beside computing
// it: the 1000 seeded N = 2 cases (cases.hpp) in double, each computed once, then timed
//   BM_compute   pendavg::average alone (the row's computation),
//   BM_print     the row's record filled (every value's shortest text and printing gap) and
//                its CSV cells written: every column (arg 0) or the seven of pendavg 0.2
//                (beta_K, beta_K_error, ratio, cos_phi, method, evaluations; arg 1),
// per case, in a loop over the cases (the time is per row).
//   build/tests/bench_print --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include "cases.hpp"

#include "io/record.hpp"
#include "io/results.hpp"
#include "pendavg/average.hpp"

#include <benchmark/benchmark.h>

#include <string>
#include <vector>

namespace {

using pendavg::Averages;
using pendavg::Chain;

struct Rows {
  std::vector<Chain<double>> chains;
  std::vector<double> betas;
  std::vector<Averages<double>> averages;
};

const Rows& rows() {
  static const Rows r = [] {
    Rows out;
    for (const pendavg_bench::Case& c : pendavg_bench::make_cases()) {
      out.chains.emplace_back(std::vector<double>{c.m1, c.m2}, std::vector<double>{c.l1, c.l2},
                              c.g);
      out.betas.push_back(c.beta);
      out.averages.push_back(pendavg::average(out.chains.back(), c.beta));
    }
    return out;
  }();
  return r;
}

void BM_compute(benchmark::State& state) {
  const Rows& r = rows();
  pendavg::AverageWorkspace<double> workspace;
  std::size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(pendavg::average(r.chains[i], r.betas[i], {}, workspace));
    i = (i + 1) % r.chains.size();
  }
}
BENCHMARK(BM_compute);

void BM_print(benchmark::State& state) {
  const Rows& r = rows();
  const std::vector<std::string> names = pendavg::io::column_names(pendavg::io::averages_fields(), 2);
  std::vector<std::size_t> chosen;
  if (state.range(0) == 1) {
    std::vector<std::string> headers;
    chosen = pendavg::io::select_columns("beta_K,beta_K_error,ratio,cos_phi,method,evaluations",
                                         names, {"beta", "g", "m1", "m2", "l1", "l2"}, 2, headers);
  } else {
    for (std::size_t k = 0; k < names.size(); ++k) chosen.push_back(k);
  }
  pendavg::io::Record record;
  std::string line;
  std::size_t i = 0;
  for (auto _ : state) {
    line.clear();
    record.reset(pendavg::io::averages_fields(), 2);
    pendavg::io::append_averages(record, r.averages[i], &r.betas[i], pendavg::io::Printing{16});
    pendavg::io::append_csv_cells(line, record, chosen);
    benchmark::DoNotOptimize(line.data());
    i = (i + 1) % r.averages.size();
  }
}
BENCHMARK(BM_print)->Arg(0)->Arg(1);

}  // namespace

BENCHMARK_MAIN();
