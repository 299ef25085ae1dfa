// stf's modules: libraries whose dependencies cost every command startup time when linked in
// (OpenImageIO 0.23 s, OpenVDB 36 ms), so they are built as MODULEs and loaded on first use.
// Header-only: the renderer's sanitized test builds compile its sources one by one, and this keeps
// them from needing another source file.
#pragma once

#include <dlfcn.h>
#include <unistd.h>

#include <cstdlib>
#include <stdexcept>
#include <string>
#include <vector>

namespace stf::core {

// Where one module may be.
struct PluginPlace {
  const char* file_name;  // "libstf_image_codec.so"
  const char* env_var;    // when set, the only place looked
  const char* libdir;     // where an install puts libraries, relative to its prefix ("lib")
  const char* installed;  // the full path `cmake --install` gives it
  const void* anchor;     // an address in the program or library that loads it
};

inline std::string folder_of(const std::string& path) {
  const std::size_t slash = path.rfind('/');
  return slash == std::string::npos ? "." : path.substr(0, slash);
}

// $ENV_VAR alone when set; else beside the file that holds the anchor (the stf program, or the
// Python module, whose folder's parent holds it in a build tree), beside the running program or
// in the library folder of its install prefix, and where `cmake --install` puts it.
inline std::vector<std::string> plugin_candidates(const PluginPlace& place) {
  if (const char* given = std::getenv(place.env_var)) return {given};
  const std::string name = place.file_name;
  std::vector<std::string> where;
  Dl_info info{};
  if (dladdr(place.anchor, &info) && info.dli_fname && std::string(info.dli_fname).find('/') != std::string::npos) {
    where.push_back(folder_of(info.dli_fname) + "/" + name);
    where.push_back(folder_of(info.dli_fname) + "/../" + name);
  }
  char exe[4096];
  const ssize_t n = readlink("/proc/self/exe", exe, sizeof exe - 1);
  if (n > 0) {
    const std::string program = folder_of(std::string(exe, std::size_t(n)));
    where.push_back(program + "/" + name);
    where.push_back(program + "/../" + place.libdir + "/stf/" + name);  // an installed stf
  }
  where.push_back(place.installed);
  return where;
}

// The address of `symbol` in the first candidate that loads (RTLD_LOCAL: the module's
// dependencies stay its own). Throws std::runtime_error "cannot load WHAT: why", where `what`
// names the module and what it is for.
inline void* plugin_export(const PluginPlace& place, const char* symbol, const std::string& what) {
  std::string why;
  for (const std::string& path : plugin_candidates(place)) {
    if (void* module = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL)) {
      if (void* address = dlsym(module, symbol)) return address;
      why = path + " has no " + symbol;
      continue;
    }
    if (why.empty()) why = dlerror();
  }
  throw std::runtime_error("cannot load " + what + ": " + why);
}

}  // namespace stf::core
