#include "toml_values.h"

#include <stdexcept>

namespace stf::scene {

toml::value parse_toml(const std::string& path) {
  try {
    return toml::parse(path);
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

std::string text(const toml::value& v, const std::string& name) {
  if (!v.is_string()) error_at(v, name + ": expected a string");
  return v.as_string().str;
}

void expect(bool ok, const toml::value& v, const std::string& message) {
  if (!ok) error_at(v, message);
}

}  // namespace stf::scene
