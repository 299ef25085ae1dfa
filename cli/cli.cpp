#include "cli.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>

namespace stf::cli {

std::atomic<bool> interrupted{false};

void fail(const std::string& message) { throw Error(message); }

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
void on_signal(int) {
  interrupted = true;
  // A second signal ends the process at once.
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
}
}  // namespace

void install_interrupt_handler() {
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
}

AtomicOutput::AtomicOutput(std::string path, const std::string& option) : path_(std::move(path)) {
  if (path_.empty()) fail(option + " must name an output file");
  temp_ = path_ + ".tmp-" + std::to_string(::getpid());
  int fd = ::open(temp_.c_str(), O_WRONLY | O_CREAT | O_EXCL, 0644);
  if (fd < 0) {
    std::string why = std::strerror(errno);
    temp_.clear();
    fail(option + " '" + path_ + "' is not writable: " + why);
  }
  ::close(fd);
}

AtomicOutput::~AtomicOutput() {
  if (!committed_ && !temp_.empty()) ::unlink(temp_.c_str());
}

void AtomicOutput::commit() {
  if (std::rename(temp_.c_str(), path_.c_str()) != 0)
    fail("cannot move the finished output into place at '" + path_ + "': " + std::strerror(errno));
  committed_ = true;
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
