#include "cli.h"

#include <fcntl.h>
#include <limits.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>

namespace stf::cli {

std::atomic<bool> interrupted{false};

void fail(const std::string& message) { throw Error(message); }

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

void on_signal(int) {
  if (!interrupted.exchange(true)) return;
  // A second signal: the user insists. Leave nothing half-written behind.
  for (auto& slot : open_temps)
    if (const char* p = slot.load()) ::unlink(p);
  ::_exit(130);
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

// Temporary files `target.tmp-PID` of processes that no longer run (killed with SIGKILL, which
// no handler sees) are removed when the same output is written again.
void remove_orphans(const std::string& target) {
  namespace fs = std::filesystem;
  const std::string prefix = fs::path(target).filename().string() + ".tmp-";
  std::error_code error;
  for (const fs::directory_entry& e : fs::directory_iterator(folder_of(target), error)) {
    const std::string name = e.path().filename().string();
    if (name.rfind(prefix, 0) != 0) continue;
    const std::string pid = name.substr(prefix.size());
    if (pid.empty() || pid.find_first_not_of("0123456789") != std::string::npos) continue;
    if (::kill(pid_t(std::stol(pid)), 0) != 0 && errno == ESRCH) fs::remove(e.path(), error);
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
}

void require_files(const std::vector<NamedFile>& inputs) {
  for (const NamedFile& f : inputs) {
    struct stat st;
    if (::stat(f.path.c_str(), &st) != 0) fail(f.option + " '" + f.path + "': " + std::strerror(errno));
    if (S_ISDIR(st.st_mode)) fail(f.option + " '" + f.path + "' is a folder, not a file");
  }
}

void refuse_same_file(const std::string& path, const std::string& option, const std::vector<NamedFile>& keep) {
  if (path == "-") return;
  for (const NamedFile& k : keep)
    if (!k.path.empty() && k.path != "-" && same_file(path, k.path))
      fail(option + " '" + path + "' is the same file as " + k.option + " '" + k.path + "'; refusing to overwrite it");
}

AtomicOutput::AtomicOutput(std::string path, std::string option, const std::vector<NamedFile>& keep)
    : path_(std::move(path)), option_(std::move(option)) {
  if (path_.empty()) fail(option_ + " must name an output file");
  refuse_same_file(path_, option_, keep);
  target_ = path_ == "-" ? path_ : follow_links(path_, option_);
  struct stat st;
  const bool exists = path_ == "-" || ::stat(target_.c_str(), &st) == 0;
  if (exists && path_ != "-" && S_ISDIR(st.st_mode)) fail(option_ + " '" + path_ + "' is a folder; give a file name");
  in_place_ = path_ == "-" || target_.rfind("/proc/", 0) == 0 || target_.rfind("/dev/fd/", 0) == 0 ||
              (exists && !S_ISREG(st.st_mode));
  if (in_place_) {
    if (path_ != "-" && ::access(target_.c_str(), W_OK) != 0)
      fail(option_ + " '" + path_ + "' is not writable: " + std::strerror(errno));
    temp_ = scratch_.emplace(option_).path();
    return;
  }
  remove_orphans(target_);
  temp_ = target_ + ".tmp-" + std::to_string(::getpid());
  int fd = ::open(temp_.c_str(), O_WRONLY | O_CREAT | O_EXCL, 0644);
  if (fd < 0) {
    std::string why = std::strerror(errno);
    temp_.clear();
    fail(option_ + " '" + path_ + "' is not writable: " + why);
  }
  if (exists) ::fchmod(fd, st.st_mode & 07777);
  ::close(fd);
  register_temp(temp_);
}

AtomicOutput::~AtomicOutput() {
  if (temp_.empty() || in_place_) return;  // the scratch file removes itself
  unregister_temp(temp_);
  if (!committed_) ::unlink(temp_.c_str());
}

ScratchFile::ScratchFile(const std::string& what) {
  const char* tmpdir = std::getenv("TMPDIR");
  std::string pattern = std::string(tmpdir && *tmpdir ? tmpdir : "/tmp") + "/stf-XXXXXX";
  std::vector<char> name(pattern.begin(), pattern.end());
  name.push_back('\0');
  int fd = ::mkstemp(name.data());
  if (fd < 0) fail(what + ": cannot create a temporary file in " + pattern + ": " + std::strerror(errno));
  ::close(fd);
  path_ = name.data();
  register_temp(path_);
}

ScratchFile::~ScratchFile() {
  if (path_.empty()) return;
  unregister_temp(path_);
  ::unlink(path_.c_str());
}

void AtomicOutput::commit() {
  stop_if_interrupted();  // after Ctrl-C nothing is put in place, however far the work got
  if (in_place_) {
    int fd = path_ == "-" ? STDOUT_FILENO : ::open(target_.c_str(), O_WRONLY);
    if (fd < 0) fail("cannot open '" + path_ + "' for writing: " + std::strerror(errno));
    copy_into(temp_, fd, path_);
    if (fd != STDOUT_FILENO) ::close(fd);
  } else if (std::rename(temp_.c_str(), target_.c_str()) != 0) {
    fail("cannot move the finished output into place at '" + path_ + "': " + std::strerror(errno));
  }
  committed_ = true;
}

void run_python(const std::string& script, const std::vector<std::string>& args, const std::string& what) {
  std::vector<std::string> words{"/usr/bin/python3", tools_dir() + "/" + script};
  words.insert(words.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (std::string& w : words) argv.push_back(w.data());
  argv.push_back(nullptr);
  // Its own process group: a terminal's Ctrl-C reaches only stf, which stops the script
  // quietly (no Python traceback) and cleans up.
  posix_spawnattr_t attr;
  posix_spawnattr_init(&attr);
  posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETPGROUP);
  posix_spawnattr_setpgroup(&attr, 0);
  pid_t pid;
  int error = posix_spawn(&pid, argv[0], nullptr, &attr, argv.data(), environ);
  posix_spawnattr_destroy(&attr);
  if (error != 0) fail(what + ": cannot run /usr/bin/python3: " + std::strerror(error));
  int status = 0;
  while (::waitpid(pid, &status, WNOHANG) == 0) {
    if (interrupted) {
      // The whole group: the script's own stf runs too, which would otherwise go on writing
      // into the folders the caller is about to remove. Each cleans up and exits; wait (a few
      // seconds at most) until none is left.
      ::kill(-pid, SIGTERM);
      ::waitpid(pid, &status, 0);
      for (int i = 0; i < 500 && ::kill(-pid, 0) == 0; ++i) ::usleep(10000);
      throw Interrupted();
    }
    ::usleep(20000);
  }
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0)
    fail(what + " failed (" + script + (WIFEXITED(status) ? " exited with status " + std::to_string(WEXITSTATUS(status))
                                                         : std::string(" was killed")) + ")");
}

ProgressBar::ProgressBar(std::string label, bool quiet)
    : label_(std::move(label)), enabled_(!quiet && ::isatty(STDERR_FILENO)) {}

void ProgressBar::update(std::int64_t done, std::int64_t total, double seconds) {
  if (!enabled_ || total <= 0) return;
  const int width = 30;
  double frac = double(done) / double(total);
  int filled = int(frac * width);
  double rate = seconds > 0 ? double(done) / seconds : 0;
  double eta = rate > 0 ? double(total - done) / rate : 0;
  std::string bar(filled, '#');
  bar.resize(width, '.');
  std::fprintf(stderr, "\r%s [%s] %5.1f%%  %.3g paths/s  ETA %4.0f s ", label_.c_str(), bar.c_str(),
               100 * frac, rate, eta);
  std::fflush(stderr);
  drawn_ = true;
}

void ProgressBar::finish() {
  if (drawn_) std::fprintf(stderr, "\n");
  drawn_ = false;
}

}  // namespace stf::cli
