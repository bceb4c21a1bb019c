// src/cli/average_options.cpp -- see average_options.hpp.
#include "average_options.hpp"

#include <algorithm>
#include <string>
#include <utility>

#if defined(_OPENMP)
#include <omp.h>
#endif

namespace pendavg::cli {

AverageOptions parse_average_options(const Options& options,
                                     std::span<const std::string_view> read) {
  const auto reads = [&](std::string_view name) {
    return std::ranges::find(read, name) != read.end() && options.has(name);
  };
  AverageOptions out;
  if (reads("method")) out.method = parse_average_method(std::string(options.required("method")).c_str());
  if (reads("digits")) out.digits = parse_digits(options.required("digits"));
  if (reads("tol")) {
    const std::string_view text = options.required("tol");
    out.tolerance = parse_real<double>(text, "--tol", Domain::positive);
    if (!(*out.tolerance < 1)) throw usage_error("--tol: '" + std::string(text) + "' must be < 1");
  }
  // The library checks the ranges of these for the method that runs.
  if (reads("samples"))
    out.samples = static_cast<std::size_t>(
        parse_integer(options.required("samples"), "--samples", 1, 1L << 40));
  if (reads("shifts"))
    out.shifts = static_cast<std::size_t>(
        parse_integer(options.required("shifts"), "--shifts", 1, 1L << 40));
  if (reads("seed")) out.seed = parse_unsigned(options.required("seed"), "--seed");
  return out;
}

const char* microcanonical_rule_name(MicrocanonicalOptions::Rule rule, std::size_t particles) {
  using Rule = MicrocanonicalOptions::Rule;
  rule = resolve_microcanonical_rule(particles, rule);
  return rule == Rule::integral ? "integral" : rule == Rule::torus ? "torus-trapezoid" : "qmc";
}

MicrocanonicalOptions microcanonical_options(const AverageOptions& options, std::size_t particles) {
  using Rule = MicrocanonicalOptions::Rule;
  MicrocanonicalOptions out;
  switch (options.method) {
    case AverageMethod::automatic: out.rule = Rule::automatic; break;
    case AverageMethod::integral: out.rule = Rule::integral; break;
    case AverageMethod::torus_trapezoid: out.rule = Rule::torus; break;
    case AverageMethod::qmc: out.rule = Rule::qmc; break;
    default:
      throw usage_error(std::string("--method ") + average_method_name(options.method) +
                        " is not available for microcanonical averages (auto, integral, "
                        "torus-trapezoid, qmc)");
  }
  const std::string rule = microcanonical_rule_name(out.rule, particles);
  const std::string chosen = "the microcanonical " + rule + " rule" +
                             (out.rule == Rule::automatic
                                  ? " (--method auto for N = " + std::to_string(particles) + ")"
                                  : std::string());
  const bool qmc = rule == "qmc";
  if (options.tolerance) {
    if (qmc) throw usage_error("--tol is not used by " + chosen);
    if (options.digits != min_digits)
      throw usage_error("--tol is for double runs (digits 16); with --digits " +
                        std::to_string(options.digits) + " the tolerance is 1e-" +
                        std::to_string(options.digits));
    out.tolerance = *options.tolerance;
  } else {
    out.tolerance = default_microcanonical_tolerance(particles);
  }
  for (const auto& [given, name] : {std::pair{options.samples.has_value(), "samples"},
                                    std::pair{options.shifts.has_value(), "shifts"},
                                    std::pair{options.seed.has_value(), "seed"}})
    if (given && !qmc)
      throw usage_error(std::string("--") + name + " is used by qmc only, not by " + chosen);
  if (qmc) {
    if (particles > 256)
      throw usage_error("N = " + std::to_string(particles) + " is beyond " + chosen +
                        ": microcanonical qmc's lattices cover N <= 256");
    if (options.digits != min_digits)
      throw usage_error("--digits " + std::to_string(options.digits) + " is not available with " +
                        chosen + ": microcanonical qmc runs in double only (digits > 16 need "
                        "N <= 4 with the integral or torus-trapezoid rule)");
    if (options.samples) {
      const std::size_t s = *options.samples;
      if (s < 1024 || s > 65536 || (s & (s - 1)) != 0)
        throw usage_error("--samples must be a power of two in 1024..65536 for microcanonical "
                          "qmc, got " + std::to_string(s));
      out.points = s;
    }
    if (options.shifts) {
      if (*options.shifts < 4 || *options.shifts > 1024)
        throw usage_error("--shifts must be in 4..1024, got " + std::to_string(*options.shifts));
      out.shifts = *options.shifts;
    }
    if (options.seed) out.seed = *options.seed;
  } else if (rule == "torus-trapezoid" && options.digits != min_digits && particles > 2) {
    throw usage_error("the microcanonical torus-trapezoid rule converges only algebraically (a "
                      "check, not for --digits " + std::to_string(options.digits) +
                      " at N = " + std::to_string(particles) + "): use the integral rule");
  } else if (rule == "integral" && particles > 6) {
    throw usage_error("the microcanonical integral rule is for N <= 6 (N = " +
                      std::to_string(particles) + ": use --method qmc)");
  } else if (rule == "torus-trapezoid" && particles > 5) {
    throw usage_error("the microcanonical torus-trapezoid rule is for N <= 5 (N = " +
                      std::to_string(particles) + ": use --method qmc)");
  }
  if (particles > 32 && qmc)
    throw usage_error("microcanonical qmc covers N <= 32 (N = " + std::to_string(particles) + ")");
  out.digits = options.digits == min_digits ? 0 : options.digits;
  out.threads = options.threads;
  return out;
}

int hardware_threads() {
#if defined(_OPENMP)
  return std::max(1, omp_get_max_threads());
#else
  return 1;
#endif
}

}  // namespace pendavg::cli
