// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/files.hpp -- output files of the pendavg CLI, written atomically: everything goes to a
// temporary file next to the target, which is renamed onto it only when complete. A failed or
// abandoned file leaves nothing behind (the temporary is removed), and SIGINT/SIGTERM/SIGHUP are
// deferred while the temporary exists (interrupt.hpp, DeferSignals), so no signal leaves one
// behind either. A temporary is named "<target>.tmp.<host>.<pid>.XXXXXX"; one left by a process
// that was killed outright (SIGKILL, a crash: no handler runs) holds the rows that process had
// written: --resume of the target on the same host takes them (sweep_file.hpp), and the next
// commit of the target there removes it. A symbolic link is followed: its final target is what
// gets replaced. A target that exists and is not a regular file (a device such as /dev/null, a
// FIFO) is written in place, never replaced; a FIFO that no process reads is refused (an open
// would wait forever). A replaced file keeps its permissions (and its owner and group when the process
// may give them). A file with several hard links is refused: replacing it would leave the other
// links with the old content, and writing it in place would not be atomic. A target's name may
// be as long as the file system allows (its temporary's name is cut to fit).
#pragma once

#include "interrupt.hpp"

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace pendavg::cli {

/// A file being written: the constructor creates the temporary (or opens a non-regular target),
/// append() adds text, commit() makes it appear under its name. Destroying an uncommitted file
/// removes the temporary. Errors throw usage_error "<command>: cannot write '<path>': <reason>".
class AtomicFile {
 public:
  AtomicFile(std::string path, std::string_view command);
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;
  ~AtomicFile();

  void append(std::string_view text);
  void commit();
  const std::string& path() const { return path_; }
  /// The target is not a regular file (a device, a FIFO): written in place, no temporary.
  bool in_place() const { return in_place_; }

 private:
  [[noreturn]] void fail(int error);
  std::string path_, command_, target_, temporary_;
  std::optional<DeferSignals> deferred_;  ///< while a temporary exists
  int fd_ = -1;
  bool committed_ = false, in_place_ = false;
};

/// The temporaries of `target` (a resolved path) that a process of this host left when it was
/// killed: "<target>.tmp.<host>.<pid>.XXXXXX" whose pid no longer exists, in name order.
/// Temporaries of other hosts (a shared file system) and of live processes are not listed.
std::vector<std::string> dead_temporaries(const std::string& target);

/// Writes `content` to `path` atomically (AtomicFile in one go).
void write_atomically(const std::string& path, const std::string& content, std::string_view command);

/// Fails early (before a long computation) when `path` cannot be written; leaves nothing behind.
void probe_output(const std::string& path, std::string_view command);

/// The file a path names after following symbolic links (the path itself when it does not
/// exist yet); throws usage_error for a loop of links.
std::string resolved_path(const std::string& path, std::string_view command);

/// Refuses (usage_error, one line) an output path that names the same file as an input path
/// (or as another output): `--<output_option> X` would overwrite what `--<input_option>` reads
/// (an `input_option` with a space says what the input is, e.g. "a shard", and is shown as is).
void refuse_same_file(const std::string& output, std::string_view output_option,
                      const std::string& input, std::string_view input_option,
                      std::string_view command);

}  // namespace pendavg::cli
