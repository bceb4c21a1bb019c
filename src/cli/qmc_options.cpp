// src/cli/qmc_options.cpp -- see qmc_options.hpp.
#include "qmc_options.hpp"

namespace pendavg::cli {

std::vector<std::string> parse_qmc_options(const Options& options, QmcOptions& qmc) {
  std::vector<std::string> given;
  qmc.points = default_samples;
  if (options.has("samples")) {
    const std::string_view text = options.required("samples");
    qmc.points = static_cast<std::size_t>(parse_integer(
        text, "--samples", static_cast<long>(min_samples), static_cast<long>(max_samples)));
    if ((qmc.points & (qmc.points - 1)) != 0)
      throw usage_error("--samples: '" + std::string(text) + "' is not a power of two (" +
                        std::to_string(min_samples) + ", " + std::to_string(2 * min_samples) +
                        ", ..., " + std::to_string(max_samples) + ")");
    given.emplace_back("samples");
  }
  if (options.has("shifts")) {
    qmc.shifts = static_cast<std::size_t>(
        parse_integer(options.required("shifts"), "--shifts", min_shifts, max_shifts));
    given.emplace_back("shifts");
  }
  if (options.has("seed")) {
    qmc.seed = parse_unsigned(options.required("seed"), "--seed");
    given.emplace_back("seed");
  }
  return given;
}

}  // namespace pendavg::cli
