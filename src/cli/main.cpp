// src/cli/main.cpp -- entry point of the `pendavg` command-line tool: runs one command, writes its
// output to stdout in one piece, and maps failures to exit codes (2 bad input, 1 internal error,
// 130 stopped by a signal before anything was finished), each with exactly one line on stderr.
#include "commands.hpp"

#include "pendavg/chain.hpp"
#include "pendavg/result.hpp"

#include <algorithm>
#include <cstdio>
#include <exception>
#include <string>
#include <string_view>
#include <vector>

namespace {

constexpr int exit_bad_input = 2;
constexpr int exit_internal_error = 1;
constexpr int exit_interrupted = 130;  // 128 + SIGINT, as a shell reports it

int report(std::string_view kind, std::string message, int exit_code) {
  std::ranges::replace(message, '\n', ' ');  // one line, whatever the message
  std::fprintf(stderr, "pendavg: %.*s: %s\n", static_cast<int>(kind.size()), kind.data(),
               message.c_str());
  return exit_code;
}

}  // namespace

int main(int argc, char** argv) {
  const std::vector<std::string_view> args(argv + 1, argv + argc);
  try {
    const std::string output = pendavg::cli::run(args);
    if (std::fwrite(output.data(), 1, output.size(), stdout) != output.size() ||
        std::fflush(stdout) != 0)
      return report("internal error", "cannot write to stdout", exit_internal_error);
    return 0;
  } catch (const pendavg::invalid_input& bad) {
    return report("error", bad.what(), exit_bad_input);
  } catch (const pendavg::interrupted& stopped) {
    return report("interrupted", stopped.what(), exit_interrupted);
  } catch (const std::exception& failure) {
    return report("internal error", failure.what(), exit_internal_error);
  } catch (...) {
    return report("internal error", "unknown exception", exit_internal_error);
  }
}
