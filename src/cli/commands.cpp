// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/commands.cpp -- the dispatch of the pendavg CLI: one table of the commands (each in its
// own file: average.cpp, limit.cpp, series.cpp, table.cpp, simulate.cpp, poincare.cpp, merge's
// in shard.cpp), the general usage, --help and --version.
#include "commands.hpp"

#include "common.hpp"
#include "distribute.hpp"
#include "version_info.hpp"

#include "io/results.hpp"

#include <algorithm>
#include <array>
#include <functional>
#include <string>
#include <string_view>

namespace pendavg::cli {

namespace {

constexpr std::string_view general_usage =
    "pendavg -- thermal averages of the kinetic energy of a planar multiple pendulum\n"
    "(Konishi & Yanagita): beta<K_i>, <cos phi_i>, Var K_i, with error estimates.\n"
    "\n"
    "usage:\n"
    "  pendavg average --masses M1,...,MN --lengths L1,...,LN [--g G] --beta B [options]\n"
    "  pendavg average --masses ... --lengths ... (--energy E | --excitation D) [options]\n"
    "  pendavg average --cases FILE.csv [--digits D] [--method M] [method options] [--columns LIST] [--timing]\n"
    "  pendavg limit   --masses M1,M2 [--lengths L1,L2] [--g G] [--digits D] [--format F]\n"
    "  pendavg series  --masses M1,M2 --lengths L1,L2 [--g G] --beta B [--terms N] [options]\n"
    "  pendavg table   --beta SPEC [--mu1 SPEC] [--l2 SPEC] [--g SPEC] ... [--chain LIST] [--digits LIST] [--output FILE.csv]\n"
    "  pendavg table   (--energy SPEC | --excitation SPEC) ...: microcanonical sweeps\n"
    "  pendavg simulate --masses ... --lengths ... (--theta A | --phi ...) --time T [options]\n"
    "  pendavg poincare --masses M1,M2 --lengths L1,L2 --energy E [--orbits K] [--points P]\n"
    "  pendavg merge   --output FILE SHARD...: the files of table/average --cases --shard K/N\n"
    "  pendavg help [COMMAND]     pendavg COMMAND --help     pendavg --version\n"
    "  pendavg help schema        every output field: names, kinds, meaning (output schema)\n"
    "  pendavg help migration     the names that changed from pendavg 0.2 (schema 0)\n"
    "\n"
    "Numbers are plain decimals (0.5, 1e-3). --digits D (16..1000, default 16) is the number of\n"
    "significant digits requested: 16 runs in double, more in MPFR. Bad input exits with 2.\n";

const std::array<const Command*, 7> commands{&average_command, &limit_command, &series_command,
                                             &table_command,   &simulate_command, &poincare_command,
                                             &merge_command};

const Command& find_command(std::string_view name) {
  const auto found = std::ranges::find_if(commands, [&](const Command* c) { return c->name == name; });
  if (found == commands.end())
    throw usage_error("unknown command '" + std::string(name) + "' (try 'pendavg --help')");
  return **found;
}

std::function<void(std::string_view)>& input_checked_hook() {
  static std::function<void(std::string_view)> hook;
  return hook;
}

}  // namespace

void input_checked(std::string_view command) {
  if (input_checked_hook()) input_checked_hook()(command);
}

void set_input_checked_hook(std::function<void(std::string_view command)> hook) {
  input_checked_hook() = std::move(hook);
}

std::string run(std::span<const std::string_view> args) {
  if (args.empty()) throw usage_error("no command given (try 'pendavg --help')");
  const std::string_view name = args.front();
  const auto rest = args.subspan(1);
  if (name == "--help" || name == "-h" || (name == "help" && rest.empty()))
    return std::string(general_usage);
  if (name == "help" && rest.front() == "schema") return io::schema_text();
  if (name == "help" && rest.front() == "migration") return io::migration_text();
  if (name == "help") return std::string(find_command(rest.front()).usage);
  if (name == "--version") return version_text();
  const Command& command = find_command(name);
  if (asks_for_help(rest)) return std::string(command.usage);
  set_digits_advice(std::ranges::find(command.options, "digits") != command.options.end());
  const Options options(name, rest, command.options, command.flags, command.operands);
  if (!command.distributed && !is_root()) return {};
  return command.run(options);
}

}  // namespace pendavg::cli
