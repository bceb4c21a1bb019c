// src/cli/files.hpp -- output files of the pendavg CLI, written atomically: everything goes to a
// temporary file next to the target, which is renamed onto it only when complete. A failed or
// abandoned file leaves nothing behind (the temporary is removed).
#pragma once

#include <string>
#include <string_view>

namespace pendavg::cli {

/// A file being written: open() creates the temporary, append() adds text, commit() makes it
/// appear under its name. Destroying an uncommitted file removes the temporary. Errors throw
/// usage_error "<command>: cannot write '<path>': <reason>".
class AtomicFile {
 public:
  AtomicFile(std::string path, std::string_view command);
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;
  ~AtomicFile();

  void append(std::string_view text);
  void commit();
  const std::string& path() const { return path_; }

 private:
  [[noreturn]] void fail(int error);
  std::string path_, command_, temporary_;
  int fd_ = -1;
  bool committed_ = false;
};

/// Writes `content` to `path` atomically (AtomicFile in one go).
void write_atomically(const std::string& path, const std::string& content, std::string_view command);

/// Fails early (before a long computation) when `path` cannot be written; leaves nothing behind.
void probe_output(const std::string& path, std::string_view command);

}  // namespace pendavg::cli
