// tests/fuzz/fuzz_args.cpp -- libFuzzer target: the command line. The input is argv without the
// program name, one argument per line ("average\n--masses\n1,1\n..."). Every command runs its
// option parser (args.cpp), its numbers, the average options (average_options.cpp), the
// sweep specs (table.cpp) and every check it makes before work, up to input_checked(): nothing is
// computed and no file is touched (options naming files are left out; the --cases reader has
// its own target, fuzz_cases).
//
// Invariants: no crash, leak or undefined behaviour; bad input is refused with
// pendavg::invalid_input (exit code 2) and a message, never with another exception (exit code 1).
#include "fuzz_common.hpp"

#include <charconv>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace {

/// How many values a sweep option of `table` gives (a list: its elements; lin:/log:A:B:N: N).
std::size_t sweep_values(std::string_view value) {
  if (value.starts_with("lin:") || value.starts_with("log:")) {
    const std::string_view count = value.substr(value.rfind(':') + 1);
    std::size_t n = 1;
    std::from_chars(count.data(), count.data() + count.size(), n);
    return n;
  }
  std::size_t n = 1;
  for (const char c : value) n += c == ',';
  return n;
}

/// An upper estimate of the points `table` checks before its work: the product of the sweeps.
/// Checking is linear in the points (up to 1e8 are allowed); the target keeps it short.
double sweep_points(const std::vector<std::string>& args) {
  double points = 1;
  for (std::size_t i = 0; i < args.size(); ++i) {
    for (const std::string_view name :
         {"--beta", "--energy", "--excitation", "--mu1", "--l1", "--l2", "--g", "--chain",
          "--digits"}) {
      const std::string_view arg = args[i];
      if (arg == name && i + 1 < args.size())
        points *= static_cast<double>(sweep_values(args[i + 1]));
      else if (arg.starts_with(name) && arg.size() > name.size() && arg[name.size()] == '=')
        points *= static_cast<double>(sweep_values(arg.substr(name.size() + 1)));
    }
  }
  return points;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view input(reinterpret_cast<const char*>(data), size);
  if (input.find('\0') != std::string_view::npos) return -1;  // argv strings end at NUL
  std::vector<std::string> args = pendavg::fuzz::split(input, '\n');
  if (!args.empty() && args.back().empty()) args.pop_back();  // a file's final newline
  if (args.size() > 64) return -1;
  for (const std::string& arg : args)
    if (pendavg::fuzz::names_a_file(arg)) return -1;
  if (sweep_points(args) > 2000) return -1;
  pendavg::fuzz::run_checks(args, input);
  return 0;
}
