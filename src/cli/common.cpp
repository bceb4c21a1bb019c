// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/common.cpp -- what every command of the CLI shares.
#include "common.hpp"

#include "distribute.hpp"
#include "files.hpp"

#include "io/results.hpp"

#include <algorithm>

namespace pendavg::cli {

std::vector<std::string_view> input_texts(const Options& options, std::string_view state,
                                          std::size_t particles) {
  std::vector<std::string_view> texts;
  if (!state.empty()) texts.push_back(options.required(state));
  texts.push_back(options.get("g", "1"));
  for (const std::string_view list : {options.required("masses"), options.get("lengths", "")}) {
    std::size_t count = 0;
    for (std::size_t begin = 0; begin <= list.size() && !list.empty(); ++count) {
      const std::size_t end = std::min(list.find(',', begin), list.size());
      texts.push_back(list.substr(begin, end - begin));
      begin = end + 1;
    }
    for (; count < particles; ++count) texts.push_back("1");  // lengths default to 1
  }
  return texts;
}

Chain<double> dynamics_chain_option(const Options& options) {
  auto masses = parse_real_list<double>(options.required("masses"), "--masses", Domain::positive);
  auto lengths =
      parse_real_list<double>(options.required("lengths"), "--lengths", Domain::positive);
  if (masses.size() != lengths.size())
    throw usage_error(options.command() + ": " + std::to_string(masses.size()) + " masses but " +
                      std::to_string(lengths.size()) + " lengths");
  const double g = parse_real<double>(options.get("g", "1"), "--g", Domain::nonnegative);
  return Chain<double>(std::move(masses), std::move(lengths), g);
}

std::string deliver(const Options& options, std::string_view command, std::string text) {
  if (!options.has("output") || !is_root()) return text;
  write_atomically(std::string(options.get("output", "")), text, command);
  return {};
}

void check_output_option(const Options& options, std::string_view command) {
  if (!options.has("output")) return;
  const std::string path(options.get("output", ""));
  if (path.empty()) throw usage_error(std::string(command) + ": --output needs a file name");
  probe_output(path, command);
}

template <class Real>
std::string run_json(const Averages<Real>& a) {
  const std::span<const io::Field> fields = io::run_fields(a);
  if (fields.empty()) return "null";
  io::Record run(fields, 0);
  io::append_run(run, a);
  std::string out = "{";
  io::append_json_members(out, run);
  return out + "}";
}

template std::string run_json<double>(const Averages<double>&);
template std::string run_json<mpfr_real>(const Averages<mpfr_real>&);

}  // namespace pendavg::cli
