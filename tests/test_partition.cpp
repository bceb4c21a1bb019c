// SPDX-License-Identifier: GPL-3.0-or-later
// tests/test_partition.cpp -- what the CLI's MPI layer relies on in the library (issue 14):
// one qmc average split between cooperating parts (pendavg::ShiftPartition) gives the bits of the
// undivided run for any number of parts, and check_average refuses, without computing, exactly
// what average would refuse.
#include <catch2/catch.hpp>

#include "pendavg/mpfr.hpp"
#include "pendavg/pendavg.hpp"

#include <barrier>
#include <cstring>
#include <functional>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace {

using pendavg::AverageMethod;
using pendavg::AverageOptions;
using pendavg::Averages;
using pendavg::Chain;

/// P parts in one process: part p of a Team runs on its own thread; all_gather meets the others
/// at a barrier (as MPI_Allgatherv does across ranks).
class Team {
 public:
  explicit Team(int parts) : parts_(parts), locals_(static_cast<std::size_t>(parts)), sync_(parts) {}

  class Part final : public pendavg::ShiftPartition {
   public:
    Part(Team& team, int part) : team_(team), part_(part) {}
    int part() const override { return part_; }
    int parts() const override { return team_.parts_; }
    std::vector<double> all_gather(std::span<const double> local) const override {
      team_.locals_[static_cast<std::size_t>(part_)].assign(local.begin(), local.end());
      team_.sync_.arrive_and_wait();
      std::vector<double> all;
      for (const auto& block : team_.locals_) all.insert(all.end(), block.begin(), block.end());
      team_.sync_.arrive_and_wait();  // nobody overwrites a block before everyone has read it
      return all;
    }

   private:
    Team& team_;
    int part_;
  };

 private:
  int parts_;
  std::vector<std::vector<double>> locals_;
  std::barrier<> sync_;
};

bool same_bits(const Averages<double>& a, const Averages<double>& b) {
  const auto same = [](const std::vector<pendavg::Estimate<double>>& x,
                       const std::vector<pendavg::Estimate<double>>& y) {
    if (x.size() != y.size()) return false;
    for (std::size_t i = 0; i < x.size(); ++i)
      if (std::memcmp(&x[i].value, &y[i].value, sizeof(double)) != 0 ||
          std::memcmp(&x[i].error, &y[i].error, sizeof(double)) != 0)
        return false;
    return true;
  };
  return same(a.beta_kinetic, b.beta_kinetic) && same(a.cos_angle, b.cos_angle) &&
         same(a.beta2_kinetic_variance, b.beta2_kinetic_variance) &&
         a.evaluations == b.evaluations &&
         a.qmc->effective_sample_fraction == b.qmc->effective_sample_fraction;
}

/// Every part's result of one qmc average split `parts` ways.
std::vector<Averages<double>> split_run(const Chain<double>& chain, double beta,
                                        AverageOptions options, int parts) {
  Team team(parts);
  std::vector<Averages<double>> results(static_cast<std::size_t>(parts));
  std::vector<std::thread> threads;
  for (int p = 0; p < parts; ++p)
    threads.emplace_back([&, p] {
      const Team::Part part(team, p);
      AverageOptions mine = options;
      mine.partition = &part;
      results[static_cast<std::size_t>(p)] = pendavg::average(chain, beta, mine);
    });
  for (std::thread& t : threads) t.join();
  return results;
}

}  // namespace

TEST_CASE("partition: a qmc average split between parts gives the undivided bits", "[api][partition]") {
  const Chain<double> chain({1, 2, 1, 0.5, 1, 3}, {1, 0.5, 1, 2, 1, 1}, 1);
  AverageOptions options;
  options.method = AverageMethod::qmc;
  options.samples = 1024;
  options.shifts = 7;  // not a multiple of the part counts: unequal parts
  options.seed = 11;
  for (const double beta : {0.3, 2.0, 1e9}) {  // 1e9: the low-temperature extrapolation (3 runs)
    const Averages<double> whole = pendavg::average(chain, beta, options);
    for (const int parts : {1, 2, 3, 5, 7}) {
      for (const Averages<double>& part : split_run(chain, beta, options, parts)) {
        INFO("beta = " << beta << ", parts = " << parts);
        CHECK(same_bits(part, whole));
      }
    }
  }
}

TEST_CASE("partition: the threads inside a part do not change the bits", "[api][partition]") {
  const Chain<double> chain({1, 1, 1, 1, 1, 1, 1, 1}, {1, 1, 1, 1, 1, 1, 1, 1}, 1);
  AverageOptions options;
  options.method = AverageMethod::qmc;
  options.samples = 1024;
  options.shifts = 8;
  const Averages<double> whole = pendavg::average(chain, 1.0, options);
  options.threads = 3;
  for (const Averages<double>& part : split_run(chain, 1.0, options, 2)) CHECK(same_bits(part, whole));
}

TEST_CASE("check_average refuses what average refuses, before any work", "[api][partition]") {
  const auto refusal = [](const std::function<void()>& call) -> std::string {
    try {
      call();
    } catch (const pendavg::invalid_input& bad) {
      return bad.what();
    }
    return "";
  };
  struct Case {
    std::vector<double> masses, lengths;
    double g, beta;
    AverageMethod method;
  };
  const std::vector<Case> cases{
      {{0.5, 0.5}, {1, 1}, 1, 1e300, AverageMethod::automatic},     // N = 2 double range
      {{0.5, 0.5}, {1, 1}, 1, 1e300, AverageMethod::series},
      {{1, 1, 1}, {1, 1e-12, 1}, 1, 1e15, AverageMethod::automatic},  // a soft joint and a stiff one
      {{1, 1, 1, 1, 1}, {1, 1, 1, 1, 1}, 1, 1e20, AverageMethod::qmc},
      {{0.5, 0.5}, {1, 1}, 1, 1, AverageMethod::torus_trapezoid},
      {{0.5, 0.5}, {1, 1}, 1, 2, AverageMethod::automatic},
      {{1, 2, 3}, {1, 1, 1}, 9.81, 0.1, AverageMethod::automatic},
  };
  for (const Case& c : cases) {
    const Chain<double> chain(c.masses, c.lengths, c.g);
    AverageOptions options;
    options.method = c.method;
    if (c.method == AverageMethod::qmc) options.samples = 1024;
    const std::string checked = refusal([&] { pendavg::check_average(chain, c.beta, options); });
    const std::string computed = refusal([&] { pendavg::average(chain, c.beta, options); });
    INFO("N = " << c.masses.size() << ", beta = " << c.beta);
    CHECK(checked == computed);
  }
  SECTION("MPFR: the same, under a working precision") {
    const pendavg::working_precision precision(30 + pendavg::guard_digits);
    const Chain<pendavg::mpfr_real> chain({1, 1, 1}, {1, 1, 1}, 1);
    AverageOptions options;
    options.digits = 30;
    CHECK_THROWS_AS(pendavg::check_average(chain, pendavg::mpfr_real("1e12"), options),
                    pendavg::invalid_input);
    CHECK_NOTHROW(pendavg::check_average(chain, pendavg::mpfr_real(1), options));
    CHECK_THROWS_AS(pendavg::check_average(chain, pendavg::mpfr_real(-1), options),
                    pendavg::invalid_input);
  }
}
