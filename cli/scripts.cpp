// Running the Python drawing scripts of tools/ and showing progress: the parts of the command
// line that talk to other processes and to the terminal.
#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstring>

#include <fmt/format.h>

#include "cli.h"
#include "stf/core/clock.h"

extern char** environ;

namespace stf::cli {

namespace {

// A script's stderr, passed on line by line until a Python traceback or an error of the stf it
// runs starts; from there it is held back: if the script fails, one line makes the error (the
// first stf error, which says what went wrong, else the exception); if it succeeds after all,
// the held lines are passed on too.
class ScriptErrors {
 public:
  void take(const char* bytes, std::size_t n) {
    pending_.append(bytes, n);
    for (std::size_t end; (end = pending_.find('\n')) != std::string::npos;
         pending_.erase(0, end + 1)) {
      const std::string line = pending_.substr(0, end);
      if (line.rfind("Traceback (most recent call last)", 0) == 0) holding_ = true;
      if (line.rfind(kStfError, 0) == 0) {
        holding_ = true;
        if (stf_error_.empty()) stf_error_ = line.substr(std::string(kStfError).size());
      }
      if (holding_)
        held_ += line + "\n";
      else
        std::fprintf(stderr, "%s\n", line.c_str());
      if (!line.empty()) last_ = line;
    }
  }
  std::string cause() const { return !stf_error_.empty() ? stf_error_ : pending_.empty() ? last_ : pending_; }
  void pass_on_the_rest() const { std::fprintf(stderr, "%s%s", held_.c_str(), pending_.c_str()); }

 private:
  static constexpr const char* kStfError = "stf: error: ";
  std::string pending_, last_, held_, stf_error_;
  bool holding_ = false;
};

void drain(int fd, ScriptErrors& errors) {
  char buf[4096];
  for (ssize_t n; (n = ::read(fd, buf, sizeof buf)) > 0;) errors.take(buf, std::size_t(n));
}

}  // namespace

void run_python(const std::string& script, const std::vector<std::string>& args,
                const std::string& what) {
  std::vector<std::string> words{"/usr/bin/python3", tools_dir() + "/" + script};
  words.insert(words.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (std::string& w : words) argv.push_back(w.data());
  argv.push_back(nullptr);
  int pipe_fds[2];
  if (::pipe2(pipe_fds, O_CLOEXEC) != 0)
    fail(what + ": cannot make a pipe: " + std::strerror(errno));
  ::fcntl(pipe_fds[0], F_SETFL, O_NONBLOCK);
  posix_spawn_file_actions_t files;
  posix_spawn_file_actions_init(&files);
  posix_spawn_file_actions_adddup2(&files, pipe_fds[1], STDERR_FILENO);
  // Its own process group: a terminal's Ctrl-C reaches only stf, which stops the script
  // quietly (no Python traceback) and cleans up.
  posix_spawnattr_t attr;
  posix_spawnattr_init(&attr);
  posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETPGROUP);
  posix_spawnattr_setpgroup(&attr, 0);
  pid_t pid;
  int error = posix_spawn(&pid, argv[0], &files, &attr, argv.data(), environ);
  posix_spawnattr_destroy(&attr);
  posix_spawn_file_actions_destroy(&files);
  ::close(pipe_fds[1]);
  if (error != 0) {
    ::close(pipe_fds[0]);
    fail(what + ": cannot run /usr/bin/python3: " + std::strerror(error));
  }
  ScriptErrors errors;
  int status = 0;
  while (::waitpid(pid, &status, WNOHANG) == 0) {
    drain(pipe_fds[0], errors);
    if (interrupted) {
      // The whole group: the script's own stf runs too, which would otherwise go on writing
      // into the folders the caller is about to remove. Each cleans up and exits; wait (a few
      // seconds at most) until none is left.
      ::kill(-pid, SIGTERM);
      ::waitpid(pid, &status, 0);
      for (int i = 0; i < 500 && ::kill(-pid, 0) == 0; ++i) ::usleep(10000);
      ::close(pipe_fds[0]);
      throw Interrupted();
    }
    ::usleep(20000);
  }
  drain(pipe_fds[0], errors);
  ::close(pipe_fds[0]);
  if (WIFEXITED(status) && WEXITSTATUS(status) == 0) return errors.pass_on_the_rest();
  const std::string why = WIFEXITED(status)
                              ? " exited with status " + std::to_string(WEXITSTATUS(status))
                              : " was killed";
  fail(what + " failed (" + script + why + ")" +
       (errors.cause().empty() ? "" : ": " + errors.cause()));
}

ProgressBar::ProgressBar(std::string label, bool quiet)
    : label_(std::move(label)), enabled_(!quiet && ::isatty(STDERR_FILENO)) {}

void ProgressBar::update(std::int64_t done, std::int64_t total) {
  if (!enabled_ || total <= 0) return;
  const double seconds = seconds_since(start_);
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

SphereProgress::SphereProgress(std::string command, bool quiet)
    : command_(std::move(command)), quiet_(quiet), terminal_(::isatty(STDERR_FILENO)) {}

void SphereProgress::start(int index, int count, const std::string& sphere) {
  if (quiet_) return;
  const double seconds = seconds_since(start_);
  const std::string left = index > 0 ? fmt::format("about {:.0f} s left", seconds / index * (count - index)) : "";
  if (!terminal_) {
    std::fprintf(stderr, "%s: precomputing [%d/%d] %s%s\n", command_.c_str(), index + 1, count, sphere.c_str(),
                 left.empty() ? "" : (", " + left).c_str());
    return;
  }
  const int width = 30, filled = width * index / std::max(count, 1);
  const std::string bar = std::string(std::size_t(filled), '#') + std::string(std::size_t(width - filled), '.');
  std::fprintf(stderr, "\r\033[K%s: precomputing [%s] %d of %d spheres, %.0f s%s%s", command_.c_str(), bar.c_str(),
               index, count, seconds, left.empty() ? "" : ", ", left.c_str());
  std::fflush(stderr);
  drawn_ = true;
}

void SphereProgress::finish() {
  if (drawn_) std::fprintf(stderr, "\r\033[K");
  drawn_ = false;
}

StepStatus::StepStatus(std::string label, bool quiet)
    : label_(std::move(label)), enabled_(!quiet && ::isatty(STDERR_FILENO)) {}

void StepStatus::update(std::string_view step, std::int64_t done, std::int64_t total) {
  if (!enabled_) return;
  std::unique_lock<std::mutex> lock(mutex_, std::try_to_lock);
  if (!lock) return;
  const double now = seconds_since(start_);
  if (now < shown_ + 0.1 && done < total) return;
  shown_ = now;
  // \033[K clears what a longer step's line left.
  std::fprintf(stderr, "\r\033[K%s: %.*s: %lld of %lld bins, %.0f s", label_.c_str(), int(step.size()), step.data(), (long long)done,
               (long long)total, now);
  std::fflush(stderr);
}

void StepStatus::finish() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (enabled_ && shown_ >= 0) std::fprintf(stderr, "\r\033[K");
  shown_ = -1;
}

}  // namespace stf::cli
