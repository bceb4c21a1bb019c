// src/cli/files.cpp -- atomic output files (see files.hpp).
#include "files.hpp"

#include "args.hpp"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <utility>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

namespace pendavg::cli {

namespace {

std::string cannot_write(std::string_view command, const std::string& path, std::string_view why) {
  return std::string(command) + ": cannot write '" + path + "': " + std::string(why);
}

}  // namespace

AtomicFile::AtomicFile(std::string path, std::string_view command)
    : path_(std::move(path)), command_(command) {
  std::error_code ec;
  if (std::filesystem::is_directory(path_, ec))
    throw usage_error(cannot_write(command_, path_, "is a directory"));
  temporary_ = path_ + ".tmp.XXXXXX";
  fd_ = mkstemp(temporary_.data());
  if (fd_ < 0) throw usage_error(cannot_write(command_, path_, std::strerror(errno)));
  const mode_t mask = umask(0);
  umask(mask);
  if (fchmod(fd_, 0666 & ~mask) != 0) fail(errno);
}

AtomicFile::~AtomicFile() {
  if (fd_ >= 0) close(fd_);
  if (!committed_ && !temporary_.empty()) unlink(temporary_.c_str());
}

void AtomicFile::fail(int error) {
  if (fd_ >= 0) close(fd_);
  fd_ = -1;
  unlink(temporary_.c_str());
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
  if (fsync(fd_) != 0) fail(errno);
  const int fd = fd_;
  fd_ = -1;
  if (close(fd) != 0) {
    const int error = errno;
    unlink(temporary_.c_str());
    throw usage_error(cannot_write(command_, path_, std::strerror(error)));
  }
  if (std::rename(temporary_.c_str(), path_.c_str()) != 0) {
    const int error = errno;
    unlink(temporary_.c_str());
    throw usage_error(cannot_write(command_, path_, std::strerror(error)));
  }
  committed_ = true;
}

void write_atomically(const std::string& path, const std::string& content,
                      std::string_view command) {
  AtomicFile file(path, command);
  file.append(content);
  file.commit();
}

void probe_output(const std::string& path, std::string_view command) {
  AtomicFile file(path, command);  // created and removed again: the directory is writable
}

}  // namespace pendavg::cli
