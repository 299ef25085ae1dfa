// Reading values of stf's TOML files (scenes, render scenes): every error is one line naming
// the file, the line and the key, as a SceneError.
#pragma once

#include <toml.hpp>

#include <set>
#include <string>

#include <fmt/format.h>

#include "stf/scene/scene_error.h"

namespace stf::scene {

// Parses `path`; a syntax error or an unreadable file is a SceneError "file:line: what".
toml::value parse_toml(const std::string& path);

[[noreturn]] void error_at(const toml::value& v, const std::string& what);
void check_keys(const toml::value& table, const std::string& where, const std::set<std::string>& allowed);
const toml::value& require(const toml::value& table, const std::string& key, const std::string& where);
double number(const toml::value& v, const std::string& name);
// A string of printable characters (no NUL, no line break).
std::string text(const toml::value& v, const std::string& name);
// A name (of a medium): a non-empty text().
std::string name_text(const toml::value& v, const std::string& name);
// A number that is a whole number in [low, high] (1.5 is refused, 2.0 taken).
double whole_number(const toml::value& v, const std::string& name, double low, double high);
void expect(bool ok, const toml::value& v, const std::string& message);

}  // namespace stf::scene
