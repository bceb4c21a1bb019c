// SPDX-License-Identifier: GPL-3.0-or-later
// tests/fuzz/fuzz_args.cpp -- libFuzzer target: the command line. The input is argv without the
// program name, one argument per line ("average\n--masses\n1,1\n..."). Every command runs its
// option parser (args.cpp), its numbers, the average options (average_options.cpp), the
// sweep specs (table.cpp) and every check it makes before work, up to input_checked(); no file
// is touched (options naming files are left out; the --cases reader has its own target,
// fuzz_cases). Only requests whose work is short by construction run to the end: `average` and
// `limit` of N <= 2 in double (closed form for N = 1, the double-pendulum integral, a 1-D torus,
// the microcanonical integral rule; not qmc, whose samples and shifts the input chooses, nor the
// series, whose MPFR terms grow without a small bound as mu2 -> 1), and
// `simulate` of N <= 3 for at most 2000 steps.
//
// Invariants: no crash, leak or undefined behaviour; bad input is refused with
// pendavg::invalid_input (exit code 2) and a message, never with another exception (exit code 1);
// a computed result is valid JSON (or CSV/text) without a nan or inf anywhere.
#include "fuzz_common.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <optional>
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

/// The value of --name (as `--name value` or `--name=value`), if given.
std::optional<std::string_view> option(const std::vector<std::string>& args, std::string_view name) {
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string_view arg = args[i];
    if (arg == name && i + 1 < args.size()) return args[i + 1];
    if (arg.starts_with(name) && arg.size() > name.size() && arg[name.size()] == '=')
      return arg.substr(name.size() + 1);
  }
  return std::nullopt;
}

/// A number of the command line as strtod reads it (0 when it does not read).
double number(std::string_view text) {
  return std::strtod(std::string(text).c_str(), nullptr);
}

/// `simulate` of at most 2000 steps (and as many of burn-in) of a chain of N <= 3, one replica;
/// the exact values only for N <= 2 (microseconds to milliseconds).
bool short_simulation(const std::vector<std::string>& args) {
  const auto masses = option(args, "--masses");
  if (!masses || std::ranges::count(*masses, ',') > 2) return false;
  if (const auto replicas = option(args, "--replicas"); replicas && *replicas != "1") return false;
  const auto exact = option(args, "--exact");
  if (std::ranges::count(*masses, ',') > 1 && (!exact || *exact != "no")) return false;
  const auto time = option(args, "--time");
  const double dt = number(option(args, "--dt").value_or("1e-3"));
  const double burn_in = number(option(args, "--burn-in").value_or("0"));
  return time && number(*time) / dt <= 2000 && burn_in / dt <= 2000;
}

/// `average` or `limit` of one or two particles in double, not qmc or series; microcanonical
/// averages by the integral rule only (the torus rule converges algebraically): work of
/// milliseconds. And short simulations.
bool short_work(const std::vector<std::string>& args) {
  if (!args.empty() && args[0] == "simulate") return short_simulation(args);
  if (args.empty() || (args[0] != "average" && args[0] != "limit")) return false;
  const auto masses = option(args, "--masses");
  if (!masses || std::ranges::count(*masses, ',') > 1) return false;
  if (const auto digits = option(args, "--digits"); digits && *digits != "16") return false;
  const auto method = option(args, "--method");
  // Not qmc (the input chooses its samples), nor the series: its terms, in MPFR, grow as
  // mu2 -> 1 up to the 6000-term cap (masses 0.5,8.5: 640 evaluations, seconds under ASan).
  if (method && (*method == "qmc" || *method == "series")) return false;
  const bool microcanonical = option(args, "--energy") || option(args, "--excitation");
  return !microcanonical || !method || *method == "auto" || *method == "integral";
}

/// A minimal JSON reader (RFC 8259 values) that also collects every string value, for the
/// checks below.
class JsonReader {
 public:
  explicit JsonReader(std::string_view text) : text_(text) {}
  bool document() {
    space();
    if (!value()) return false;
    space();
    return at_ == text_.size();
  }
  const std::vector<std::string>& strings() const { return strings_; }

 private:
  bool value() {
    if (at_ >= text_.size()) return false;
    switch (text_[at_]) {
      case '{': return members('}', true);
      case '[': return members(']', false);
      case '"': return string(true);
      case 't': return word("true");
      case 'f': return word("false");
      case 'n': return word("null");
      default: return number();
    }
  }
  bool members(char close, bool object) {
    ++at_;
    space();
    if (peek(close)) return ++at_, true;
    for (;;) {
      space();
      if (object) {
        if (!string(false)) return false;
        space();
        if (!peek(':')) return false;
        ++at_;
        space();
      }
      if (!value()) return false;
      space();
      if (peek(close)) return ++at_, true;
      if (!peek(',')) return false;
      ++at_;
    }
  }
  bool string(bool keep) {
    if (!peek('"')) return false;
    std::string out;
    for (++at_; at_ < text_.size(); ++at_) {
      const char c = text_[at_];
      if (c == '"') {
        ++at_;
        if (keep) strings_.push_back(out);
        return true;
      }
      if (static_cast<unsigned char>(c) < 0x20) return false;
      if (c == '\\') {
        if (++at_ >= text_.size()) return false;
        if (text_[at_] == 'u') {
          if (at_ + 4 >= text_.size()) return false;
          for (int k = 1; k <= 4; ++k)
            if (!std::isxdigit(static_cast<unsigned char>(text_[at_ + k]))) return false;
          at_ += 4;
          continue;
        }
        if (std::string_view("\"\\/bfnrt").find(text_[at_]) == std::string_view::npos)
          return false;
      }
      out += c;
    }
    return false;
  }
  bool number() {
    const std::size_t start = at_;
    if (peek('-')) ++at_;
    if (peek('0')) ++at_;
    else if (!digits()) return false;
    if (peek('.') && (++at_, !digits())) return false;
    if (peek('e') || peek('E')) {
      ++at_;
      if (peek('+') || peek('-')) ++at_;
      if (!digits()) return false;
    }
    return at_ > start;
  }
  bool digits() {
    const std::size_t start = at_;
    while (at_ < text_.size() && text_[at_] >= '0' && text_[at_] <= '9') ++at_;
    return at_ > start;
  }
  bool word(std::string_view w) {
    if (text_.substr(at_, w.size()) != w) return false;
    at_ += w.size();
    return true;
  }
  bool peek(char c) const { return at_ < text_.size() && text_[at_] == c; }
  void space() {
    while (at_ < text_.size() && std::string_view(" \t\r\n").find(text_[at_]) != std::string_view::npos)
      ++at_;
  }

  std::string_view text_;
  std::size_t at_ = 0;
  std::vector<std::string> strings_;
};

/// True for a printed non-finite number: nan, -nan, nan(...), inf, -inf, infinity (any case).
bool non_finite(std::string_view token) {
  if (!token.empty() && (token.front() == '-' || token.front() == '+')) token.remove_prefix(1);
  std::string lower(token);
  for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return lower == "nan" || lower.starts_with("nan(") || lower == "inf" || lower == "infinity";
}

/// A finished command's output: JSON that reads, CSV or text cells that are not nan or inf.
void check_output(const std::string& output, std::string_view input) {
  if (output.empty()) pendavg::fuzz::fail("a finished command printed nothing", input);
  if (output.front() == '{') {
    JsonReader json(output);
    if (!json.document()) pendavg::fuzz::fail("invalid JSON: " + output, input);
    for (const std::string& value : json.strings())
      if (non_finite(value)) pendavg::fuzz::fail("a non-finite value in: " + output, input);
    return;
  }
  // CSV and text: every cell or word (limit's text names its row "beta -> inf").
  std::string cells = output;
  for (std::size_t at; (at = cells.find("-> inf")) != std::string::npos;) cells.erase(at, 6);
  std::size_t begin = 0;
  for (std::size_t i = 0; i <= cells.size(); ++i) {
    if (i < cells.size() && std::string_view(", \t\n").find(cells[i]) == std::string_view::npos)
      continue;
    if (non_finite(std::string_view(cells).substr(begin, i - begin)))
      pendavg::fuzz::fail("a non-finite value in: " + output, input);
    begin = i + 1;
  }
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
  const bool compute = short_work(args);
  const std::optional<std::string> output = pendavg::fuzz::run_command(args, input, compute);
  if (compute && output && !output->starts_with("usage:")) check_output(*output, input);
  return 0;
}
