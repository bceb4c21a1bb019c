// The CLI's printed errors (src/cli/format.cpp, printed_error): the error printed beside a value
// printed with `digits` digits adds half a unit in the value's last printed place, so it covers
// the printing's rounding. Checked exactly: the printed text read in MPFR at 400 digits.
#include <catch2/catch.hpp>

#include "cli/format.hpp"

#include "pendavg/mpfr.hpp"

#include <cmath>
#include <limits>
#include <string>

namespace {

/// |decimal(x, digits) - x|, exactly enough (400 digits).
pendavg::mpfr_real printing_rounding(double x, int digits) {
  const std::string text = pendavg::cli::decimal(x, digits);
  const pendavg::working_precision precision(400);
  pendavg::mpfr_real printed;
  mpfr_set_str(printed.backend().data(), text.c_str(), 10, MPFR_RNDN);
  return abs(printed - pendavg::mpfr_real(x));
}

}  // namespace

// Found by tests/fuzz/fuzz_number: below 1e-292 the half unit 10^(e - digits + 1) / 2 is
// subnormal in double (a few significant bits) and below 1e-324 it was 0, so a value such as
// 4.9406564584124654e-324 printed with 17 digits had a printed error of 0.
TEST_CASE("printed errors cover the printing of tiny values (subnormal half units)",
          "[cli][format]") {
  const double smallest = std::numeric_limits<double>::denorm_min();
  for (const double x : {smallest, 7 * smallest, 3.0e-320, 1.2345678901234567e-310,
                         std::numeric_limits<double>::min(), 4.4501477170144023e-308,
                         1.0000000000000002e-300, 3.3e-295, 0.1, -123.456}) {
    for (const int digits : {1, 3, 16, 17}) {
      INFO("x = " << pendavg::cli::decimal(x, 17) << ", " << digits << " digits");
      const double covered = pendavg::cli::printed_error(x, 0.0, digits);
      CHECK(covered > 0);
      CHECK(printing_rounding(x, digits) <= pendavg::mpfr_real(covered));
      // A computed error adds to it: still covered, and never less than the error itself.
      const double error = 1e-3 * std::abs(x);
      CHECK(pendavg::cli::printed_error(x, error, digits) >= error);
      CHECK(printing_rounding(x, digits) <=
            pendavg::mpfr_real(pendavg::cli::printed_error(x, error, digits)));
    }
  }
}
