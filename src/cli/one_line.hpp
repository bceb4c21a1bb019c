// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/one_line.hpp -- the text of a message line that may echo what a user gave (an
// argument, a field of a cases file): printed as one line that a terminal shows as it is.
// Control characters (C0 but newline, DEL, C1, U+2028/U+2029) and bytes that are not UTF-8
// would move the cursor, clear the screen, recolour the terminal or break the line in a log
// viewer: they are escaped (\xNN for a byte, \uNNNN for a character); a newline becomes a space
// (messages joined from several lines read on). An echoed value can be any length (a 1 MB
// number): a run of more than long_word characters without a space (longer than almost any
// path) keeps its first kept_characters and says how long it was, and the whole line is cut at
// max_characters.
#pragma once

#include <cstddef>
#include <cstdio>
#include <string>
#include <string_view>

namespace pendavg::cli {

namespace one_line_limits {
inline constexpr std::size_t long_word = 256;       ///< longer runs without a space are cut
inline constexpr std::size_t kept_characters = 40;  ///< of a cut run
inline constexpr std::size_t max_characters = 2000; ///< of the whole line
}  // namespace one_line_limits

namespace one_line_detail {

/// The length of the UTF-8 sequence at `text[i]` (1..4) and its code point, or 0 when the bytes
/// there are not a valid sequence (overlong forms and surrogates count as invalid).
inline std::size_t utf8_sequence(std::string_view text, std::size_t i, char32_t& code) {
  const auto byte = [&](std::size_t k) { return static_cast<unsigned char>(text[k]); };
  const unsigned char lead = byte(i);
  std::size_t length = 0;
  char32_t minimum = 0;
  if (lead < 0x80) {
    code = lead;
    return 1;
  } else if ((lead & 0xE0) == 0xC0) {
    length = 2, code = lead & 0x1F, minimum = 0x80;
  } else if ((lead & 0xF0) == 0xE0) {
    length = 3, code = lead & 0x0F, minimum = 0x800;
  } else if ((lead & 0xF8) == 0xF0) {
    length = 4, code = lead & 0x07, minimum = 0x10000;
  } else {
    return 0;
  }
  if (text.size() - i < length) return 0;
  for (std::size_t k = 1; k < length; ++k) {
    if ((byte(i + k) & 0xC0) != 0x80) return 0;
    code = (code << 6) | (byte(i + k) & 0x3F);
  }
  if (code < minimum || code > 0x10FFFF || (code >= 0xD800 && code <= 0xDFFF)) return 0;
  return length;
}

/// `text` with every control character escaped (see above); a newline becomes a space.
inline std::string escaped(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  char buffer[16];
  for (std::size_t i = 0; i < text.size();) {
    char32_t code = 0;
    const std::size_t length = utf8_sequence(text, i, code);
    if (length == 0) {  // not UTF-8: the byte
      std::snprintf(buffer, sizeof buffer, "\\x%02x", static_cast<unsigned char>(text[i]));
      out += buffer;
      ++i;
      continue;
    }
    if (code == '\n') {
      out += ' ';
    } else if (code < 0x20 || code == 0x7F) {
      std::snprintf(buffer, sizeof buffer, "\\x%02x", static_cast<unsigned>(code));
      out += buffer;
    } else if ((code >= 0x80 && code <= 0x9F) || code == 0x2028 || code == 0x2029) {
      std::snprintf(buffer, sizeof buffer, "\\u%04x", static_cast<unsigned>(code));
      out += buffer;
    } else {
      out.append(text.substr(i, length));
    }
    i += length;
  }
  return out;
}

/// The characters (not bytes) of UTF-8 `text`.
inline std::size_t characters(std::string_view text) {
  std::size_t count = 0;
  for (const char c : text) count += (static_cast<unsigned char>(c) & 0xC0) != 0x80;
  return count;
}

/// The byte offset after the first `n` characters of `text` (all of it when shorter).
inline std::size_t after_characters(std::string_view text, std::size_t n) {
  std::size_t i = 0;
  for (std::size_t seen = 0; i < text.size(); ++i) {
    if ((static_cast<unsigned char>(text[i]) & 0xC0) != 0x80) {
      if (seen == n) break;
      ++seen;
    }
  }
  return i;
}

}  // namespace one_line_detail

/// `text` as one line with every character kept (escaped as above), never cut: a name written
/// into a file's header line.
inline std::string escaped_line(std::string_view text) { return one_line_detail::escaped(text); }

/// `text` made safe to print as one line (see above).
inline std::string one_line(std::string_view text) {
  using namespace one_line_limits;
  using namespace one_line_detail;
  const std::string clean = escaped(text);
  std::string out;
  out.reserve(std::min(clean.size(), max_characters * 4 + 64));
  for (std::size_t i = 0; i < clean.size();) {
    if (clean[i] == ' ') {
      out += ' ';
      ++i;
      continue;
    }
    const std::size_t end = std::min(clean.find(' ', i), clean.size());
    const std::string_view word = std::string_view(clean).substr(i, end - i);
    const std::size_t length = characters(word);
    if (length > long_word) {
      out.append(word.substr(0, after_characters(word, kept_characters)));
      out += "... (" + std::to_string(length) + " characters)";
    } else {
      out.append(word);
    }
    i = end;
  }
  const std::size_t length = characters(out);
  if (length > max_characters) {
    out.resize(after_characters(out, max_characters));
    out += "... (" + std::to_string(length) + " characters)";
  }
  return out;
}

}  // namespace pendavg::cli
