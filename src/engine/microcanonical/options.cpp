// SPDX-License-Identifier: GPL-3.0-or-later
// The microcanonical engine's options (pendavg/microcanonical.hpp): the rule automatic picks, the
// default tolerance, the rules' names, and the adapter from the common AverageOptions of the
// front ends (which options each rule takes, refused in one line otherwise).
#include "engine/qmc/lattice_table.hpp"
#include "pendavg/average.hpp"
#include "pendavg/microcanonical.hpp"

#include <cstddef>
#include <string>
#include <utility>

namespace pendavg {

MicrocanonicalOptions::Rule resolve_microcanonical_rule(std::size_t particles,
                                                        MicrocanonicalOptions::Rule rule) {
  using Rule = MicrocanonicalOptions::Rule;
  if (rule != Rule::automatic) return rule;
  return particles <= 4 ? Rule::integral : Rule::qmc;
}

double default_microcanonical_tolerance(std::size_t particles) {
  return particles <= 2 ? 1e-13 : particles == 3 ? 1e-11 : 1e-9;
}

const char* microcanonical_rule_name(MicrocanonicalOptions::Rule rule, std::size_t particles) {
  using Rule = MicrocanonicalOptions::Rule;
  switch (resolve_microcanonical_rule(particles, rule)) {
    case Rule::integral: return average_method_name(AverageMethod::integral);
    case Rule::torus: return average_method_name(AverageMethod::torus_trapezoid);
    default: return average_method_name(AverageMethod::qmc);
  }
}

bool microcanonical_rule_uses_option(MicrocanonicalOptions::Rule rule, AverageOption option,
                                     int digits) {
  using Rule = MicrocanonicalOptions::Rule;
  if (option == AverageOption::tolerance) return rule != Rule::qmc && digits == min_digits;
  return rule == Rule::qmc;
}

MicrocanonicalOptions microcanonical_options(const AverageOptions& options, std::size_t particles) {
  using Rule = MicrocanonicalOptions::Rule;
  const std::string context = "microcanonical: ";
  MicrocanonicalOptions out;
  switch (options.method) {
    case AverageMethod::automatic: out.rule = Rule::automatic; break;
    case AverageMethod::integral: out.rule = Rule::integral; break;
    case AverageMethod::torus_trapezoid: out.rule = Rule::torus; break;
    case AverageMethod::qmc: out.rule = Rule::qmc; break;
    default:
      throw invalid_input(context + "method " + average_method_name(options.method) +
                          " is not available for microcanonical averages (auto, integral, "
                          "torus-trapezoid, qmc)");
  }
  if (options.digits < min_digits || options.digits > max_digits)
    throw invalid_input(context + "digits must be in " + std::to_string(min_digits) + ".." +
                        std::to_string(max_digits) + ", got " + std::to_string(options.digits));
  if (options.threads < 1) throw invalid_input(context + "threads must be >= 1");
  const Rule rule = resolve_microcanonical_rule(particles, out.rule);
  const std::string name = microcanonical_rule_name(rule, particles);
  const std::string chosen = "the microcanonical " + name + " rule" +
                             (out.rule == Rule::automatic
                                  ? " (method auto for N = " + std::to_string(particles) + ")"
                                  : std::string());
  const bool qmc = rule == Rule::qmc;
  if (options.tolerance) {
    if (qmc) throw invalid_input(context + "tol is not used by " + chosen);
    if (!microcanonical_rule_uses_option(rule, AverageOption::tolerance, options.digits))
      throw invalid_input(context + "tol is for double runs (digits 16); with digits " +
                          std::to_string(options.digits) + " the tolerance is 1e-" +
                          std::to_string(options.digits));
    if (!(*options.tolerance > 0 && *options.tolerance < 1))
      throw invalid_input(context + "tol must be in (0, 1)");
    out.tolerance = options.tolerance;
  }
  for (const auto& [given, option] :
       {std::pair{options.samples.has_value(), AverageOption::samples},
        std::pair{options.shifts.has_value(), AverageOption::shifts},
        std::pair{options.seed.has_value(), AverageOption::seed}})
    if (given && !microcanonical_rule_uses_option(rule, option, options.digits))
      throw invalid_input(context + average_option_name(option) + " is used by qmc only, not by " +
                          chosen);
  if (qmc) {
    if (particles > detail::qmc::lattice_max_dimension)
      throw invalid_input(context + "N = " + std::to_string(particles) + " is beyond " + chosen +
                          ": its lattices cover N <= " +
                          std::to_string(detail::qmc::lattice_max_dimension));
    if (options.digits != min_digits)
      throw invalid_input(context + "digits " + std::to_string(options.digits) +
                          " is not available with " + chosen +
                          ": microcanonical qmc runs in double only (digits > 16 need N <= 4 "
                          "with the integral or torus-trapezoid rule)");
    if (options.samples) {
      const std::size_t s = *options.samples;
      const std::size_t most = std::size_t(1) << detail::qmc::lattice_table_max_log2;
      if (s < 1024 || s > most || (s & (s - 1)) != 0)
        throw invalid_input(context + "samples must be a power of two in 1024.." +
                            std::to_string(most) + ", got " + std::to_string(s));
      out.points = s;
    }
    if (options.shifts) {
      if (*options.shifts < 4 || *options.shifts > 1024)
        throw invalid_input(context + "shifts must be in 4..1024, got " +
                            std::to_string(*options.shifts));
      out.shifts = *options.shifts;
    }
    if (options.seed) out.seed = *options.seed;
  } else if (rule == Rule::torus && options.digits != min_digits && particles > 2) {
    throw invalid_input(context + "the torus-trapezoid rule converges only algebraically (a "
                        "check, not for digits " + std::to_string(options.digits) + " at N = " +
                        std::to_string(particles) + "): use the integral rule");
  } else if (rule == Rule::integral && particles > 6) {
    throw invalid_input(context + "the integral rule is for N <= 6 (N = " +
                        std::to_string(particles) + ": use method qmc)");
  } else if (rule == Rule::torus && particles > 5) {
    throw invalid_input(context + "the torus-trapezoid rule is for N <= 5 (N = " +
                        std::to_string(particles) + ": use method qmc)");
  }
  out.digits = options.digits == min_digits ? 0 : options.digits;
  out.threads = options.threads;
  out.control = options.control;
  return out;
}

}  // namespace pendavg
