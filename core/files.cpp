#include "stf/core/files.h"

#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <stdexcept>

namespace stf {

namespace {

[[noreturn]] void fail_with_errno(const std::string& name, int error) {
  throw std::runtime_error("cannot write " + name + ": " + std::strerror(error));
}

void write_all(int fd, std::string_view bytes, const std::string& name) {
  for (std::size_t done = 0; done < bytes.size();) {
    ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      const int error = errno;
      ::close(fd);
      fail_with_errno(name, error);
    }
    done += std::size_t(n);
  }
}

}  // namespace

void write_durably(const std::string& path, std::string_view bytes, const std::string& name) {
  int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC | O_NOFOLLOW, 0644);
  if (fd < 0) fail_with_errno(name, errno);
  write_all(fd, bytes, name);
  // fsync and close report what a write could not yet know: blocks the device could not take.
  if (::fsync(fd) != 0 && errno != EINVAL && errno != EROFS) {
    const int error = errno;
    ::close(fd);
    fail_with_errno(name, error);
  }
  if (::close(fd) != 0) fail_with_errno(name, errno);
}

void sync_file(const std::string& path, const std::string& name) {
  int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) fail_with_errno(name, errno);
  if (::fsync(fd) != 0 && errno != EINVAL && errno != EROFS) {
    const int error = errno;
    ::close(fd);
    fail_with_errno(name, error);
  }
  if (::close(fd) != 0) fail_with_errno(name, errno);
}

void sync_folder_of(const std::string& path) {
  const std::size_t slash = path.find_last_of('/');
  const std::string folder = slash == std::string::npos ? "."
                             : slash == 0               ? "/"
                                                        : path.substr(0, slash);
  int fd = ::open(folder.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return;
  ::fsync(fd);
  ::close(fd);
}

void remove_orphans(const std::string& folder, const std::string& prefix, int tail) {
  namespace fs = std::filesystem;
  std::error_code error;
  for (const fs::directory_entry& e : fs::directory_iterator(folder, error)) {
    const std::string name = e.path().filename().string();
    if (name.rfind(prefix, 0) != 0) continue;
    const std::string rest = name.substr(prefix.size());
    const std::size_t dash = rest.find('-');
    const std::string pid = rest.substr(0, dash);
    if (tail == 0 ? dash != std::string::npos : dash == std::string::npos || rest.size() != dash + 1 + std::size_t(tail))
      continue;
    if (pid.empty() || pid.size() > 9 || pid.find_first_not_of("0123456789") != std::string::npos)
      continue;
    if (::kill(pid_t(std::stol(pid)), 0) != 0 && errno == ESRCH) fs::remove(e.path(), error);
  }
}

void replace_file(const std::string& path, std::string_view bytes) {
  const std::filesystem::path target(path);
  remove_orphans(target.has_parent_path() ? target.parent_path().string() : ".",
                 target.filename().string() + ".tmp-");
  const std::string temp = path + ".tmp-" + std::to_string(::getpid());
  ::unlink(temp.c_str());  // whatever an earlier process of this number left there
  try {
    write_durably(temp, bytes, path);
  } catch (...) {
    ::unlink(temp.c_str());
    throw;
  }
  if (std::rename(temp.c_str(), path.c_str()) != 0) {
    const int error = errno;
    ::unlink(temp.c_str());
    fail_with_errno(path, error);
  }
  sync_folder_of(path);
}

}  // namespace stf
