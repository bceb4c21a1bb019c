// engine/text.hpp -- numbers in the engines' one-line error messages.
#pragma once

#include <cstdio>
#include <string>

namespace pendavg {

/// x with 3 significant digits ("2e+303", "0.125"), for messages.
inline std::string short_decimal(long double x) {
  char buffer[48];
  std::snprintf(buffer, sizeof buffer, "%.3Lg", x);
  return buffer;
}

}  // namespace pendavg
