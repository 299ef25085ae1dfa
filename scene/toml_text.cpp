#include "stf/scene/toml_text.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <vector>

#include "stf/scene/scene_error.h"

namespace stf::scene {

namespace {

// One pass over the text: where strings and comments are skipped, which brackets are open, and
// whether the scan is in a key (before its `=`), where dots separate parts.
class NestingScan {
 public:
  NestingScan(std::string_view text, const std::string& path) : t_(text), path_(path) {}
  void run();

 private:
  [[noreturn]] void fail(const std::string& what) const {
    throw SceneError(path_ + ":" + std::to_string(line_) + ": " + what + "; stf reads TOML nested at most " +
                     std::to_string(kMaxTomlDepth) + " deep");
  }
  bool at(std::string_view s) const { return t_.substr(at_, s.size()) == s; }
  void skip_comment() {
    while (at_ < t_.size() && t_[at_] != '\n') ++at_;
  }
  void skip_string(char quote);
  void key_char(char c);
  void value_char(char c);
  void open(char c) {
    open_.push_back(c);
    if (open_.size() > std::size_t(kMaxTomlDepth)) fail("arrays and inline tables nested more than " + std::to_string(kMaxTomlDepth) + " deep");
  }
  void another_part() {
    if (++parts_ > kMaxTomlDepth) fail("a key of more than " + std::to_string(kMaxTomlDepth) + " dotted parts");
  }

  std::string_view t_;
  const std::string& path_;
  std::size_t at_ = 0;
  int line_ = 1, parts_ = 1;
  bool key_ = true, header_ = false;
  std::vector<char> open_;
};

void NestingScan::skip_string(char quote) {
  const std::string triple(3, quote);
  const bool multiline = at(triple);
  at_ += multiline ? 3 : 1;
  while (at_ < t_.size()) {
    const char c = t_[at_];
    if (multiline ? at(triple) : c == quote) {
      at_ += multiline ? 3 : 1;
      return;
    }
    if (c == '\n') {
      if (!multiline) return;  // an unterminated string: the parser says so
      ++line_;
    }
    at_ += (quote == '"' && c == '\\' && at_ + 1 < t_.size() && t_[at_ + 1] != '\n') ? 2 : 1;
  }
}

void NestingScan::key_char(char c) {
  if (c == '[' && open_.empty() && !header_) header_ = true;  // a table header: its dots are parts
  else if (c == '.') another_part();
  else if (c == '=' && !header_) key_ = false, parts_ = 1;
  else if (c == '}' && !open_.empty()) open_.pop_back(), key_ = false;  // "{}" or a trailing comma
}

void NestingScan::value_char(char c) {
  if (c == '[' || c == '{') {
    open(c);
    if (c == '{') key_ = true, parts_ = 1;
  } else if ((c == ']' || c == '}') && !open_.empty()) {
    open_.pop_back();
  } else if (c == ',' && !open_.empty() && open_.back() == '{') {
    key_ = true, parts_ = 1;
  }
}

void NestingScan::run() {
  while (at_ < t_.size()) {
    const char c = t_[at_];
    if (c == '#') {
      skip_comment();
    } else if (c == '"' || c == '\'') {
      skip_string(c);
    } else {
      if (c == '\n') {
        ++line_;
        if (open_.empty()) key_ = true, header_ = false, parts_ = 1;
      } else if (key_) {
        key_char(c);
      } else {
        value_char(c);
      }
      ++at_;
    }
  }
}

}  // namespace

std::string read_toml_text(const std::string& path) {
  const auto fail = [&](const std::string& what) { throw SceneError(path + ": " + what); };
  struct stat st;
  if (::stat(path.c_str(), &st) != 0) fail(std::strerror(errno));
  if (S_ISDIR(st.st_mode)) fail("is a folder, not a TOML file");
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) fail(std::strerror(errno));
  std::string text;
  char buffer[1 << 16];
  for (;;) {
    const ssize_t n = ::read(fd, buffer, sizeof buffer);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int error = errno;
      ::close(fd);
      if (n < 0) fail(std::strerror(error));
      return text;
    }
    text.append(buffer, std::size_t(n));
    if (text.size() > kMaxTomlBytes) {
      ::close(fd);
      fail("larger than " + std::to_string(kMaxTomlBytes >> 20) + " MiB; stf reads TOML files up to that size");
    }
  }
}

void check_toml_nesting(std::string_view text, const std::string& path) { NestingScan(text, path).run(); }

}  // namespace stf::scene
