#include "hal/recording/line_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <stdexcept>
#include <system_error>

namespace rilo::recording {
namespace {

[[noreturn]] void throwErrno(const std::string& what, const std::string& path) {
  throw std::system_error(errno, std::generic_category(), what + " " + path);
}

void writeAll(int fd, const char* data, std::size_t size, std::size_t& written, const std::string& path) {
  while (written < size) {
    const ssize_t n = ::write(fd, data + written, size - written);
    if (n < 0) {
      if (errno == EINTR) continue;
      throwErrno("write", path);
    }
    written += static_cast<std::size_t>(n);
  }
}

int openForWrite(const std::string& path, bool overwrite) {
  const int flags = O_WRONLY | O_CREAT | O_CLOEXEC | (overwrite ? O_TRUNC : O_EXCL);
  const int fd = ::open(path.c_str(), flags, 0644);
  if (fd < 0) throwErrno(errno == EEXIST ? "refusing to overwrite existing file" : "cannot create", path);
  return fd;
}

}  // namespace

LineFile::~LineFile() {
  if (fd_ >= 0) ::close(fd_);
}

void LineFile::open(const std::filesystem::path& path, bool overwrite, std::size_t buffer_reserve) {
  if (fd_ >= 0) throw std::logic_error("LineFile::open: already open: " + path_);
  path_ = path.string();
  fd_ = openForWrite(path_, overwrite);
  buf_.clear();
  buf_.reserve(buffer_reserve);
}

void LineFile::flush(bool sync) {
  if (fd_ < 0) return;
  std::size_t written = 0;
  try {
    writeAll(fd_, buf_.data(), buf_.size(), written, path_);
  } catch (...) {
    buf_.erase(0, written);  // a retry continues exactly where the kernel stopped
    throw;
  }
  buf_.clear();
  if (sync && ::fdatasync(fd_) != 0) throwErrno("fdatasync", path_);
}

void LineFile::close(bool sync) {
  if (fd_ < 0) return;
  flush(sync);
  const int fd = fd_;
  fd_ = -1;
  if (::close(fd) != 0) throwErrno("close", path_);
}

void writeFileAtomically(const std::filesystem::path& path, std::string_view text, bool overwrite, bool sync) {
  const std::string target = path.string();
  if (!overwrite && ::access(target.c_str(), F_OK) == 0) {
    errno = EEXIST;
    throwErrno("refusing to overwrite existing file", target);
  }
  const std::string tmp = target + ".tmp";
  const int fd = openForWrite(tmp, true);
  std::size_t written = 0;
  try {
    writeAll(fd, text.data(), text.size(), written, tmp);
    if (sync && ::fsync(fd) != 0) throwErrno("fsync", tmp);
  } catch (...) {
    ::close(fd);
    ::unlink(tmp.c_str());
    throw;
  }
  if (::close(fd) != 0) throwErrno("close", tmp);
  if (::rename(tmp.c_str(), target.c_str()) != 0) throwErrno("rename to " + target + " from", tmp);
}

void syncDirectory(const std::filesystem::path& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) throwErrno("cannot open directory", dir.string());
  const int rc = ::fsync(fd);
  const int err = errno;
  ::close(fd);
  errno = err;
  if (rc != 0) throwErrno("fsync", dir.string());
}

}  // namespace rilo::recording
