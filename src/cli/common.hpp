// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/common.hpp -- what every command of the CLI shares: its entry in the dispatch table,
// the number type of a run, the chain options, where the output goes, the run diagnostics.
#pragma once

#include "args.hpp"
#include "format.hpp"

#include "pendavg/mpfr.hpp"
#include "pendavg/pendavg.hpp"

#include <array>
#include <chrono>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace pendavg::cli {

/// One command: what `run` dispatches on (src/cli/commands.cpp holds the table).
struct Command {
  std::string_view name;
  std::string_view usage;
  std::span<const std::string_view> options;
  std::string (*run)(const Options&);
  std::span<const std::string_view> flags = {};  ///< options without a value
  bool distributed = false;  ///< runs on every MPI rank; the others run on rank 0 alone
  bool operands = false;     ///< takes file names besides its options
};

// Each command's entry, defined in its own file (average.cpp, limit.cpp, ...).
extern const Command average_command, limit_command, series_command, table_command,
    simulate_command, poincare_command, merge_command;

/// Called once a command has checked all of its input, before any work (tests hook it).
void input_checked(std::string_view command);

/// Runs `body.operator()<Real>()` with Real = double for 16 digits and Real = mpfr_real (under a
/// working_precision held for the whole call, parsing included) for more. Not for commands whose
/// rows run in a parallel loop: each row holds its own working precision there.
template <class Body>
std::string with_number_type(int digits, Body&& body) {
  if (digits == min_digits) return body.template operator()<double>();
  const working_precision guard(digits + guard_digits);
  return body.template operator()<mpfr_real>();
}

inline constexpr std::array<std::string_view, 3> all_formats{"json", "csv", "text"};

inline Format format_option(const Options& options, std::string_view fallback,
                            std::span<const std::string_view> allowed) {
  const std::string_view name = options.get("format", fallback);
  parse_choice(name, "format", allowed);
  constexpr std::array<std::string_view, 3> names{"json", "csv", "text"};
  return static_cast<Format>(std::ranges::find(names, name) - names.begin());
}

template <class Real>
Chain<Real> make_chain(std::vector<Real> masses, std::vector<Real> lengths, Real g) {
  if (masses.size() != lengths.size())
    throw usage_error(std::to_string(masses.size()) + " masses but " +
                      std::to_string(lengths.size()) + " lengths");
  return Chain<Real>(std::move(masses), std::move(lengths), std::move(g));
}

/// The chain of --masses, --lengths (all 1 when optional and absent) and --g (default 1).
template <class Real>
Chain<Real> chain_option(const Options& options, bool lengths_required) {
  auto masses = parse_real_list<Real>(options.required("masses"), "--masses", Domain::positive);
  auto lengths = lengths_required || options.has("lengths")
                     ? parse_real_list<Real>(options.required("lengths"), "--lengths",
                                             Domain::positive)
                     : std::vector<Real>(masses.size(), Real(1));
  Real g = parse_real<Real>(options.get("g", "1"), "--g", Domain::nonnegative);
  return make_chain(std::move(masses), std::move(lengths), std::move(g));
}

/// The chain of `simulate` and `poincare` (double only): --masses, --lengths (both required)
/// and --g (default 1).
Chain<double> dynamics_chain_option(const Options& options);

class Stopwatch {
 public:
  double seconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  }

 private:
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
};

/// The numbers of a chain's options as written (the state first when given, then g, m1..mN,
/// l1..lN): an MPFR run prints its inputs as written.
std::vector<std::string_view> input_texts(const Options& options, std::string_view state,
                                          std::size_t particles);

/// Where a command's output goes: stdout (returned), or with --output FILE written atomically
/// to FILE (nothing on stdout).
std::string deliver(const Options& options, std::string_view command, std::string text);

/// --output FILE of a single-result command: checked before any work.
void check_output_option(const Options& options, std::string_view command);

/// The run diagnostics of `a` (io::run_fields: the torus grid, the qmc run or the transfer
/// operator's final resolution) as a JSON object, "null" for the other methods.
template <class Real>
std::string run_json(const Averages<Real>& a);

}  // namespace pendavg::cli
