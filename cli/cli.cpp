#include "cli.h"

#include <CLI/CLI.hpp>

#include <fcntl.h>
#include <limits.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>

#include "stf/core/files.h"
#include "stf/core/h5io.h"
#include "stf/core/table.h"

namespace stf::cli {

std::atomic<bool> interrupted{false};
std::atomic<int> interrupt_signal{0};

void fail(const std::string& message) { throw Error(message); }

int interrupted_status() { return 128 + (interrupt_signal.load() ? interrupt_signal.load() : SIGINT); }

void stop_if_interrupted() {
  if (interrupted) throw Interrupted();
}

std::string tools_dir() {
  if (const char* env = std::getenv("STF_TOOLS_DIR")) return env;
  return STF_TOOLS_DIR;
}

std::int64_t parse_count(const std::string& text, const std::string& option, std::int64_t min,
                         std::int64_t max) {
  const std::string allowed = option + " must be a whole number in " + std::to_string(min) + ".." +
                              std::to_string(max) + " (plain or exponent notation), got '" + text + "'";
  // Digits, a sign, a point and an exponent only: strtod would also take white space, hex and
  // "inf".
  if (text.find_first_not_of("0123456789+-.eE") != std::string::npos) fail(allowed);
  errno = 0;
  char* end = nullptr;
  long long exact = std::strtoll(text.c_str(), &end, 10);
  if (!text.empty() && *end == '\0' && errno == 0) {
    if (exact < min || exact > max) fail(allowed);
    return exact;
  }
  double value = std::strtod(text.c_str(), &end);
  if (text.empty() || *end != '\0' || !std::isfinite(value) || value != std::floor(value) ||
      value < double(min) || value > double(max))
    fail(allowed);
  return std::int64_t(value);
}

namespace {

// Temporary files of open AtomicOutputs, for the second signal's clean-up (the handler may
// only read these: plain pointers to strings that outlive their registration).
constexpr int kMaxTemps = 32;
std::atomic<const char*> open_temps[kMaxTemps];

void register_temp(const std::string& path) {
  for (auto& slot : open_temps) {
    const char* empty = nullptr;
    if (slot.compare_exchange_strong(empty, path.c_str())) return;
  }
}

void unregister_temp(const std::string& path) {
  for (auto& slot : open_temps) {
    const char* mine = path.c_str();
    slot.compare_exchange_strong(mine, nullptr);
  }
}

void on_signal(int signal) {
  int none = 0;
  interrupt_signal.compare_exchange_strong(none, signal);  // the first signal's, before the flag
  // The first signal is polled for, unless the command is still reading its inputs: then a
  // library stuck in a malformed file could keep it from ever looking.
  const bool second = interrupted.exchange(true);
  if (!second && !h5::reading_input()) return;
  // A second signal: the user insists. Leave nothing half-written behind.
  for (auto& slot : open_temps)
    if (const char* p = slot.load()) ::unlink(p);
  if (!second) {
    constexpr char kLine[] = "stf: error: interrupted while reading inputs; no output replaced\n";
    [[maybe_unused]] const ssize_t n = ::write(STDERR_FILENO, kLine, sizeof kLine - 1);
  }
  ::_exit(interrupted_status());
}

std::string folder_of(const std::string& path) {
  std::size_t slash = path.find_last_of('/');
  if (slash == std::string::npos) return ".";
  return slash == 0 ? "/" : path.substr(0, slash);
}

// The path a chain of symbolic links finally names (the link's target may not exist yet).
std::string follow_links(const std::string& path, const std::string& option) {
  std::string p = path;
  for (int hops = 0; hops < 40; ++hops) {
    char buf[PATH_MAX];
    ssize_t n = ::readlink(p.c_str(), buf, sizeof buf - 1);
    if (n < 0) return p;
    std::string link(buf, std::size_t(n));
    if (p.rfind("/proc/", 0) == 0 || p.rfind("/dev/fd/", 0) == 0) return p;  // fd links: not paths
    p = link.front() == '/' ? link : folder_of(p) + "/" + link;
  }
  fail(option + " '" + path + "': too many levels of symbolic links");
}

// A name for a file that may not exist yet: its folder's real path and its own name.
std::string canonical_name(const std::string& path) {
  char buf[PATH_MAX];
  std::string folder = folder_of(path);
  if (!::realpath(folder.c_str(), buf)) return path;
  return std::string(buf) + "/" + path.substr(path.find_last_of('/') + 1);
}

bool same_file(const std::string& a, const std::string& b) {
  struct stat sa, sb;
  if (::stat(a.c_str(), &sa) == 0 && ::stat(b.c_str(), &sb) == 0)
    return sa.st_dev == sb.st_dev && sa.st_ino == sb.st_ino;
  return canonical_name(follow_links(a, "")) == canonical_name(follow_links(b, ""));
}

// Opens a device or FIFO for writing without blocking in open(): a FIFO with no reader yet is
// retried until one comes or Ctrl-C, which a blocked open() would not see.
int open_in_place(const std::string& target, const std::string& path) {
  for (;;) {
    int fd = ::open(target.c_str(), O_WRONLY | O_NONBLOCK | O_CLOEXEC);
    if (fd >= 0) {
      ::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) & ~O_NONBLOCK);
      return fd;
    }
    const int error = errno;
    struct stat st;
    const bool fifo_without_reader = error == ENXIO && ::stat(target.c_str(), &st) == 0 && S_ISFIFO(st.st_mode);
    if (!fifo_without_reader && error != EINTR) fail("cannot open '" + path + "' for writing: " + std::strerror(error));
    stop_if_interrupted();
    ::usleep(20000);
  }
}

void copy_into(const std::string& from, int fd, const std::string& path) {
  int in = ::open(from.c_str(), O_RDONLY);
  if (in < 0) fail("cannot read back the finished output for '" + path + "'");
  char buf[1 << 16];
  for (ssize_t n; (n = ::read(in, buf, sizeof buf)) > 0;)
    for (ssize_t done = 0; done < n;) {
      ssize_t w = ::write(fd, buf + done, std::size_t(n - done));
      if (w < 0 && errno == EINTR) continue;
      if (w < 0) {
        ::close(in);
        fail("cannot write '" + path + "': " + std::strerror(errno));
      }
      done += w;
    }
  ::close(in);
}

}  // namespace

void install_interrupt_handler() {
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  // Past a file-size limit (ulimit -f) a write fails with "File too large" and is reported as
  // any failed write, instead of the signal killing the process mid-file. (Python restores the
  // default for its children, so report.py's stf runs need this too.)
  std::signal(SIGXFSZ, SIG_IGN);
}

void require_writable_folder(const std::string& folder, const std::string& option) {
  std::string at = folder.empty() ? "." : folder;
  while (at.size() > 1 && at.back() == '/') at.pop_back();
  for (;;) {
    struct stat st;
    if (::stat(at.c_str(), &st) == 0) {
      if (!S_ISDIR(st.st_mode))
        fail(option + " '" + folder + "': " + (at == folder ? "not a folder" : "'" + at + "' is not a folder"));
      if (::access(at.c_str(), W_OK | X_OK) != 0) fail(option + " '" + folder + "': cannot write in '" + at + "'");
      return;
    }
    if (errno != ENOENT) fail(option + " '" + folder + "': " + std::strerror(errno));
    const std::size_t slash = at.find_last_of('/');
    at = slash == std::string::npos ? "." : slash == 0 ? "/" : at.substr(0, slash);
  }
}

void require_files(const std::vector<NamedFile>& inputs) {
  for (const NamedFile& f : inputs) {
    struct stat st;
    if (::stat(f.path.c_str(), &st) != 0) fail(f.option + " '" + f.path + "': " + std::strerror(errno));
    if (S_ISDIR(st.st_mode)) fail(f.option + " '" + f.path + "' is a folder, not a file");
  }
}

bool inside_folder(const std::string& path, const std::string& folder) {
  if (path == "-") return false;
  char a[PATH_MAX], b[PATH_MAX];
  const std::string target = follow_links(path, "");
  if (!::realpath(folder_of(target).c_str(), a) || !::realpath(folder.c_str(), b)) return false;
  const std::string inner = a, outer = b;
  return inner == outer || inner.rfind(outer + "/", 0) == 0;
}

void refuse_same_file(const std::string& path, const std::string& option, const std::vector<NamedFile>& keep) {
  if (path == "-") return;
  for (const NamedFile& k : keep)
    if (!k.path.empty() && k.path != "-" && same_file(path, k.path))
      fail(option + " '" + path + "' is the same file as " + k.option + " '" + k.path + "'; refusing to overwrite it");
}

bool written_in_place(const std::string& path) {
  if (path == "-") return true;
  const std::string target = follow_links(path, "");
  if (target.rfind("/proc/", 0) == 0 || target.rfind("/dev/fd/", 0) == 0) return true;
  struct stat st;
  return ::stat(target.c_str(), &st) == 0 && !S_ISREG(st.st_mode) && !S_ISDIR(st.st_mode);
}

OutputLock::OutputLock(const std::string& target, const std::string& option, const std::string& path)
    : lock_(target + ".lock") {
  for (int tries = 0; tries < 100; ++tries) {
    fd_ = ::open(lock_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0644);
    if (fd_ < 0) fail(option + " '" + path + "' is not writable: " + std::strerror(errno));
    if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
      const int error = errno;
      ::close(fd_);
      fd_ = -1;
      if (error != EWOULDBLOCK) fail(option + " '" + path + "': cannot lock " + lock_ + ": " + std::strerror(error));
      fail(option + " '" + path + "' is being written by another stf process (it holds " + lock_ +
           "); wait for it to finish or choose another output");
    }
    // The holder before us may have removed the file between our open and our lock: then the
    // lock is on a name no one else sees, and we start again on the new file.
    struct stat held, named;
    if (::fstat(fd_, &held) == 0 && ::stat(lock_.c_str(), &named) == 0 && held.st_ino == named.st_ino &&
        held.st_dev == named.st_dev) {
      register_temp(lock_);
      return;
    }
    ::close(fd_);
    fd_ = -1;
  }
  fail(option + " '" + path + "': cannot take the lock " + lock_);
}

OutputLock::~OutputLock() {
  if (fd_ < 0) return;
  unregister_temp(lock_);
  ::unlink(lock_.c_str());  // before the lock goes: a waiter then sees a new file, not this one
  ::close(fd_);
}

AtomicOutput::AtomicOutput(std::string path, std::string option, const std::vector<NamedFile>& keep)
    : path_(std::move(path)), option_(std::move(option)) {
  if (path_.empty()) fail(option_ + " must name an output file");
  refuse_same_file(path_, option_, keep);
  refuse_same_file(path_, option_, {{config_file(), "--config"}});
  target_ = path_ == "-" ? path_ : follow_links(path_, option_);
  struct stat st;
  const bool exists = path_ == "-" || ::stat(target_.c_str(), &st) == 0;
  if (exists && path_ != "-" && S_ISDIR(st.st_mode)) fail(option_ + " '" + path_ + "' is a folder; give a file name");
  in_place_ = written_in_place(path_);
  if (exists && path_ != "-" && ::access(target_.c_str(), W_OK) != 0)
    fail(option_ + " '" + path_ + "' is not writable: " + std::strerror(errno));
  if (in_place_) {
    temp_ = scratch_.emplace(option_).path();
    return;
  }
  lock_.emplace(target_, option_, path_);
  remove_orphans(folder_of(target_), std::filesystem::path(target_).filename().string() + ".tmp-");
  temp_ = target_ + ".tmp-" + std::to_string(::getpid());
  int fd = ::open(temp_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd < 0) {
    std::string why = std::strerror(errno);
    temp_.clear();
    fail(option_ + " '" + path_ + "' is not writable: " + why);
  }
  register_temp(temp_);
  if (exists) ::fchmod(fd, st.st_mode & 07777);
  ::close(fd);
}

AtomicOutput::~AtomicOutput() {
  if (temp_.empty() || in_place_) return;  // the scratch file removes itself
  unregister_temp(temp_);
  if (!committed_) ::unlink(temp_.c_str());
}

ScratchFile::ScratchFile(const std::string& what) {
  const char* tmpdir = std::getenv("TMPDIR");
  const std::string folder = tmpdir && *tmpdir ? tmpdir : "/tmp";
  remove_orphans(folder, "stf-", 6);
  std::string pattern = folder + "/stf-" + std::to_string(::getpid()) + "-XXXXXX";
  std::vector<char> name(pattern.begin(), pattern.end());
  name.push_back('\0');
  int fd = ::mkstemp(name.data());
  if (fd < 0) fail(what + ": cannot create a temporary file in " + folder + ": " + std::strerror(errno));
  ::close(fd);
  path_ = name.data();
  register_temp(path_);
}

ScratchFile::~ScratchFile() {
  if (path_.empty()) return;
  unregister_temp(path_);
  ::unlink(path_.c_str());
}

void AtomicOutput::stage(std::string_view bytes) { write_durably(temp_, bytes, option_ + " '" + path_ + "'"); }

void AtomicOutput::write(std::string_view bytes) {
  stage(bytes);
  commit();
}

void AtomicOutput::commit() {
  stop_if_interrupted();  // after Ctrl-C nothing is put in place, however far the work got
  put_in_place();
}

void commit_all(std::initializer_list<AtomicOutput*> outputs) {
  stop_if_interrupted();
  for (AtomicOutput* out : outputs)
    if (out) out->put_in_place();
}

void AtomicOutput::put_in_place() {
  if (in_place_) {
    int fd = path_ == "-" ? STDOUT_FILENO : open_in_place(target_, path_);
    copy_into(temp_, fd, path_);
    if (fd != STDOUT_FILENO && ::close(fd) != 0) fail("cannot write '" + path_ + "': " + std::strerror(errno));
  } else {
    sync_file(temp_, option_ + " '" + path_ + "'");
    if (std::rename(temp_.c_str(), target_.c_str()) != 0)
      fail("cannot move the finished output into place at '" + path_ + "': " + std::strerror(errno));
    sync_folder_of(target_);
  }
  committed_ = true;
}

void add_medium_options(CLI::App& cmd, Medium& medium, bool required) {
  CLI::Option* options[] = {
      cmd.add_option("--sigma-s", medium.sigma_s, "Scattering coefficient (>= 0)"),
      cmd.add_option("--sigma-a", medium.sigma_a, "Absorption coefficient (>= 0)"),
      cmd.add_option("--g", medium.g, "Henyey-Greenstein asymmetry, in (-1, 1)")};
  for (CLI::Option* o : options) o->required(required);
  cmd.add_option("--radius", medium.radius, "Sphere radius (> 0)")->capture_default_str();
}

}  // namespace stf::cli
