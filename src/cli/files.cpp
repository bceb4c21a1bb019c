// SPDX-License-Identifier: GPL-3.0-or-later
// src/cli/files.cpp -- atomic output files (see files.hpp).
#include "files.hpp"

#include "args.hpp"

#include <algorithm>
#include <cerrno>
#include <climits>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <utility>
#include <vector>

#include <dirent.h>
#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

namespace pendavg::cli {

namespace {

std::string cannot_write(std::string_view command, const std::string& path, std::string_view why) {
  return std::string(command) + ": cannot write '" + path + "': " + std::string(why);
}

constexpr int max_symlinks = 40;  // as the kernel's ELOOP limit

/// "<host>.<pid>." of this process: the part of a temporary's name after "<target>.tmp." that
/// says who wrote it (host names reduced to [A-Za-z0-9-], at most 64 characters).
std::string writer_tag(long pid) {
  char host[256] = {};
  if (gethostname(host, sizeof host - 1) != 0) host[0] = '\0';
  std::string tag;
  for (const char* c = host; *c != '\0' && tag.size() < 64; ++c)
    if ((*c >= 'a' && *c <= 'z') || (*c >= 'A' && *c <= 'Z') || (*c >= '0' && *c <= '9') || *c == '-')
      tag += *c;
  if (tag.empty()) tag = "host";
  return tag + "." + std::to_string(pid) + ".";
}

/// The longest name in `directory` (NAME_MAX, 255 on Linux file systems).
std::size_t longest_name(const std::filesystem::path& directory) {
  const long most = pathconf(directory.c_str(), _PC_NAME_MAX);
  return most > 0 ? static_cast<std::size_t>(most) : std::size_t(NAME_MAX);
}

/// The part of a temporary's name before ".tmp.<host>.<pid>.XXXXXX": the target's name, cut
/// so that the whole name fits the directory's longest name (a target's name may be as long
/// as that itself). A cut name can be shared by two targets; their temporaries still differ
/// (pid and random part), and a stale one of either is garbage.
std::string temporary_stem(const std::filesystem::path& target) {
  const std::filesystem::path parent =
      target.has_parent_path() ? target.parent_path() : std::filesystem::path(".");
  const std::string name = target.filename().string();
  // ".tmp." + "<host>." (at most 65) + "<pid>." (at most 20) + "XXXXXX"
  constexpr std::size_t suffix = 5 + 65 + 20 + 6;
  const std::size_t most = longest_name(parent);
  return name.size() + suffix <= most || most <= suffix ? name : name.substr(0, most - suffix);
}

/// Whether process `pid` has ended: gone, or a zombie (ended, not yet reaped: when its parent
/// was killed too -- all of an mpirun's ranks -- a container's first process may reap it only
/// seconds later).
bool process_ended(long pid) {
  if (kill(static_cast<pid_t>(pid), 0) != 0) return errno == ESRCH;
  std::ifstream stat("/proc/" + std::to_string(pid) + "/stat");
  std::string text;
  std::getline(stat, text);
  const std::size_t name_end = text.rfind(')');  // "pid (name) state ..."
  return name_end != std::string::npos && name_end + 2 < text.size() && text[name_end + 2] == 'Z';
}

/// Opens a target that is not a regular file (a device, a FIFO) for writing. A FIFO without a
/// reader would block the open forever: it is opened without blocking (ENXIO when nobody reads
/// it: refused), then made blocking again for the writes.
int open_in_place(const std::string& path, std::string_view command) {
  const int fd = open(path.c_str(), O_WRONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) {
    if (errno == ENXIO)
      throw usage_error(cannot_write(command, path, "it is a FIFO that no process reads"));
    throw usage_error(cannot_write(command, path, std::strerror(errno)));
  }
  const int flags = fcntl(fd, F_GETFL);
  if (flags < 0 || fcntl(fd, F_SETFL, flags & ~O_NONBLOCK) != 0) {
    const int error = errno;
    close(fd);
    throw usage_error(cannot_write(command, path, std::strerror(error)));
  }
  return fd;
}

}  // namespace

std::vector<std::string> dead_temporaries(const std::string& target) {
  namespace fs = std::filesystem;
  const fs::path path = target;
  const fs::path parent = path.has_parent_path() ? path.parent_path() : fs::path(".");
  const std::string host_prefix = temporary_stem(path) + ".tmp." + writer_tag(0);
  const std::string prefix = host_prefix.substr(0, host_prefix.size() - 2);  // "<...>.<host>."
  std::vector<std::string> dead;
  DIR* dir = opendir(parent.c_str());
  if (dir == nullptr) return dead;
  while (const dirent* entry = readdir(dir)) {
    const std::string_view name = entry->d_name;
    if (!name.starts_with(prefix)) continue;
    const std::string_view rest = name.substr(prefix.size());  // "<pid>.XXXXXX"
    const std::size_t dot = rest.find('.');
    if (dot == 0 || dot == std::string_view::npos || rest.size() - dot != 7) continue;
    long pid = 0;
    bool digits = true;
    for (const char c : rest.substr(0, dot)) {
      if (c < '0' || c > '9' || pid > 1'000'000'000) digits = false;
      pid = pid * 10 + (c - '0');
    }
    if (digits && pid > 0 && process_ended(pid))
      dead.push_back((parent / std::string(name)).string());
  }
  closedir(dir);
  std::ranges::sort(dead);  // a fixed order, whatever the directory's
  return dead;
}

std::string resolved_path(const std::string& path, std::string_view command) {
  namespace fs = std::filesystem;
  fs::path current = path;
  for (int hops = 0;; ++hops) {
    struct stat status {};
    if (lstat(current.c_str(), &status) != 0 || !S_ISLNK(status.st_mode)) return current.string();
    if (hops == max_symlinks)
      throw usage_error(cannot_write(command, path, "too many levels of symbolic links"));
    std::string link(PATH_MAX, '\0');
    const ssize_t length = readlink(current.c_str(), link.data(), link.size());
    if (length < 0) throw usage_error(cannot_write(command, path, std::strerror(errno)));
    link.resize(static_cast<std::size_t>(length));
    const fs::path target = link;
    current = target.is_absolute() ? target : current.parent_path() / target;
  }
}

AtomicFile::AtomicFile(std::string path, std::string_view command)
    : path_(std::move(path)), command_(command) {
  // The path as the kernel follows it first: /dev/stdout onto a pipe is a link to "pipe:[N]",
  // which names no file that readlink could follow.
  struct stat status {};
  const bool exists = stat(path_.c_str(), &status) == 0;
  if (exists) {
    if (S_ISDIR(status.st_mode)) throw usage_error(cannot_write(command_, path_, "is a directory"));
    if (!S_ISREG(status.st_mode)) {
      // A device, FIFO or socket: written in place (never replaced by a regular file).
      in_place_ = true;
      target_ = path_;
      fd_ = open_in_place(path_, command_);
      return;
    }
    // Replacing the file (a new inode renamed onto the name) would leave its other hard links
    // with the old content, silently; writing it in place would lose the atomicity (a failed or
    // interrupted run would leave every link with a partial file). Neither keeps work safe:
    // refused, with what to do.
    if (status.st_nlink > 1)
      throw usage_error(cannot_write(
          command_, path_,
          "it has " + std::to_string(status.st_nlink) +
              " hard links, which replacing it would leave with the old content; remove the "
              "other links, or write another file"));
  }
  target_ = resolved_path(path_, command_);  // a regular file: replace it, not a link to it
  deferred_.emplace();
  {
    const std::filesystem::path target = target_;
    temporary_ = (target.parent_path() / (temporary_stem(target) + ".tmp." +
                                          writer_tag(static_cast<long>(getpid())) + "XXXXXX"))
                     .string();
  }
  fd_ = mkostemp(temporary_.data(), O_CLOEXEC);
  if (fd_ < 0) {
    const int error = errno;
    temporary_.clear();
    deferred_.reset();
    throw usage_error(cannot_write(command_, path_, std::strerror(error)));
  }
  if (exists) {
    // A rewritten file keeps its permissions (0600 stays 0600), and its owner and group when
    // this process may give them (root, or a group it is in; otherwise they become the
    // writer's, as for any file it creates).
    if (fchmod(fd_, status.st_mode & 07777) != 0) fail(errno);
    if (fchown(fd_, status.st_uid, status.st_gid) != 0)
      (void)!fchown(fd_, static_cast<uid_t>(-1), status.st_gid);
    return;
  }
  const mode_t mask = umask(0);
  umask(mask);
  if (fchmod(fd_, 0666 & ~mask) != 0) fail(errno);
}

AtomicFile::~AtomicFile() {
  if (fd_ >= 0) close(fd_);
  if (!committed_ && !temporary_.empty()) unlink(temporary_.c_str());
  // deferred_ is released last (member order): a deferred signal acts after the cleanup.
}

void AtomicFile::fail(int error) {
  if (fd_ >= 0) close(fd_);
  fd_ = -1;
  if (!temporary_.empty()) unlink(temporary_.c_str());
  temporary_.clear();
  throw usage_error(cannot_write(command_, path_, std::strerror(error)));
}

void AtomicFile::append(std::string_view text) {
  for (std::size_t written = 0; written < text.size();) {
    const ssize_t n = write(fd_, text.data() + written, text.size() - written);
    if (n < 0) {
      if (errno != EINTR) fail(errno);
    } else {
      written += static_cast<std::size_t>(n);
    }
  }
}

void AtomicFile::commit() {
  if (in_place_) {
    const int fd = fd_;
    fd_ = -1;
    committed_ = true;
    if (close(fd) != 0 && errno != EINTR)
      throw usage_error(cannot_write(command_, path_, std::strerror(errno)));
    return;
  }
  if (fsync(fd_) != 0) fail(errno);
  const int fd = fd_;
  fd_ = -1;
  if (close(fd) != 0) {
    const int error = errno;
    unlink(temporary_.c_str());
    throw usage_error(cannot_write(command_, path_, std::strerror(error)));
  }
  if (std::rename(temporary_.c_str(), target_.c_str()) != 0) {
    const int error = errno;
    unlink(temporary_.c_str());
    throw usage_error(cannot_write(command_, path_, std::strerror(error)));
  }
  committed_ = true;
  deferred_.reset();
  // Only now: a dead writer's rows, which --resume took (ResumedRows), are in the file.
  for (const std::string& dead : dead_temporaries(target_)) unlink(dead.c_str());
}

void write_atomically(const std::string& path, const std::string& content,
                      std::string_view command) {
  AtomicFile file(path, command);
  file.append(content);
  file.commit();
}

void probe_output(const std::string& path, std::string_view command) {
  struct stat status {};
  if (stat(path.c_str(), &status) == 0 && !S_ISDIR(status.st_mode) && !S_ISREG(status.st_mode)) {
    // A device or FIFO: ask for write permission (a FIFO is not opened here: its reader would
    // see the end of its input; the output's own open refuses one that nobody reads).
    if (access(path.c_str(), W_OK) != 0)
      throw usage_error(cannot_write(command, path, std::strerror(errno)));
    return;
  }
  AtomicFile file(path, command);  // created and removed again: the directory is writable
}

void refuse_same_file(const std::string& output, std::string_view output_option,
                      const std::string& input, std::string_view input_option,
                      std::string_view command) {
  struct stat out_status {}, in_status {};
  bool same = false;
  if (stat(output.c_str(), &out_status) == 0 && stat(input.c_str(), &in_status) == 0) {
    same = out_status.st_dev == in_status.st_dev && out_status.st_ino == in_status.st_ino &&
           S_ISREG(out_status.st_mode);  // two names of /dev/null are no conflict
  } else {
    std::error_code ec1, ec2;
    const auto a = std::filesystem::weakly_canonical(resolved_path(output, command), ec1);
    const auto b = std::filesystem::weakly_canonical(resolved_path(input, command), ec2);
    same = !ec1 && !ec2 && a == b;
  }
  if (same)
    throw usage_error(std::string(command) + ": --" + std::string(output_option) + " '" + output +
                      "' names the same file as " +
                      (input_option.find(' ') == std::string_view::npos ? "--" : "") +
                      std::string(input_option) +
                      ", which writing it would overwrite; choose another file");
}

}  // namespace pendavg::cli
