// The text of a TOML file (a scene, a render scene, a --config file), read and checked before a
// parser sees it: toml11 parses arrays, inline tables and dotted keys by recursion, and a file
// nested 10,000 deep overflows the stack.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

namespace stf::scene {

// The most arrays and inline tables nested in one another, and the most parts of one dotted key
// (a.b.c) or table header ([a.b.c]), in a file stf reads: far beyond what any scene needs.
inline constexpr int kMaxTomlDepth = 64;
// The largest TOML file stf reads (a scene of thousands of objects is well below it).
inline constexpr std::size_t kMaxTomlBytes = 4u << 20;

// The bytes of `path`, at most kMaxTomlBytes. Throws SceneError "PATH: what" for a folder, a
// missing or unreadable file and one too large (a FIFO is read as it comes).
std::string read_toml_text(const std::string& path);

// Throws SceneError "PATH:LINE: what" at the first place where `text` nests arrays and inline
// tables, or the parts of a key, more than kMaxTomlDepth deep; strings and comments are skipped.
void check_toml_nesting(std::string_view text, const std::string& path);

}  // namespace stf::scene
