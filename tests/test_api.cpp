// SPDX-License-Identifier: GPL-3.0-or-later
// tests/test_api.cpp -- the public API (issue 10): one entry point for any N, options checked
// against the method they select, error kinds, workspaces, and thread safety across precisions.
#include <catch2/catch.hpp>

#include "refusals.hpp"
#include "pendavg/mpfr.hpp"
#include "pendavg/pendavg.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdlib>
#include <mutex>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace {

using pendavg::AverageMethod;
using pendavg::AverageOptions;
using pendavg::Chain;
using pendavg::ErrorKind;
using pendavg::mpfr_real;

AverageOptions with_method(AverageMethod m) {
  AverageOptions o;
  o.method = m;
  return o;
}

/// Every value and error of `a`, in full precision, as one string (for bitwise comparisons).
template <class Real>
std::string fingerprint(const pendavg::Averages<Real>& a) {
  std::ostringstream out;
  out.precision(std::numeric_limits<double>::max_digits10);
  const auto put = [&](const Real& x) {
    if constexpr (std::is_same_v<Real, double>) {
      out << x << ' ';
    } else {
      out << x.str(0, std::ios::scientific) << ' ';
    }
  };
  for (const auto* group : {&a.beta_kinetic, &a.cos_angle, &a.beta2_kinetic_variance}) {
    for (const auto& e : *group) {
      put(e.value);
      put(e.error);
    }
  }
  if (a.ratio) put(a.ratio->value);
  out << pendavg::method_name(a.method) << ' ' << a.evaluations;
  return out.str();
}

}  // namespace

TEST_CASE("api: automatic picks the documented method for every N", "[api]") {
  const AverageOptions automatic;
  CHECK(pendavg::resolve_average_method(1, automatic) == AverageMethod::torus_trapezoid);
  CHECK(pendavg::resolve_average_method(2, automatic) == AverageMethod::integral);
  CHECK(pendavg::resolve_average_method(3, automatic) == AverageMethod::torus_trapezoid);
  CHECK(pendavg::resolve_average_method(4, automatic) == AverageMethod::torus_trapezoid);
  CHECK(pendavg::resolve_average_method(5, automatic) == AverageMethod::transfer);
  CHECK(pendavg::resolve_average_method(256, automatic) == AverageMethod::transfer);
  CHECK(pendavg::resolve_average_method(1024, automatic) == AverageMethod::transfer);
  CHECK(pendavg::resolve_average_method(pendavg::transfer_max_particles, automatic) ==
        AverageMethod::transfer);
  CHECK_THROWS_AS(pendavg::resolve_average_method(pendavg::transfer_max_particles + 1, automatic),
                  pendavg::invalid_input);
  CHECK_THROWS_AS(pendavg::resolve_average_method(257, with_method(AverageMethod::qmc)),
                  pendavg::invalid_input);
  CHECK_THROWS_AS(pendavg::resolve_average_method(0, automatic), pendavg::invalid_input);
  for (const char* name :
       {"auto", "integral", "series", "torus-trapezoid", "torus-gauss", "qmc", "transfer"})
    CHECK(std::string(pendavg::average_method_name(pendavg::parse_average_method(name))) == name);
  CHECK_THROWS_AS(pendavg::parse_average_method("simpson"), pendavg::invalid_input);
}

TEST_CASE("api: an option the chosen method does not use is refused with one line", "[api]") {
  // Refused with one line that names `needle`.
  const auto refused = [](std::size_t n, const AverageOptions& o, const std::string& needle) {
    const std::string message =
        pendavg_test::rejection([&] { pendavg::resolve_average_method(n, o); });
    UNSCOPED_INFO(message);  // shown by the CHECK of the result
    return message.find(needle) != std::string::npos && message.find('\n') == std::string::npos;
  };
  AverageOptions o;
  o.tolerance = 1e-10;
  CHECK(refused(2, o, "tol"));  // the double-pendulum engine has no tolerance to set
  CHECK_NOTHROW(pendavg::resolve_average_method(3, o));
  o.digits = 30;
  CHECK(refused(3, o, "digits 30"));  // the torus tolerance is 10^-digits in MPFR
  o = with_method(AverageMethod::torus_trapezoid);
  o.samples = 4096;
  CHECK(refused(3, o, "samples"));
  o = AverageOptions{};
  o.seed = 3;
  CHECK(refused(4, o, "seed"));  // auto runs the torus for N = 4
  CHECK(refused(5, o, "seed"));  // and transfer for N = 5
  o.method = AverageMethod::qmc;
  CHECK_NOTHROW(pendavg::resolve_average_method(5, o));
  o.samples = 3000;
  CHECK(refused(5, o, "power of two"));
  o = AverageOptions{};
  o.tolerance = 1e-7;
  CHECK_NOTHROW(pendavg::resolve_average_method(5, o));  // transfer takes a tolerance
  o.tolerance = 0;
  CHECK(refused(5, o, "tol"));
  o = AverageOptions{};
  o.digits = 20;
  CHECK(refused(8, o, "double only"));  // auto runs transfer for N = 8: double only
  o = with_method(AverageMethod::qmc);
  o.tolerance = 1e-6;
  CHECK(refused(8, o, "tol"));
  o = with_method(AverageMethod::qmc);
  o.digits = 20;
  CHECK(refused(3, o, "double only"));
  o = with_method(AverageMethod::series);
  CHECK(refused(3, o, "N = 2"));
  o = AverageOptions{};
  o.digits = 1001;
  CHECK(refused(2, o, "digits"));
  o = with_method(AverageMethod::torus_trapezoid);
  CHECK(refused(12, o, "too long"));
  // Real and digits must match.
  const Chain<double> pendulum({1.0, 1.0}, {1.0, 1.0});
  AverageOptions thirty;
  thirty.digits = 30;
  CHECK_THROWS_AS(pendavg::average(pendulum, 1.0, thirty), pendavg::invalid_input);
  CHECK_THROWS_AS(pendavg::average(pendulum, 0.0), pendavg::invalid_input);
}

TEST_CASE("api: which options and digits each method takes, as front ends ask it", "[api]") {
  using pendavg::AverageOption;
  using pendavg::method_supports_digits;
  using pendavg::method_uses_option;
  for (const AverageMethod m : {AverageMethod::torus_trapezoid, AverageMethod::torus_gauss}) {
    CHECK(method_uses_option(m, AverageOption::tolerance, 16));
    CHECK_FALSE(method_uses_option(m, AverageOption::tolerance, 30));  // 10^-digits in MPFR
    CHECK(method_supports_digits(m, 30));
  }
  CHECK(method_uses_option(AverageMethod::transfer, AverageOption::tolerance, 16));
  CHECK_FALSE(method_supports_digits(AverageMethod::transfer, 17));
  CHECK_FALSE(method_supports_digits(AverageMethod::qmc, 17));
  CHECK(method_supports_digits(AverageMethod::qmc, 16));
  for (const AverageMethod m : {AverageMethod::integral, AverageMethod::series}) {
    CHECK(method_supports_digits(m, 1000));
    for (const AverageOption o : {AverageOption::tolerance, AverageOption::samples,
                                  AverageOption::shifts, AverageOption::seed})
      CHECK_FALSE(method_uses_option(m, o, 16));
  }
  for (const AverageOption o : {AverageOption::samples, AverageOption::shifts, AverageOption::seed}) {
    CHECK(method_uses_option(AverageMethod::qmc, o, 16));
    CHECK_FALSE(method_uses_option(AverageMethod::transfer, o, 16));
  }
  // The predicates and average()'s checks are one rule: every option a method uses is
  // accepted, every other one refused.
  for (const AverageMethod m : {AverageMethod::torus_trapezoid, AverageMethod::torus_gauss,
                                AverageMethod::qmc, AverageMethod::transfer}) {
    for (const AverageOption option : {AverageOption::tolerance, AverageOption::samples,
                                       AverageOption::shifts, AverageOption::seed}) {
      AverageOptions o = with_method(m);
      if (option == AverageOption::tolerance) o.tolerance = 1e-6;
      if (option == AverageOption::samples) o.samples = 2048;
      if (option == AverageOption::shifts) o.shifts = 8;
      if (option == AverageOption::seed) o.seed = 5;
      INFO(pendavg::average_method_name(m) << " " << pendavg::average_option_name(option));
      if (method_uses_option(m, option, 16))
        CHECK_NOTHROW(pendavg::resolve_average_method(3, o));
      else
        CHECK_THROWS_AS(pendavg::resolve_average_method(3, o), pendavg::invalid_input);
    }
  }
}

TEST_CASE("api: every method returns one result type with the kind of its errors", "[api]") {
  const Chain<double> pendulum({0.3, 0.7}, {1.0, 2.0}, 1.0);
  const double beta = 1.5;
  const auto integral = pendavg::average(pendulum, beta);
  const auto series = pendavg::average(pendulum, beta, with_method(AverageMethod::series));
  const auto torus = pendavg::average(pendulum, beta, with_method(AverageMethod::torus_trapezoid));
  const auto gauss = pendavg::average(pendulum, beta, with_method(AverageMethod::torus_gauss));
  AverageOptions qmc_options = with_method(AverageMethod::qmc);
  qmc_options.samples = 4096;
  const auto qmc = pendavg::average(pendulum, beta, qmc_options);
  const auto transfer = pendavg::average(pendulum, beta, with_method(AverageMethod::transfer));
  CHECK(integral.method == pendavg::Method::reduced_integral);
  CHECK(integral.error_kind == ErrorKind::estimate);
  CHECK(integral.work_unit == pendavg::WorkUnit::nodes);
  CHECK(series.method == pendavg::Method::series);
  CHECK(series.error_kind == ErrorKind::bound);  // the certified tail bound
  CHECK(series.work_unit == pendavg::WorkUnit::terms);
  CHECK(series.cos_angle[0].kind == ErrorKind::estimate);  // from the integral
  CHECK(torus.torus.has_value());
  CHECK(torus.error_kind == ErrorKind::estimate);
  CHECK(gauss.method == pendavg::Method::torus_gauss_legendre);
  CHECK(qmc.error_kind == ErrorKind::statistical);
  CHECK(qmc.work_unit == pendavg::WorkUnit::samples);
  REQUIRE(qmc.qmc.has_value());
  CHECK(qmc.evaluations == 4096 * qmc.qmc->shifts);
  CHECK(transfer.method == pendavg::Method::transfer);
  CHECK(transfer.error_kind == ErrorKind::estimate);
  CHECK(transfer.work_unit == pendavg::WorkUnit::nodes);
  REQUIRE(transfer.transfer.has_value());
  CHECK(transfer.transfer->angle_nodes >= 16);
  CHECK(transfer.converged);
  for (const auto* r : {&integral, &series, &torus, &gauss, &qmc, &transfer}) {
    INFO(pendavg::method_name(r->method));
    REQUIRE(r->beta_kinetic.size() == 2);
    REQUIRE(r->ratio.has_value());
    CHECK(r->beta_kinetic_canonical.size() == 2);
    CHECK(r->beta_kinetic_canonical[0].value == 0.5);
    CHECK(r->diagonal_approximation == pendavg::diagonal_approximation(pendulum));
    CHECK(r->equipartition_residual <= 1e-12);
    for (std::size_t i = 0; i < 2; ++i) {
      // Every method agrees with the integral within the two errors.
      CHECK(std::abs(r->beta_kinetic[i].value - integral.beta_kinetic[i].value) <=
            r->beta_kinetic[i].error + integral.beta_kinetic[i].error);
      CHECK(std::abs(r->cos_angle[i].value - integral.cos_angle[i].value) <=
            r->cos_angle[i].error + integral.cos_angle[i].error);
      CHECK(std::abs(r->beta2_kinetic_variance[i].value -
                     integral.beta2_kinetic_variance[i].value) <=
            r->beta2_kinetic_variance[i].error + integral.beta2_kinetic_variance[i].error);
    }
  }
  // N = 1 has no ratio; beta<K_1> = 1/2 exactly.
  const auto single = pendavg::average(Chain<double>({2.0}, {3.0}), 0.7);
  CHECK_FALSE(single.ratio.has_value());
  CHECK(single.beta_kinetic[0].value == Approx(0.5).epsilon(1e-15));
}

TEST_CASE("api: the limits through the one API", "[api]") {
  const Chain<double> pendulum({0.5, 0.5}, {1.0, 1.0});
  const auto high = pendavg::high_temperature_limit(pendulum);
  CHECK(high.method == pendavg::Method::high_temperature_limit);
  CHECK(high.error_kind == ErrorKind::bound);
  CHECK(high.beta_kinetic[0].value == Approx(0.3431834814709248549).epsilon(2e-15));
  const Chain<double> three({1.0, 2.0, 3.0}, {1.0, 1.0, 2.0});
  const auto high3 = pendavg::high_temperature_limit(three);
  CHECK(high3.method == pendavg::Method::torus_trapezoid);
  CHECK(high3.cos_angle[1].value == 0);
  // Beyond N = 5 the beta -> 0 limit runs transfer on the chain at g = 0, any length.
  const Chain<double> seven(std::vector<double>(7, 1.0), std::vector<double>(7, 1.0));
  const auto high7 = pendavg::high_temperature_limit(seven);
  CHECK(high7.method == pendavg::Method::transfer);
  CHECK(high7.cos_angle[6].value == 0);
  double sum = 0;
  for (const auto& k : high7.beta_kinetic) sum += k.value;
  CHECK(std::abs(sum - 3.5) <= 1e-12);
  const auto low3 = pendavg::low_temperature_limit(three);
  CHECK(low3.method == pendavg::Method::low_temperature_limit);
  for (const auto& k : low3.beta_kinetic) CHECK(k.value == 0.5);
  // The limits choose their own method and take no torus tolerance in MPFR.
  CHECK_THROWS_AS(pendavg::high_temperature_limit(three, with_method(AverageMethod::qmc)),
                  pendavg::invalid_input);
  AverageOptions seed;
  seed.seed = 2;
  CHECK_THROWS_AS(pendavg::low_temperature_limit(three, seed), pendavg::invalid_input);
}

TEST_CASE("api: a workspace reused across calls gives the bits of fresh calls", "[api]") {
  pendavg::AverageWorkspace<double> workspace;
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> log_beta(-3, 4), mu(0.01, 0.99), log_l(-2, 2);
  for (int k = 0; k < 200; ++k) {
    const double m1 = mu(rng);
    const Chain<double> chain({m1, 1 - m1}, {1.0, std::pow(10.0, log_l(rng))});
    const double beta = std::pow(10.0, log_beta(rng));
    CHECK(fingerprint(pendavg::average(chain, beta, {}, workspace)) ==
          fingerprint(pendavg::average(chain, beta)));
  }
}

TEST_CASE("api: working precisions nest and are restored", "[api][mpfr]") {
  const int before = pendavg::current_mpfr_digits();
  {
    const pendavg::working_precision outer(40);
    CHECK(pendavg::current_mpfr_digits() == 40);
    {
      const pendavg::working_precision inner(80);
      CHECK(pendavg::current_mpfr_digits() == 80);
      CHECK(mpfr_real(1).precision() == 80);
      const pendavg::working_precision same(80);
      CHECK(pendavg::current_mpfr_digits() == 80);
    }
    CHECK(pendavg::current_mpfr_digits() == 40);
  }
  CHECK(pendavg::current_mpfr_digits() == before);
}

namespace {

/// An MPFR input built at `digits10` digits without touching the thread's precision (the caller
/// of an entry point holds nothing).
mpfr_real input(const char* text, int digits10) {
  return mpfr_real(text, static_cast<unsigned>(digits10));
}

}  // namespace

// MPFR's precision is per thread (pendavg/mpfr.hpp): calls of several threads at different
// digits give the same bits as the same calls one after another, and leave each thread's
// precision as it was. The callers hold no working_precision. The calls cover the double engine
// (which takes an MPFR working precision inside its long-double moments), the exact-sum and
// quadrature paths of the MPFR double pendulum (whose Fourier moments run at extra digits), the
// series (its own guard digits, and two OpenMP threads for its table) and the torus in MPFR.
TEST_CASE("api: concurrent calls at 16, 30 and 60 digits give the bits of serial calls",
          "[api][mpfr][threads]") {
  struct Call {
    int digits;
    AverageMethod method;
    std::vector<const char*> masses, lengths;
    const char* beta;
  };
  std::vector<Call> calls;
  const std::vector<std::pair<const char*, const char*>> pendulums{
      {"0.5", "0.5"}, {"0.05", "0.95"}, {"0.999", "0.001"}, {"1e-7", "0.9999999"}, {"0.3", "0.7"}};
  for (const int digits : {16, 30, 60}) {
    for (const auto& [m1, m2] : pendulums) {
      for (const char* beta : {"0.01", "1", "30", "2000"}) {
        calls.push_back({digits, AverageMethod::automatic, {m1, m2}, {"1", "0.7"}, beta});
      }
    }
    calls.push_back({digits, AverageMethod::series, {"0.5", "0.5"}, {"1", "1"}, "2"});
    if (digits <= 30)
      calls.push_back({digits, AverageMethod::torus_trapezoid, {"1", "2", "3"}, {"1", "1", "1"}, "1"});
  }
  const auto run = [](const Call& c) -> std::string {
    AverageOptions options;
    options.method = c.method;
    options.digits = c.digits;
    if (c.digits == 16) {
      std::vector<double> m, l;
      for (const char* x : c.masses) m.push_back(std::stod(x));
      for (const char* x : c.lengths) l.push_back(std::stod(x));
      return fingerprint(pendavg::average(Chain<double>(m, l), std::stod(c.beta), options));
    }
    const int working = c.digits + pendavg::guard_digits;
    std::vector<mpfr_real> m, l;
    for (const char* x : c.masses) m.push_back(input(x, working));
    for (const char* x : c.lengths) l.push_back(input(x, working));
    const int before = pendavg::current_mpfr_digits();
    std::string result =
        fingerprint(pendavg::average(Chain<mpfr_real>(m, l), input(c.beta, working), options));
    if (pendavg::current_mpfr_digits() != before) result += " (precision not restored)";
    return result;
  };
  std::vector<std::string> serial;
  for (const Call& c : calls) serial.push_back(run(c));

  constexpr int threads = 4;
  for (int round = 0; round < 2; ++round) {
    std::vector<std::size_t> order(calls.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::shuffle(order.begin(), order.end(), std::mt19937_64(round + 1));
    std::vector<std::string> concurrent(calls.size());
    std::atomic<std::size_t> next{0};
    std::vector<std::thread> team;
    for (int t = 0; t < threads; ++t) {
      team.emplace_back([&] {
        for (std::size_t k; (k = next++) < order.size();) concurrent[order[k]] = run(calls[order[k]]);
      });
    }
    for (std::thread& t : team) t.join();
    for (std::size_t i = 0; i < calls.size(); ++i) {
      INFO("call " << i << ": digits " << calls[i].digits << ", beta " << calls[i].beta);
      CHECK(concurrent[i] == serial[i]);
    }
  }
}

namespace {

/// A barrier that gives up after `timeout`: arrive_and_wait() is true when every party arrived
/// in time. With a process-wide precision lock the threads below would never all arrive.
class TimedBarrier {
 public:
  explicit TimedBarrier(int parties) : waiting_(parties) {}
  bool arrive_and_wait(std::chrono::seconds timeout) {
    std::unique_lock lock(mutex_);
    if (--waiting_ == 0) all_arrived_.notify_all();
    return all_arrived_.wait_for(lock, timeout, [&] { return waiting_ == 0; });
  }

 private:
  std::mutex mutex_;
  std::condition_variable all_arrived_;
  int waiting_;
};

}  // namespace

// No waiting: three threads at 30, 77 and 25 digits are inside their MPFR calls at the same time.
// Each call's first progress report (made inside the computation, at the call's own working
// precision) waits at a barrier until the other two calls have reached theirs, which a lock
// serializing precisions would make impossible. Each call sees its own precision there, and
// gives the bits of the same call made alone.
TEST_CASE("api: MPFR calls at different digits run at the same time, each at its own precision",
          "[api][mpfr][threads]") {
  struct Result {
    std::string text;
    std::vector<int> digits_seen;  // current_mpfr_digits() at each progress report
    bool met = true;               // the first report met the other threads at the barrier
  };
  TimedBarrier barrier(3);
  constexpr auto patience = std::chrono::seconds(120);
  const auto observed = [](Result& r, TimedBarrier* meet) {
    pendavg::RunControl control;
    control.progress = [&r, meet, first = true](double) mutable {
      r.digits_seen.push_back(pendavg::current_mpfr_digits());
      if (first && meet != nullptr) r.met = meet->arrive_and_wait(patience);
      first = false;
    };
    return control;
  };
  // The series (beta<K1> term by term) at `digits`; its Bessel table reports progress.
  const auto series = [&](int digits, TimedBarrier* meet) {
    Result r;
    const int working = digits + pendavg::guard_digits;
    const Chain<mpfr_real> chain({input("0.5", working), input("0.5", working)},
                                 {input("1", working), input("0.7", working)});
    const auto rows = pendavg::series_convergence(chain, input("3", working), digits, 0,
                                                  observed(r, meet));
    for (const auto& row : rows)
      r.text += row.beta_kinetic1.str(0, std::ios::scientific) + ' ' +
                row.bound.str(0, std::ios::scientific) + '\n';
    return r;
  };
  // The torus of N = 3 through average() at `digits`; each level's rows report progress.
  const auto torus = [&](int digits, TimedBarrier* meet) {
    Result r;
    const int working = digits + pendavg::guard_digits;
    const Chain<mpfr_real> chain({input("1", working), input("2", working), input("3", working)},
                                 {input("1", working), input("1", working), input("1", working)});
    AverageOptions options = with_method(AverageMethod::torus_trapezoid);
    options.digits = digits;
    options.control = observed(r, meet);
    r.text = fingerprint(pendavg::average(chain, input("1", working), options));
    return r;
  };
  const Result alone[] = {series(30, nullptr), series(77, nullptr), torus(25, nullptr)};
  Result together[3];
  {
    std::thread a([&] { together[0] = series(30, &barrier); });
    std::thread b([&] { together[1] = series(77, &barrier); });
    std::thread c([&] { together[2] = torus(25, &barrier); });
    a.join();
    b.join();
    c.join();
  }
  const int digits[] = {30, 77, 25};
  for (int k = 0; k < 3; ++k) {
    INFO("call at " << digits[k] << " digits");
    CHECK(together[k].met);
    CHECK(together[k].text == alone[k].text);
    REQUIRE(!together[k].digits_seen.empty());
    // The call's working precision (digits + guard_digits; the series' own guard is smaller),
    // whatever the other threads run at.
    for (const int seen : together[k].digits_seen) {
      CHECK(seen > digits[k]);
      CHECK(seen <= digits[k] + pendavg::guard_digits);
    }
  }
  CHECK(together[2].digits_seen.front() == 25 + pendavg::guard_digits);
}

namespace {

// GMP's (and so MPFR's) allocation functions, counting the bytes held by allocations of the
// threads that set counted_thread.
thread_local bool counted_thread = false;
std::atomic<long long> counted_bytes{0};
void* counting_allocate(std::size_t size) {
  if (counted_thread) counted_bytes += static_cast<long long>(size);
  return std::malloc(size);
}
void* counting_reallocate(void* block, std::size_t old_size, std::size_t new_size) {
  if (counted_thread) counted_bytes += static_cast<long long>(new_size) - static_cast<long long>(old_size);
  return std::realloc(block, new_size);
}
void counting_free(void* block, std::size_t size) {
  if (counted_thread) counted_bytes -= static_cast<long long>(size);
  std::free(block);
}

}  // namespace

// Found by LeakSanitizer in the PENDAVG_SANITIZE build (this file's concurrent calls, and every
// MPFR sweep of tests/cli/test_cli.sh): MPFR keeps constants (pi, log 2) and a pool of integers
// per thread, which leak unless the thread frees them before it ends; a thread that computed under
// a working_precision now does.
TEST_CASE("api: a thread that computed in MPFR frees MPFR's thread caches when it ends",
          "[api][mpfr][threads]") {
  if (!mpfr_buildopt_tls_p()) {
    WARN("this MPFR shares its caches between threads: nothing to free per thread");
    return;
  }
  void* (*allocate)(std::size_t) = nullptr;
  void* (*reallocate)(void*, std::size_t, std::size_t) = nullptr;
  void (*release)(void*, std::size_t) = nullptr;
  mp_get_memory_functions(&allocate, &reallocate, &release);
  mp_set_memory_functions(counting_allocate, counting_reallocate, counting_free);
  long long cached = 0;
  std::thread worker([&] {
    counted_thread = true;
    {
      const pendavg::working_precision precision(300);
      mpfr_real x;
      mpfr_const_pi(x.backend().data(), MPFR_RNDN);
      mpfr_const_log2(x.backend().data(), MPFR_RNDN);
      x = exp(x);
    }
    cached = counted_bytes.load();  // the values are gone, MPFR's caches are not
  });
  worker.join();
  mp_set_memory_functions(allocate, reallocate, release);
  CHECK(cached > 0);
  CHECK(counted_bytes.load() == 0);
}
