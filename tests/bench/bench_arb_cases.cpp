// SPDX-License-Identifier: GPL-3.0-or-later
// tests/bench/bench_arb_cases.cpp -- pendavg's double pendulum (N = 2) against Arb's rigorous
// integrator on five fixed cases, in double, at 38 and at 77 digits (issue 30).
//
// The cases (l1 = l2 = 1, g = 1, total mass M = m1 + m2 = 1 up to rounding):
//   A  mu1 = 0.5   beta = 1        D  mu1 = 0.5   beta = 100
//   B  mu1 = 0.05  beta = 1        E  mu1 = 0.5   beta = 1000
//   C  mu1 = 1e-4  beta = 1
// Each case is the doubles m1 = mu1 and m2 = double(1 - mu1); pendavg and Arb both start from
// exactly these doubles (Arb forms mu_i = m_i / (m1 + m2) in ball arithmetic).
//
// pendavg: pendavg::average (automatic method: the reduced integral) with an AverageWorkspace
// kept across calls, at digits 16 (double), 38 and 77 (mpfr_real); all observables. Certified:
// the same call with AverageOptions::certified (every observable an enclosure; in double the
// double-word fast path of src/engine/certified.md Sec. 10, at 38 and 77 digits Arb's balls).
// Arb (when built with Debian's libflint-arb-dev; PENDAVG_BENCH_HAS_ARB): acb_calc_integrate of
// the two integrals behind beta<K_1> = (mu1/2) J_{-1/2} / J_{1/2},
//   J_s = int_0^pi q(t)^s e^{-A} I_0(R(t)) dt,  q = mu1 + mu2 sin^2 t,  A = a1 + a2,
//   R^2 = A^2 - 4 a1 a2 sin^2(t/2),  a1 = beta M g l1,  a2 = beta m2 g l2
// (the reduced integral of engine/double_pendulum/integral.cpp unfolded to [0, pi]), with
// e^{-A} I_0(R) = e^{R - A} [e^{-R} I_0(R)] and R - A = -4 a1 a2 sin^2(t/2) / (R + A). Only the
// kinetic pair: Arb is given the least work pendavg's five integrals include. Precision: goal
// g = ceil(digits log2 10) + 4 bits relative (53 bits for double), working precision g + 32
// bits, absolute tolerance 2^-g times |J| (|J| from a coarse Arb run before the timing), default
// acb_calc_integrate options.
//
// Runs:
//   bench_arb_cases                       Google Benchmark: BM_pendavg/<case>/<digits>,
//                                         BM_certified/<case>/<digits>,
//                                         BM_arb/<case>/<digits> (add e.g.
//                                         --benchmark_repetitions=5
//                                         --benchmark_enable_random_interleaving=true).
//   bench_arb_cases --table [ROUNDS]      side by side in one run: per case and digits, ROUNDS
//                                         (default 7) rounds each timing a block of pendavg calls,
//                                         a block of certified pendavg calls (--certified,
//                                         src/engine/certified.md) and a block of Arb calls
//                                         (thread CPU time, blocks of ~20 ms); prints the medians
//                                         (us), certified/pendavg, Arb/certified, Arb/pendavg
//                                         (uncertified; issue 30's item 5), and the check
//                                         of both pendavg beta<K_1> against Arb's ball.
//   bench_arb_cases --check               only the check: pendavg's beta<K_1> must lie in Arb's
//                                         ball widened by pendavg's own error; exit status 1 if
//                                         not.
#include <benchmark/benchmark.h>

#include "pendavg/average.hpp"
#include "pendavg/mpfr.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <string>
#include <vector>

#ifdef PENDAVG_BENCH_HAS_ARB
#include "arb_oracle.hpp"
#endif

namespace {

using pendavg::mpfr_real;

struct NamedCase {
  const char* name;
  double mu1, beta;
  double m1() const { return mu1; }
  double m2() const { return 1.0 - mu1; }  // rounded to double: both engines use this double
};

constexpr NamedCase named_cases[] = {
    {"A", 0.5, 1.0}, {"B", 0.05, 1.0}, {"C", 1e-4, 1.0}, {"D", 0.5, 100.0}, {"E", 0.5, 1000.0}};
constexpr int digit_levels[] = {16, 38, 77};

double thread_cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

double median_of(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// ---------------------------------------------------------------- pendavg

/// One pendavg call of a case at `digits`, ready to repeat (inputs built once, workspace kept).
class PendavgCall {
 public:
  PendavgCall(const NamedCase& c, int digits, bool certified = false) : digits_(digits) {
    options_.digits = digits;
    options_.certified = certified;
    if (digits == 16) {
      chain_d_.emplace_back(std::vector<double>{c.m1(), c.m2()}, std::vector<double>{1.0, 1.0},
                            1.0);
      beta_d_ = c.beta;
    } else {
      pendavg::working_precision wp(digits + pendavg::guard_digits);
      chain_m_.emplace_back(std::vector<mpfr_real>{mpfr_real(c.m1()), mpfr_real(c.m2())},
                            std::vector<mpfr_real>{mpfr_real(1), mpfr_real(1)}, mpfr_real(1));
      beta_m_ = mpfr_real(c.beta);
    }
  }
  /// beta<K_1> and its error as decimal strings (for the check), after one call.
  void run(std::string* k1 = nullptr, std::string* k1_error = nullptr) {
    if (digits_ == 16) {
      auto r = pendavg::average(chain_d_[0], beta_d_, options_, ws_d_);
      benchmark::DoNotOptimize(r);
      if (k1) *k1 = format_double(r.beta_kinetic[0].value);
      if (k1_error) *k1_error = format_double(r.beta_kinetic[0].error);
    } else {
      auto r = pendavg::average(chain_m_[0], beta_m_, options_, ws_m_);
      benchmark::DoNotOptimize(r);
      if (k1) *k1 = r.beta_kinetic[0].value.str(digits_ + pendavg::guard_digits);
      if (k1_error) *k1_error = r.beta_kinetic[0].error.str(6);
    }
  }

 private:
  static std::string format_double(double x) {
    char buffer[64];
    std::snprintf(buffer, sizeof buffer, "%.17g", x);
    return buffer;
  }
  int digits_;
  pendavg::AverageOptions options_;
  std::vector<pendavg::Chain<double>> chain_d_;
  std::vector<pendavg::Chain<mpfr_real>> chain_m_;
  double beta_d_ = 0;
  mpfr_real beta_m_;
  pendavg::AverageWorkspace<double> ws_d_;
  pendavg::AverageWorkspace<mpfr_real> ws_m_;
};

// ---------------------------------------------------------------- Arb

#ifdef PENDAVG_BENCH_HAS_ARB

using pendavg_test::arb_integrand;
using pendavg_test::ArbIntegrand;

/// Arb's beta<K_1> for one case at `digits` (16: a 53-bit goal), ready to repeat.
class ArbCall {
 public:
  ArbCall(const NamedCase& c, int digits) {
    goal_ = digits == 16 ? 53 : static_cast<slong>(std::ceil(digits * 3.321928094887362)) + 4;
    prec_ = goal_ + 32;
    f_.set(c.m1(), c.m2(), 1.0, 1.0, 1.0, c.beta, prec_);
    acb_init(a_);
    acb_init(b_);
    acb_zero(a_);
    acb_const_pi(b_, prec_);
    arb_init(k1_);
    acb_init(j_half_);
    acb_init(j_minus_half_);
    acb_calc_integrate_opt_init(options_);
    // |J| from a coarse run (not timed): the absolute tolerance 2^-goal |J| keeps the goal
    // relative (the integrals are positive).
    for (int sign : {1, -1}) {
      f_.twice_s = sign;
      acb_t rough;
      acb_init(rough);
      mag_t tol;
      mag_init(tol);
      mag_set_ui_2exp_si(tol, 1, -20);
      acb_calc_integrate(rough, arb_integrand, &f_, a_, b_, 20, tol, options_, 64);
      mag_init(sign > 0 ? tol_half_ : tol_minus_half_);
      arb_get_mag_lower(sign > 0 ? tol_half_ : tol_minus_half_, acb_realref(rough));
      mag_mul_2exp_si(sign > 0 ? tol_half_ : tol_minus_half_,
                      sign > 0 ? tol_half_ : tol_minus_half_, -goal_);
      acb_clear(rough);
      mag_clear(tol);
    }
  }
  ~ArbCall() {
    acb_clear(a_);
    acb_clear(b_);
    arb_clear(k1_);
    acb_clear(j_half_);
    acb_clear(j_minus_half_);
    mag_clear(tol_half_);
    mag_clear(tol_minus_half_);
  }
  ArbCall(const ArbCall&) = delete;
  ArbCall& operator=(const ArbCall&) = delete;
  void run() {
    f_.twice_s = 1;
    acb_calc_integrate(j_half_, arb_integrand, &f_, a_, b_, goal_, tol_half_, options_, prec_);
    f_.twice_s = -1;
    acb_calc_integrate(j_minus_half_, arb_integrand, &f_, a_, b_, goal_, tol_minus_half_,
                       options_, prec_);
    arb_div(k1_, acb_realref(j_minus_half_), acb_realref(j_half_), prec_);
    arb_mul(k1_, k1_, f_.mu1, prec_);
    arb_mul_2exp_si(k1_, k1_, -1);
  }
  const arb_struct* k1() const { return k1_; }
  slong prec() const { return prec_; }

 private:
  ArbIntegrand f_;
  slong goal_ = 0, prec_ = 0;
  acb_t a_, b_, j_half_, j_minus_half_;
  arb_t k1_;
  mag_t tol_half_, tol_minus_half_;
  acb_calc_integrate_opt_t options_;
};

/// Whether pendavg's beta<K_1> (decimal, with its error) lies in Arb's ball; prints the digits
/// on which they agree.
bool check_against_arb(const NamedCase& c, int digits, const std::string& k1,
                       const std::string& k1_error, const ArbCall& arb) {
  const slong prec = arb.prec() + 64;
  arb_t x, e, d;
  arb_init(x);
  arb_init(e);
  arb_init(d);
  arb_set_str(x, k1.c_str(), prec);
  arb_set_str(e, k1_error.c_str(), prec);
  // Consistent unless |x - ball| lies wholly above pendavg's error plus the decimal rounding
  // of x (10^-(digits + guard) |x|).
  arb_sub(d, x, arb.k1(), prec);
  arb_abs(d, d);
  arb_t allowance;
  arb_init(allowance);
  arb_set_ui(allowance, 10);
  arb_pow_ui(allowance, allowance, static_cast<ulong>(digits + pendavg::guard_digits), prec);
  arb_div(allowance, x, allowance, prec);
  arb_abs(allowance, allowance);
  arb_abs(e, e);
  arb_add(allowance, allowance, e, prec);
  const bool ok = !arb_gt(d, allowance);
  const double diff = arf_get_d(arb_midref(d), ARF_RND_NEAR);
  const double value = arf_get_d(arb_midref(arb.k1()), ARF_RND_NEAR);
  const double radius = mag_get_d(arb_radref(arb.k1()));
  std::printf("check %s %2d: pendavg beta<K1> = %s (error %s), Arb radius %.2e, "
              "|pendavg - Arb| = %.2e (%.1f digits) %s\n",
              c.name, digits, k1.substr(0, static_cast<std::size_t>(digits) + 3).c_str(),
              k1_error.c_str(), radius, diff, diff > 0 ? -std::log10(diff / value) : 99.0,
              ok ? "ok" : "MISMATCH");
  arb_clear(x);
  arb_clear(e);
  arb_clear(d);
  arb_clear(allowance);
  return ok;
}

#endif  // PENDAVG_BENCH_HAS_ARB

// ---------------------------------------------------------------- Google Benchmark

void BM_pendavg(benchmark::State& state, NamedCase c, int digits) {
  PendavgCall call(c, digits);
  for (auto _ : state) call.run();
}

void BM_certified(benchmark::State& state, NamedCase c, int digits) {
  PendavgCall call(c, digits, true);
  for (auto _ : state) call.run();
}

#ifdef PENDAVG_BENCH_HAS_ARB
void BM_arb(benchmark::State& state, NamedCase c, int digits) {
  ArbCall call(c, digits);
  for (auto _ : state) call.run();
}
#endif

void register_benchmarks() {
  for (const NamedCase& c : named_cases) {
    for (int digits : digit_levels) {
      const std::string suffix = std::string("/") + c.name + "/" + std::to_string(digits);
      benchmark::RegisterBenchmark(("BM_pendavg" + suffix).c_str(), BM_pendavg, c, digits)
          ->Unit(benchmark::kMicrosecond);
      if (pendavg::certified_available())
        benchmark::RegisterBenchmark(("BM_certified" + suffix).c_str(), BM_certified, c, digits)
            ->Unit(benchmark::kMicrosecond);
#ifdef PENDAVG_BENCH_HAS_ARB
      benchmark::RegisterBenchmark(("BM_arb" + suffix).c_str(), BM_arb, c, digits)
          ->Unit(benchmark::kMicrosecond);
#endif
    }
  }
}

// ---------------------------------------------------------------- --table, --check

/// Seconds of thread CPU time per call: a block of calls of about `budget` seconds.
template <class F>
double block_time(F&& call, int reps) {
  const double start = thread_cpu_seconds();
  for (int k = 0; k < reps; ++k) call();
  return (thread_cpu_seconds() - start) / reps;
}

template <class F>
int reps_for(F&& call, double budget) {
  const double one = block_time(call, 1);
  return static_cast<int>(std::clamp(budget / std::max(one, 1e-9), 1.0, 100000.0));
}

int run_table(int rounds, bool timing) {
  int failures = 0;
  const bool certified = pendavg::certified_available();
  if (timing) {
    std::printf("%-4s %6s %12s %12s %12s %10s %10s %10s\n", "case", "digits", "pendavg_us",
                "certified_us", "arb_us", "cert/pend", "arb/cert", "arb/pend");
  }
  for (int digits : digit_levels) {
    for (const NamedCase& c : named_cases) {
      PendavgCall p(c, digits);
      PendavgCall pc(c, digits, certified);
      std::string k1, k1_error, ck1, ck1_error;
      p.run(&k1, &k1_error);
      pc.run(&ck1, &ck1_error);
#ifdef PENDAVG_BENCH_HAS_ARB
      ArbCall a(c, digits);
      a.run();
      if (!check_against_arb(c, digits, k1, k1_error, a)) ++failures;
      if (certified && !check_against_arb(c, digits, ck1, ck1_error, a)) ++failures;
#else
      std::printf("%s %d: beta<K1> = %s (error %s), certified %s (error %s)\n", c.name, digits,
                  k1.c_str(), k1_error.c_str(), ck1.c_str(), ck1_error.c_str());
#endif
      if (!timing) continue;
      const int p_reps = reps_for([&] { p.run(); }, 0.02);
      const int c_reps = reps_for([&] { pc.run(); }, 0.02);
      std::vector<double> tp, tc, ta;
#ifdef PENDAVG_BENCH_HAS_ARB
      const int a_reps = reps_for([&] { a.run(); }, 0.02);
#endif
      for (int r = 0; r < rounds; ++r) {  // alternating blocks
        tp.push_back(block_time([&] { p.run(); }, p_reps));
        tc.push_back(block_time([&] { pc.run(); }, c_reps));
#ifdef PENDAVG_BENCH_HAS_ARB
        ta.push_back(block_time([&] { a.run(); }, a_reps));
#endif
      }
      const double mp = median_of(tp) * 1e6, mc = median_of(tc) * 1e6;
      const double ma = ta.empty() ? 0.0 : median_of(ta) * 1e6;
      std::printf("%-4s %6d %12.2f %12.2f %12.2f %10.2f %10.1f %10.1f\n", c.name, digits, mp,
                  certified ? mc : 0.0, ma, certified ? mc / mp : 0.0,
                  certified && ma > 0 ? ma / mc : 0.0, ma / mp);
      std::fflush(stdout);
    }
  }
  return failures == 0 ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc >= 2 && std::strcmp(argv[1], "--table") == 0) {
    return run_table(argc >= 3 ? std::max(1, std::atoi(argv[2])) : 7, true);
  }
  if (argc >= 2 && std::strcmp(argv[1], "--check") == 0) return run_table(1, false);
  register_benchmarks();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
