// SPDX-License-Identifier: GPL-3.0-or-later
// Large N (issue 13): the work-precision study and the timing targets of the transfer operator
// (src/engine/transfer/chain_transfer.hpp) side by side with randomized lattice QMC, in one process.
// Unit chains (m_i = l_i = 1, g = 1). Not a Google Benchmark: each mode prints CSV rows.
//
//   bench_large_n wp N BETA MAX_LOG2_POINTS [REPS]
//       One row per run: method, N, beta, work, seconds, the true errors (largest over i) of
//       beta<K_i>, beta^2 Var K_i, <cos phi_i> and the largest reported errors. Methods:
//         transfer-level  one resolution n = 12 .. 96 with pivots for 1e-15 (no estimate): the
//                         angle convergence;
//         transfer        chain_transfer_average at tolerance 1e-3 .. 1e-12 (what `auto` runs);
//         qmc-pivot       today's qmc (the pivot law, 16 shifts), 2^10 .. 2^MAX points per shift;
//         qmc-vonmises    the same lattices over the smooth von Mises law;
//         torus           the tensor torus (N <= 6).
//       Seconds: thread CPU time of one thread, median of REPS (default 3; one for qmc runs of
//       2^16 points and more). Reference: a transfer level finer than any run, checked against
//       a second one (the difference is printed in the leading # line).
//   bench_large_n aims N BETA TOL THREADS [REPS]
//       average() with method transfer at TOL on THREADS threads: wall and process CPU seconds
//       (median of REPS, default 3), the final resolution, the largest true and reported errors
//       (reference: a run 1e4 times tighter, at most 1e-12), how many of the 3N quantities'
//       reported errors (plus the reference's) miss their true errors, and the worst
//       true / reported ratio.
//   bench_large_n light N BETA MASS [TOL [REPS]]
//       One very light particle (mass MASS among unit masses, unit lengths, g = 1) at the root,
//       in the middle and at the tail: chain_transfer_average at TOL (default 1e-10), one
//       thread: thread CPU seconds (median of REPS, default 1), converged, levels, final angle
//       and pivot nodes, the light particle's beta<K> and error, and the largest reported
//       relative error of beta<K_i> over the chain.
//   bench_large_n small
//       Which method for N <= 5: torus trapezoid and transfer at the same tolerance (1e-13; 1e-10
//       for N = 5) on unit and unequal chains at beta = 0.1, 1, 10: thread CPU seconds (one run),
//       the largest reported error of beta<K_i>, converged, and the largest difference.
//
// tests/bench/large_n_work_precision.sh runs the study behind tables/large_n_work_precision.csv.
#include "engine/transfer/chain_transfer.hpp"
#include "engine/qmc/qmc.hpp"
#include "engine/torus/torus.hpp"
#include "pendavg/average.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <string>
#include <utility>
#include <vector>

namespace {

using pendavg::Averages;
using pendavg::Chain;

double thread_seconds() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

double process_seconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

double wall_seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

template <class F>
double median_of(int reps, double (*clock)(), F&& f) {
  std::vector<double> t;
  for (int r = 0; r < reps; ++r) {
    const double start = clock();
    f();
    t.push_back(clock() - start);
  }
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

Chain<double> unit_chain(std::size_t n) {
  return Chain<double>(std::vector<double>(n, 1.0), std::vector<double>(n, 1.0), 1.0);
}

/// The reference: values far more accurate than any run of the study, and their accuracy
/// (`check`). The work-precision study takes a transfer level finer than any of its runs, checked
/// against a second fine level; the timing runs take chain_transfer_average at a tolerance
/// 1e4 times tighter than theirs (at most 1e-12), checked by its own error estimate.
struct Reference {
  std::vector<double> beta_kinetic, beta2_kinetic_variance, cos_angle;
  double check = 0;
};

Reference fine_level_reference(const Chain<double>& chain, double beta, int threads) {
  const std::size_t n = 144, m = pendavg::transfer_pivot_nodes(chain, 1e-17);
  const auto level = pendavg::chain_transfer_level(chain, beta, n, m, threads);
  const auto second = pendavg::chain_transfer_level(chain, beta, 120, m - 4, threads);
  Reference ref{level.beta_kinetic, level.beta2_kinetic_variance, level.cos_angle, 0};
  for (std::size_t i = 0; i < chain.size(); ++i) {
    ref.check = std::max({ref.check, std::abs(level.beta_kinetic[i] - second.beta_kinetic[i]),
                          std::abs(level.beta2_kinetic_variance[i] -
                                   second.beta2_kinetic_variance[i]),
                          std::abs(level.cos_angle[i] - second.cos_angle[i])});
  }
  return ref;
}

Reference tight_run_reference(const Chain<double>& chain, double beta, double tol, int threads) {
  pendavg::TransferOptions o;
  o.tolerance = std::min(1e-12, tol * 1e-4);
  o.threads = threads;
  const Averages<double> a = pendavg::chain_transfer_average(chain, beta, o);
  Reference ref;
  for (std::size_t i = 0; i < chain.size(); ++i) {
    ref.beta_kinetic.push_back(a.beta_kinetic[i].value);
    ref.beta2_kinetic_variance.push_back(a.beta2_kinetic_variance[i].value);
    ref.cos_angle.push_back(a.cos_angle[i].value);
    ref.check = std::max({ref.check, a.beta_kinetic[i].error, a.beta2_kinetic_variance[i].error,
                          a.cos_angle[i].error});
  }
  return ref;
}

struct Errors {
  double k1 = 0, k = 0, v = 0, c = 0;       // true errors: beta<K_1>, largest over i
  double rk = 0, rv = 0, rc = 0;            // largest reported errors
  int uncovered = 0;                        // quantities whose reported error < true error
  double worst = 0;                         // largest true / (reported + reference) error
};

/// The larger of a and b, NaN when either is (std::max(0, NaN) is 0: a run that returned NaN
/// would look exact).
double worse(double a, double b) { return std::isnan(a) || std::isnan(b) ? NAN : std::max(a, b); }

Errors errors(const std::vector<double>& k, const std::vector<double>& v,
              const std::vector<double>& c, const Reference& ref) {
  Errors e;
  e.k1 = std::abs(k[0] - ref.beta_kinetic[0]);
  for (std::size_t i = 0; i < k.size(); ++i) {
    e.k = worse(e.k, std::abs(k[i] - ref.beta_kinetic[i]));
    e.v = worse(e.v, std::abs(v[i] - ref.beta2_kinetic_variance[i]));
    e.c = worse(e.c, std::abs(c[i] - ref.cos_angle[i]));
  }
  return e;
}

Errors errors(const Averages<double>& a, const Reference& ref) {
  std::vector<double> k, v, c;
  for (std::size_t i = 0; i < a.beta_kinetic.size(); ++i) {
    k.push_back(a.beta_kinetic[i].value);
    v.push_back(a.beta2_kinetic_variance[i].value);
    c.push_back(a.cos_angle[i].value);
  }
  Errors e = errors(k, v, c, ref);
  for (std::size_t i = 0; i < a.beta_kinetic.size(); ++i) {
    e.rk = worse(e.rk, a.beta_kinetic[i].error);
    e.rv = worse(e.rv, a.beta2_kinetic_variance[i].error);
    e.rc = worse(e.rc, a.cos_angle[i].error);
    for (const auto& [x, r] : {std::pair{a.beta_kinetic[i], ref.beta_kinetic[i]},
                               std::pair{a.beta2_kinetic_variance[i], ref.beta2_kinetic_variance[i]},
                               std::pair{a.cos_angle[i], ref.cos_angle[i]}}) {
      const double ratio = std::abs(x.value - r) / (x.error + ref.check);
      e.uncovered += ratio <= 1 ? 0 : 1;  // NaN counts as uncovered
      e.worst = worse(e.worst, ratio);
    }
  }
  return e;
}

/// One CSV row; `resolution` is "n,m" for the transfer operator, "," otherwise.
void row(const char* method, std::size_t n, double beta, const std::string& resolution,
         double work, double seconds, const Errors& e, bool reported) {
  std::printf("%s,%zu,%g,%s,%.6g,%.6g,%.3e,%.3e,%.3e,%.3e", method, n, beta, resolution.c_str(),
              work, seconds, e.k1, e.k, e.v, e.c);
  if (reported) {
    std::printf(",%.3e,%.3e,%.3e\n", e.rk, e.rv, e.rc);
  } else {
    std::printf(",,,\n");
  }
  std::fflush(stdout);
}

std::string resolution(std::size_t n, std::size_t m) {
  return std::to_string(n) + "," + std::to_string(m);
}

int work_precision(std::size_t n, double beta, int max_log2, int reps) {
  const Chain<double> chain = unit_chain(n);
  const Reference ref = fine_level_reference(chain, beta, 1);
  std::printf("# N = %zu, beta = %g, unit chain; reference: transfer level (144, %zu), its "
              "difference to (120, %zu) %.1e; beta<K_1> = %.16f\n",
              n, beta, pendavg::transfer_pivot_nodes(chain, 1e-17),
              pendavg::transfer_pivot_nodes(chain, 1e-17) - 4, ref.check, ref.beta_kinetic[0]);
  std::printf("method,N,beta,angle_nodes,pivot_nodes,work,seconds,err_K1,err_Kmax,err_Vmax,"
              "err_Cmax,reported_Kmax,reported_Vmax,reported_Cmax\n");
  for (const std::size_t angle : {12, 16, 20, 24, 32, 40, 48, 56, 64, 80, 96}) {
    const std::size_t pivot = pendavg::transfer_pivot_nodes(chain, 1e-15);
    pendavg::TransferLevel<double> r;
    const double s = median_of(reps, thread_seconds, [&] {
      r = pendavg::chain_transfer_level(chain, beta, angle, pivot, 1);
    });
    row("transfer-level", n, beta, resolution(angle, pivot), r.kernel_evaluations, s,
        errors(r.beta_kinetic, r.beta2_kinetic_variance, r.cos_angle, ref), false);
  }
  for (const double tol : {1e-3, 1e-4, 1e-6, 1e-8, 1e-10, 1e-12}) {
    pendavg::TransferOptions o;
    o.tolerance = tol;
    Averages<double> a;
    const double s =
        median_of(reps, thread_seconds, [&] { a = pendavg::chain_transfer_average(chain, beta, o); });
    row("transfer", n, beta, resolution(a.transfer->angle_nodes, a.transfer->pivot_nodes),
        a.transfer->kernel_evaluations, s, errors(a, ref), true);
  }
  for (const auto proposal : {pendavg::QmcProposal::pivot_sequential, pendavg::QmcProposal::von_mises}) {
    const bool pivot = proposal == pendavg::QmcProposal::pivot_sequential;
    for (int lg = 10; lg <= max_log2; lg += 2) {
      if (!pivot && lg > max_log2 - 2) break;  // the von Mises law is the slower; fewer points
      pendavg::QmcOptions q;
      q.points = std::size_t(1) << lg;
      q.shifts = 16;
      q.threads = 1;
      q.proposal = proposal;
      Averages<double> a;
      const double s = median_of(lg >= 16 ? 1 : reps, thread_seconds,
                                 [&] { a = pendavg::qmc_average(chain, beta, q); });
      row(pivot ? "qmc-pivot" : "qmc-vonmises", n, beta, ",",
          static_cast<double>(q.points * q.shifts), s, errors(a, ref), true);
    }
  }
  if (n <= 6) {
    for (const double tol : {1e-4, 1e-6, 1e-8, 1e-10}) {
      pendavg::TorusOptions t;
      t.tolerance = tol;
      Averages<double> a;
      const double s = median_of(1, thread_seconds, [&] { a = pendavg::torus_average(chain, beta, t); });
      row("torus", n, beta, ",", static_cast<double>(a.evaluations), s, errors(a, ref), true);
    }
  }
  return 0;
}

int aims(std::size_t n, double beta, double tol, int threads, int reps) {
  const Chain<double> chain = unit_chain(n);
  const Reference ref = tight_run_reference(chain, beta, tol, threads);
  pendavg::AverageOptions o;
  o.method = pendavg::AverageMethod::transfer;
  o.tolerance = tol;
  o.threads = threads;
  Averages<double> a;
  std::vector<double> wall, cpu;
  for (int r = 0; r < reps; ++r) {
    const double w0 = wall_seconds(), c0 = process_seconds();
    a = pendavg::average(chain, beta, o);
    wall.push_back(wall_seconds() - w0);
    cpu.push_back(process_seconds() - c0);
  }
  std::sort(wall.begin(), wall.end());
  std::sort(cpu.begin(), cpu.end());
  const Errors e = errors(a, ref);
  std::printf("%zu,%g,%g,%d,%.3f,%.3f,%zu,%zu,%d,%.2e,%.2e,%.2e,%.2e,%.2e,%.2e,%d,%zu,%.2f,%.1e\n",
              n, beta, tol, threads, wall[wall.size() / 2], cpu[cpu.size() / 2],
              a.transfer->angle_nodes, a.transfer->pivot_nodes, a.converged ? 1 : 0, e.k, e.v, e.c,
              e.rk, e.rv, e.rc, e.uncovered, 3 * n, e.worst, ref.check);
  std::fflush(stdout);
  return 0;
}

int light_particle(std::size_t n, double beta, double light, double tol, int reps) {
  std::printf("N,beta,mass,position,tol,seconds,converged,levels,angle_nodes,pivot_nodes,"
              "light_beta_K,light_error,largest_relative_error_K\n");
  for (const std::size_t position : {std::size_t(0), n / 2, n - 1}) {
    std::vector<double> masses(n, 1.0);
    masses[position] = light;
    const Chain<double> chain(masses, std::vector<double>(n, 1.0), 1.0);
    pendavg::TransferOptions o;
    o.tolerance = tol;
    Averages<double> a;
    const double s = median_of(reps, thread_seconds,
                               [&] { a = pendavg::chain_transfer_average(chain, beta, o); });
    double relative = 0;
    for (const auto& k : a.beta_kinetic) relative = worse(relative, k.error / std::abs(k.value));
    std::printf("%zu,%g,%g,%zu,%g,%.3f,%d,%zu,%zu,%zu,%.15e,%.1e,%.1e\n", n, beta, light,
                position + 1, tol, s, a.converged ? 1 : 0, a.transfer->levels,
                a.transfer->angle_nodes, a.transfer->pivot_nodes,
                a.beta_kinetic[position].value, a.beta_kinetic[position].error, relative);
    std::fflush(stdout);
  }
  return 0;
}

int small_chains() {
  const std::vector<std::pair<std::vector<double>, const char*>> chains = {
      {{1, 1, 1}, "1,1,1"},         {{1, 1, 1, 1}, "1,1,1,1"},    {{0.3, 1, 3}, "0.3,1,3"},
      {{1, 2, 0.5, 3}, "1,2,0.5,3"}, {{0.01, 1, 100}, "0.01,1,100"}, {{1, 1, 1, 1, 1}, "1,1,1,1,1"}};
  std::printf("masses,beta,tol,torus_seconds,torus_error_K,torus_converged,transfer_seconds,"
              "transfer_error_K,transfer_converged,largest_difference_K\n");
  for (const auto& [masses, name] : chains) {
    const Chain<double> chain(masses, std::vector<double>(masses.size(), 1.0), 1.0);
    for (const double beta : {0.1, 1.0, 10.0}) {
      pendavg::TorusOptions t;
      t.tolerance = masses.size() == 5 ? 1e-10 : 1e-13;
      pendavg::TransferOptions o;
      o.tolerance = t.tolerance;
      Averages<double> torus, transfer;
      const double ts = median_of(1, thread_seconds, [&] { torus = pendavg::torus_average(chain, beta, t); });
      const double fs =
          median_of(1, thread_seconds, [&] { transfer = pendavg::chain_transfer_average(chain, beta, o); });
      double et = 0, ef = 0, d = 0;
      for (std::size_t i = 0; i < masses.size(); ++i) {
        et = worse(et, torus.beta_kinetic[i].error);
        ef = worse(ef, transfer.beta_kinetic[i].error);
        d = worse(d, std::abs(torus.beta_kinetic[i].value - transfer.beta_kinetic[i].value));
      }
      std::printf("\"%s\",%g,%g,%.4f,%.1e,%d,%.4f,%.1e,%d,%.1e\n", name, beta, t.tolerance, ts, et,
                  torus.converged ? 1 : 0, fs, ef, transfer.converged ? 1 : 0, d);
      std::fflush(stdout);
    }
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string mode = argc > 1 ? argv[1] : "";
  if (mode == "wp" && argc >= 5) {
    return work_precision(std::strtoul(argv[2], nullptr, 10), std::atof(argv[3]),
                          std::atoi(argv[4]), argc > 5 ? std::atoi(argv[5]) : 3);
  }
  if (mode == "aims" && argc >= 6) {
    if (argc > 7 && std::string(argv[7]) == "header") {
      std::printf("N,beta,tol,threads,wall_seconds,cpu_seconds,angle_nodes,pivot_nodes,converged,"
                  "true_err_K,true_err_V,true_err_C,reported_K,reported_V,reported_C,uncovered,"
                  "quantities,worst_true_over_reported,reference_check\n");
    }
    return aims(std::strtoul(argv[2], nullptr, 10), std::atof(argv[3]), std::atof(argv[4]),
                std::atoi(argv[5]), argc > 6 ? std::atoi(argv[6]) : 3);
  }
  if (mode == "light" && argc >= 5) {
    return light_particle(std::strtoul(argv[2], nullptr, 10), std::atof(argv[3]),
                          std::atof(argv[4]), argc > 5 ? std::atof(argv[5]) : 1e-10,
                          argc > 6 ? std::atoi(argv[6]) : 1);
  }
  if (mode == "small") return small_chains();
  std::fprintf(stderr,
               "usage: bench_large_n wp N BETA MAX_LOG2_POINTS [REPS]\n"
               "       bench_large_n aims N BETA TOL THREADS [REPS [header]]\n"
               "       bench_large_n light N BETA MASS [TOL [REPS]]\n"
               "       bench_large_n small\n");
  return 2;
}
