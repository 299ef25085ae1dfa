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
std::string text(const toml::value& v, const std::string& name);
void expect(bool ok, const toml::value& v, const std::string& message);

}  // namespace stf::scene
