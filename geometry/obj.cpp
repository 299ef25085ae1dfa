// A strict reader of OBJ meshes: every statement that shapes the surface is read exactly or
// refused by line. tinyobjloader, which stf used before, reads "v nan 0 0" and "v x y z" as
// zeros, wraps out-of-range indices, drops bad polygon corners and opens mtllib files (a FIFO
// there hangs the read); none of that can be switched off.
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <fmt/format.h>

#include <cerrno>
#include <charconv>
#include <cfloat>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <string_view>
#include <vector>

#include "stf/geometry/mesh.h"

namespace stf::geometry {

namespace {

struct ObjError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

[[noreturn]] void refuse(const std::string& what) { throw ObjError(what); }

// The file's bytes; a folder, FIFO or device is refused before it is opened for reading (a FIFO
// would block the open).
std::string file_bytes(const std::string& path) {
  struct stat st;
  if (::stat(path.c_str(), &st) != 0) throw std::runtime_error(path + ": " + std::strerror(errno));
  if (S_ISDIR(st.st_mode)) throw std::runtime_error(path + ": is a folder, not a mesh file");
  if (!S_ISREG(st.st_mode)) throw std::runtime_error(path + ": not a regular file (a FIFO, socket or device)");
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) throw std::runtime_error(path + ": " + std::strerror(errno));
  std::string bytes(std::size_t(st.st_size), '\0');
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::read(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int error = errno;
      ::close(fd);
      throw std::runtime_error(path + ": " + (n < 0 ? std::strerror(error) : "the file shrank while it was read"));
    }
    done += std::size_t(n);
  }
  ::close(fd);
  return bytes;
}

std::vector<std::string_view> tokens_of(std::string_view line) {
  std::vector<std::string_view> out;
  std::size_t at = 0;
  while (at < line.size()) {
    while (at < line.size() && (line[at] == ' ' || line[at] == '\t')) ++at;
    const std::size_t start = at;
    while (at < line.size() && line[at] != ' ' && line[at] != '\t') ++at;
    if (at > start) out.push_back(line.substr(start, at - start));
  }
  return out;
}

double coordinate(std::string_view token) {
  double x = 0;
  const auto [end, error] = std::from_chars(token.data(), token.data() + token.size(), x);
  if (error == std::errc::result_out_of_range) refuse(fmt::format("'{}' is out of range", token));
  if (error != std::errc() || end != token.data() + token.size()) refuse(fmt::format("'{}' is not a number", token));
  if (!std::isfinite(x)) refuse(fmt::format("'{}' is not finite", token));
  // Vertices are held at float precision (mesh.h).
  if (std::abs(x) > FLT_MAX) refuse(fmt::format("'{}' is beyond the range of float (3.4e38)", token));
  return x;
}

// x y z, optionally followed by a weight w or a colour r g b (numbers, not used).
Vec3 vertex(const std::vector<std::string_view>& t) {
  const std::size_t n = t.size() - 1;
  if (n != 3 && n != 4 && n != 6) refuse(fmt::format("a vertex needs three numbers x y z, got {}", n));
  for (std::size_t i = 4; i <= n; ++i) (void)coordinate(t[i]);
  return {double(float(coordinate(t[1]))), double(float(coordinate(t[2]))), double(float(coordinate(t[3])))};
}

// One corner of a face ("v", "v/vt", "v//vn" or "v/vt/vn"): the position's index from 0, for a
// positive index (from 1) or a negative one (back from the last vertex read).
std::uint32_t corner(std::string_view token, std::size_t vertices) {
  const std::string_view index = token.substr(0, token.find('/'));
  long long i = 0;
  const auto [end, error] = std::from_chars(index.data(), index.data() + index.size(), i);
  if (error == std::errc::result_out_of_range) refuse(fmt::format("the vertex index '{}' is out of range", index));
  if (error != std::errc() || end != index.data() + index.size())
    refuse(fmt::format("'{}' is not a vertex index (a nonzero integer)", token));
  for (std::string_view rest = token.substr(index.size()); !rest.empty();) {  // texture and normal indices
    rest.remove_prefix(1);
    const std::string_view part = rest.substr(0, rest.find('/'));
    if (!part.empty() && part.find_first_not_of("-0123456789") != std::string_view::npos)
      refuse(fmt::format("'{}' is not a face corner (v, v/vt, v//vn or v/vt/vn)", token));
    rest.remove_prefix(part.size());
  }
  const long long n = (long long)vertices;
  if (i == 0) refuse("vertex index 0: OBJ indices count from 1 (or back from -1)");
  if (i > n || i < -n)
    refuse(fmt::format("the face names vertex {}, but {} vertices are defined above this line", i, n));
  return std::uint32_t(i > 0 ? i - 1 : n + i);
}

// A convex polygon in fan order (every corner turns the same way about the polygon's normal);
// a concave one would fold over itself when fanned.
bool convex(const std::vector<std::uint32_t>& c, const std::vector<Vec3>& v) {
  Vec3 normal{0, 0, 0};  // Newell's normal
  for (std::size_t i = 0; i < c.size(); ++i) normal = normal + cross(v[c[i]], v[c[(i + 1) % c.size()]]);
  for (std::size_t i = 0; i < c.size(); ++i) {
    const Vec3 &a = v[c[i]], &b = v[c[(i + 1) % c.size()]], &d = v[c[(i + 2) % c.size()]];
    if (dot(cross(b - a, d - b), normal) < 0) return false;
  }
  return true;
}

void face(const std::vector<std::string_view>& t, TriangleMesh& mesh) {
  if (t.size() < 4) refuse(fmt::format("a face needs at least three vertices, got {}", t.size() - 1));
  std::vector<std::uint32_t> c;
  for (std::size_t i = 1; i < t.size(); ++i) c.push_back(corner(t[i], mesh.vertices.size()));
  if (c.size() > 3 && !convex(c, mesh.vertices))
    refuse(fmt::format("a polygon of {} vertices that is not convex: triangulate it", c.size()));
  for (std::size_t i = 1; i + 1 < c.size(); ++i) mesh.triangles.push_back({c[0], c[i], c[i + 1]});
}

bool free_form(std::string_view keyword) {
  for (const char* k : {"cstype", "deg", "bmat", "step", "curv", "curv2", "surf", "parm", "trim", "hole", "scrv", "sp", "con"})
    if (keyword == k) return true;
  return false;
}

void statement(std::string_view line, TriangleMesh& mesh) {
  if (line.find('\0') != std::string_view::npos) refuse("a NUL byte: this is not a text OBJ file");
  const std::vector<std::string_view> t = tokens_of(line.substr(0, line.find('#')));
  if (t.empty()) return;
  if (t[0] == "v") mesh.vertices.push_back(vertex(t));
  else if (t[0] == "f") face(t, mesh);
  else if (free_form(t[0])) refuse(fmt::format("'{}': free-form curves and surfaces are not read; export polygons", t[0]));
  // Everything else (vt, vn, o, g, s, l, p, mtllib, usemtl, ...) does not shape the surface, and
  // no file it names is opened.
}

}  // namespace

TriangleMesh read_obj_as_written(const std::string& path) {
  const std::string bytes = file_bytes(path);
  TriangleMesh mesh;
  std::size_t number = 1;
  for (std::size_t at = 0; at < bytes.size(); ++number) {
    std::size_t end = bytes.find('\n', at);
    if (end == std::string::npos) end = bytes.size();
    std::string_view line(bytes.data() + at, end - at);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    try {
      statement(line, mesh);
    } catch (const ObjError& e) {
      throw std::runtime_error(fmt::format("{}:{}: {}", path, number, e.what()));
    }
    at = end + 1;
  }
  if (mesh.triangles.empty()) throw std::runtime_error(path + ": holds no triangle");
  if (mesh.vertices.size() > UINT32_MAX) throw std::runtime_error(path + ": more than 2^32 vertices");
  return mesh;
}

TriangleMesh read_obj(const std::string& path) { return welded(read_obj_as_written(path)); }

}  // namespace stf::geometry
