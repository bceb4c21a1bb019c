// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/main.cpp -- entry point of the `pendavg` command-line tool: joins the MPI job when
// started as one (distribute.hpp), runs one command, writes its output to stdout in one piece
// (commands that stream, such as table, write it themselves), and maps failures to exit codes
// (2 bad input, 1 internal error, 130 stopped by a signal before anything was finished), each
// with exactly one line on stderr (distribute.hpp, report_failure); a sweep that wrote its output
// but has failed rows exits with 3 (sweep.hpp, rows_failed). Under MPI only rank 0 prints.
#include "args.hpp"
#include "commands.hpp"
#include "distribute.hpp"

#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <exception>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

int main(int argc, char** argv) {
  // A file size limit (ulimit -f) is then a write error as a full disk is (EFBIG): the command
  // says so in one line and removes its temporary, where SIGXFSZ would kill it and leave both.
  std::signal(SIGXFSZ, SIG_IGN);
  const pendavg::cli::ProcessGroup processes(argc, argv);
  const std::vector<std::string_view> args(argv + 1, argv + argc);
  try {
    const std::string output = pendavg::cli::run(args);
    if (!pendavg::cli::is_root()) return 0;
    if (std::fwrite(output.data(), 1, output.size(), stdout) != output.size() ||
        std::fflush(stdout) != 0)
      // As an --output that cannot be written (a full disk, ulimit -f): exit 2.
      return pendavg::cli::report_failure(std::make_exception_ptr(pendavg::cli::usage_error(
          std::string("cannot write to stdout: ") + std::strerror(errno))));
    return 0;
  } catch (...) {
    return pendavg::cli::report_failure(std::current_exception());
  }
}
