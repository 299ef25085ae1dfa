// --config files: read and checked before CLI11 reads them, and remembered so that no output
// overwrites them.
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <sstream>
#include <toml.hpp>

#include "cli.h"
#include "stf/scene/scene_error.h"
#include "stf/scene/toml_text.h"

namespace stf::cli {

std::string& config_file() {
  static std::string path;
  return path;
}

namespace {

// The one line of a toml11 syntax error: its report has "[error] WHAT" on its first line, then
// the source with " N | " margins.
std::string syntax_error_line(const std::string& path, const toml::syntax_error& e) {
  std::istringstream report(e.what());
  std::string what, line, number;
  std::getline(report, what);
  if (what.rfind("[error] ", 0) == 0) what = what.substr(8);
  while (number.empty() && std::getline(report, line)) {
    std::size_t bar = line.find(" | ");
    std::string head = bar == std::string::npos ? "" : line.substr(0, bar);
    head.erase(0, head.find_first_not_of(' '));
    if (!head.empty() && head.find_first_not_of("0123456789") == std::string::npos) number = head;
  }
  return "--config '" + path + "'" + (number.empty() ? "" : ", line " + number) + ": not valid TOML: " + what;
}

// Parses the regular file `path` as TOML, its size and nesting checked first (the parser
// recurses).
void check_config_file(const std::string& path) {
  std::string text;
  try {
    text = scene::read_toml_text(path);
    scene::check_toml_nesting(text, path);
  } catch (const scene::SceneError& e) {
    fail(std::string("--config ") + e.what());
  }
  try {
    std::istringstream stream(text);
    (void)toml::parse(stream, path);
  } catch (const toml::syntax_error& e) {
    fail(syntax_error_line(path, e));
  } catch (const std::exception& e) {
    fail("--config '" + path + "': " + e.what());
  }
}

}  // namespace

void check_config_syntax(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    std::string a = argv[i], path;
    if (a == "--config" && i + 1 < argc) path = argv[i + 1];
    else if (a.rfind("--config=", 0) == 0) path = a.substr(9);
    else continue;
    if (::access(path.c_str(), R_OK) != 0) fail("--config '" + path + "': " + std::strerror(errno));
    struct stat st;
    if (::stat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) continue;  // a pipe is read once, by CLI11
    config_file() = path;
    check_config_file(path);
  }
}

}  // namespace stf::cli
