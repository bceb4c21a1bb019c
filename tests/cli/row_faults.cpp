// SPDX-License-Identifier: GPL-3.0-or-later
// tests/cli/row_faults.cpp -- the test build of the command (pendavg_row_faults): the same
// objects as pendavg, with this definition of inject_row_fault (sweep.hpp) in place of the
// shipped one, which does nothing. PENDAVG_TEST_FAILING_ROWS=I,J,... (row indices, from 0) makes
// those rows of a sweep throw when they are computed: a row that fails late, after the check
// before the sweep passed it (the shipped command refuses the rows it can foresee failing
// before any is computed, so no input of the shipped command reproduces this reliably).
#include "cli/sweep.hpp"

#include <algorithm>
#include <cstdlib>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace pendavg::cli {

namespace {

std::vector<std::size_t> failing_rows() {
  std::vector<std::size_t> rows;
  const char* list = std::getenv("PENDAVG_TEST_FAILING_ROWS");
  for (const char* p = list ? list : ""; *p != '\0';) {
    char* end = nullptr;
    rows.push_back(std::strtoull(p, &end, 10));
    p = *end == ',' ? end + 1 : end;
    if (end == p && *p != '\0') break;
  }
  std::ranges::sort(rows);
  return rows;
}

}  // namespace

void inject_row_fault(std::size_t index) {
  static const std::vector<std::size_t> rows = failing_rows();
  if (std::ranges::binary_search(rows, index))
    throw std::runtime_error("a failure injected into this row by the test build "
                             "(PENDAVG_TEST_FAILING_ROWS)");
}

}  // namespace pendavg::cli
