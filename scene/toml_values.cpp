#include "toml_values.h"

#include <cmath>
#include <sstream>
#include <stdexcept>

#include "stf/scene/toml_text.h"

namespace stf::scene {

toml::value parse_toml(const std::string& path) {
  const std::string text = read_toml_text(path);
  check_toml_nesting(text, path);
  std::istringstream stream(text);
  try {
    return toml::parse(stream, path);
  } catch (const toml::syntax_error& e) {
    // toml11's report spans lines: the problem first, then " --> file" and " N | source".
    std::string what = e.what(), first = what.substr(0, what.find('\n')), line = "1";
    std::size_t bar = what.find(" | ");
    if (bar != std::string::npos) {
      std::size_t start = what.rfind('\n', bar);
      std::string number = what.substr(start + 1, bar - start - 1);
      number.erase(0, number.find_first_not_of(' '));
      if (!number.empty() && number.find_first_not_of("0123456789") == std::string::npos) line = number;
    }
    throw SceneError(path + ":" + line + ": " + first);
  } catch (const std::runtime_error& e) {
    throw SceneError(path + ": " + e.what());
  }
}

// "file:line: what" for a value of the scene.
[[noreturn]] void error_at(const toml::value& v, const std::string& what) {
  const toml::source_location loc = v.location();
  throw SceneError(loc.file_name() + ":" + std::to_string(loc.line()) + ": " + what);
}

void check_keys(const toml::value& table, const std::string& where, const std::set<std::string>& allowed) {
  for (const auto& [key, value] : table.as_table()) {
    if (allowed.count(key)) continue;
    std::string list;
    for (const std::string& a : allowed) list += (list.empty() ? "" : ", ") + a;
    error_at(value, where + key + ": unknown key (allowed: " + list + ")");
  }
}

const toml::value& require(const toml::value& table, const std::string& key, const std::string& where) {
  if (!table.contains(key)) error_at(table, where.substr(0, where.size() - 1) + ": missing key '" + key + "'");
  return table.at(key);
}

// A number given as integer or float ("1e6" as a string is accepted too, as on the command line).
double number(const toml::value& v, const std::string& name) {
  if (v.is_floating()) return v.as_floating();
  if (v.is_integer()) return double(v.as_integer());
  if (v.is_string()) {
    try {
      std::size_t used = 0;
      double d = std::stod(v.as_string().str, &used);
      if (used == v.as_string().str.size()) return d;
    } catch (const std::exception&) {
    }
  }
  error_at(v, name + ": expected a number");
}

// Any string of a scene: printable, so that no message quoting it breaks its line (a path with
// a line break or a NUL names no file a user meant).
std::string text(const toml::value& v, const std::string& name) {
  if (!v.is_string()) error_at(v, name + ": expected a string");
  const std::string& s = v.as_string().str;
  for (std::size_t i = 0; i < s.size(); ++i)
    expect(static_cast<unsigned char>(s[i]) >= 0x20 && s[i] != 0x7f, v,
           fmt::format("{}: holds a control character (byte {} is {:#04x}); strings here are printable", name, i + 1,
                       static_cast<unsigned char>(s[i])));
  return s;
}

std::string name_text(const toml::value& v, const std::string& name) {
  const std::string s = text(v, name);
  expect(!s.empty(), v, name + ": must not be empty");
  return s;
}

double whole_number(const toml::value& v, const std::string& name, double low, double high) {
  const double x = number(v, name);
  expect(x == std::floor(x) && x >= low && x <= high, v,
         fmt::format("{}: must be a whole number in {:g}..{:g}, got {}", name, low, high, toml::format(v)));
  return x;
}

void expect(bool ok, const toml::value& v, const std::string& message) {
  if (!ok) error_at(v, message);
}

}  // namespace stf::scene
