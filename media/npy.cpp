#include "npy.h"

#include <bit>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>

namespace stf::media {

static_assert(std::endian::native == std::endian::little, "the .npy reader copies little-endian values as they are");

namespace {

// A cursor over the header's dict literal, e.g. {'descr': '<f4', 'fortran_order': False, 'shape': (2, 3, 4), }.
struct DictText {
  const std::string& path;
  const std::string& text;
  std::size_t at = 0;

  [[noreturn]] void fail(const std::string& what) const {
    throw grid_error(path, "unreadable .npy header (" + what + "): " + text.substr(0, text.find('\n')));
  }
  void skip_space() {
    while (at < text.size() && (text[at] == ' ' || text[at] == '\t' || text[at] == '\n')) ++at;
  }
  bool take(char c) {
    skip_space();
    if (at < text.size() && text[at] == c) return ++at, true;
    return false;
  }
  void expect(char c) {
    if (!take(c)) fail(std::string("expected '") + c + "'");
  }
  std::string quoted() {
    skip_space();
    if (at >= text.size() || (text[at] != '\'' && text[at] != '"')) fail("expected a quoted string");
    const char quote = text[at];
    const std::size_t end = text.find(quote, at + 1);
    if (end == std::string::npos) fail("unterminated string");
    std::string s = text.substr(at + 1, end - at - 1);
    at = end + 1;
    return s;
  }
  std::string word() {
    skip_space();
    const std::size_t start = at;
    while (at < text.size() && std::isalnum(static_cast<unsigned char>(text[at]))) ++at;
    return text.substr(start, at - start);
  }
  std::vector<std::int64_t> tuple() {
    expect('(');
    std::vector<std::int64_t> values;
    while (!take(')')) {
      const std::string digits = word();
      if (digits.empty() || digits.find_first_not_of("0123456789") != std::string::npos || digits.size() > 18)
        fail("a dimension is not a non-negative integer");
      values.push_back(std::stoll(digits));
      if (!take(',')) {
        expect(')');
        break;
      }
    }
    return values;
  }
};

void read_entry(DictText& dict, NpyHeader& header, bool seen[3]) {
  const std::string key = dict.quoted();
  dict.expect(':');
  if (key == "descr") {
    header.descr = dict.quoted(), seen[0] = true;
  } else if (key == "fortran_order") {
    const std::string value = dict.word();
    if (value != "True" && value != "False") dict.fail("fortran_order is neither True nor False");
    header.fortran_order = value == "True", seen[1] = true;
  } else if (key == "shape") {
    header.shape = dict.tuple(), seen[2] = true;
  } else {
    dict.fail("unknown key '" + key + "'");
  }
}

}  // namespace

NpyHeader parse_npy_header(const std::string& path, const std::string& text) {
  DictText dict{path, text};
  NpyHeader header;
  bool seen[3] = {false, false, false};
  dict.expect('{');
  while (!dict.take('}')) {
    read_entry(dict, header, seen);
    if (!dict.take(',')) {
      dict.expect('}');
      break;
    }
  }
  if (!seen[0] || !seen[1] || !seen[2]) dict.fail("descr, fortran_order and shape are required");
  return header;
}

namespace {

std::string shape_text(const std::vector<std::int64_t>& shape) {
  std::ostringstream text;
  text << "(";
  for (std::size_t a = 0; a < shape.size(); ++a) text << (a ? ", " : "") << shape[a];
  text << (shape.size() == 1 ? ",)" : ")");
  return text.str();
}

// The header's text after the magic and version; throws on a foreign or cut file.
std::string read_header_text(const std::string& path, std::ifstream& in) {
  char start[8];
  if (!in.read(start, 8) || std::memcmp(start, "\x93NUMPY", 6) != 0)
    throw grid_error(path, "not a .npy file (it does not start with \\x93NUMPY)");
  const int major = static_cast<unsigned char>(start[6]), minor = static_cast<unsigned char>(start[7]);
  if (major < 1 || major > 3)
    throw grid_error(path, ".npy format version " + std::to_string(major) + "." + std::to_string(minor) +
                               " is not 1.0, 2.0 or 3.0");
  unsigned char size[4] = {0, 0, 0, 0};
  if (!in.read(reinterpret_cast<char*>(size), major == 1 ? 2 : 4)) throw grid_error(path, "truncated .npy header");
  const std::size_t length = size[0] | size[1] << 8 | std::size_t(size[2]) << 16 | std::size_t(size[3]) << 24;
  if (length > (1u << 20)) throw grid_error(path, "a .npy header of " + std::to_string(length) + " bytes (a dict is < 1 MiB)");
  std::string text(length, '\0');
  if (!in.read(text.data(), std::streamsize(length))) throw grid_error(path, "truncated .npy header");
  return text;
}

// The dims of a header fit for a density grid; throws naming what is wrong.
Dims check_header(const std::string& path, const NpyHeader& header) {
  if (header.descr != "<f4" && header.descr != "<f8")
    throw grid_error(path, "dtype '" + header.descr + "' is not little-endian float32 ('<f4') or float64 ('<f8')");
  if (header.fortran_order)
    throw grid_error(path, "fortran_order is True: densities are read in C order (numpy.ascontiguousarray)");
  if (header.shape.size() != 3)
    throw grid_error(path, "shape " + shape_text(header.shape) + " is not 3-D [nx, ny, nz]");
  for (std::int64_t n : header.shape)
    if (n == 0) throw grid_error(path, "shape " + shape_text(header.shape) + " has a zero dimension");
  return {header.shape[0], header.shape[1], header.shape[2]};
}

// Copies `count` little-endian values of `item` bytes into floats, failing on a float64 past
// float's range.
void read_values(const std::string& path, std::ifstream& in, int item, Lattice& lattice) {
  std::vector<char> chunk(std::size_t(1) << 22);
  const std::size_t count = lattice.values.size(), per_chunk = chunk.size() / std::size_t(item);
  for (std::size_t done = 0; done < count;) {
    const std::size_t n = std::min(per_chunk, count - done);
    if (!in.read(chunk.data(), std::streamsize(n * std::size_t(item)))) throw grid_error(path, "truncated .npy data");
    for (std::size_t i = 0; i < n; ++i, ++done) {
      if (item == 4) {
        std::memcpy(&lattice.values[done], &chunk[i * 4], 4);
        continue;
      }
      double v;
      std::memcpy(&v, &chunk[i * 8], 8);
      lattice.values[done] = float(v);
      if (std::isfinite(v) && !std::isfinite(lattice.values[done]))
        throw grid_error(path, "density " + std::to_string(v) + " at " + name_index(lattice, done) + " is past float's range");
    }
  }
}

// The data's size against what the header's shape and dtype need.
void check_data_size(const std::string& path, std::ifstream& in, double need) {
  const std::streamoff start = in.tellg();
  in.seekg(0, std::ios::end);
  const double have = double(in.tellg() - start);
  in.seekg(start);
  if (have == need) return;
  std::ostringstream what;
  what.precision(17);
  what << (have < need ? "truncated: " : "") << "the data is " << have << " bytes, the header's shape and dtype need " << need;
  throw grid_error(path, what.str());
}

}  // namespace

Lattice read_npy(const std::string& path, const Box& bounds, FitsCheck fits) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw grid_error(path, std::string("cannot open (") + std::strerror(errno) + ")");
  const NpyHeader header = parse_npy_header(path, read_header_text(path, in));
  Lattice lattice;
  lattice.source = path;
  lattice.dims = check_header(path, header);
  fits(path, lattice.dims);
  const int item = header.descr == "<f4" ? 4 : 8;
  check_data_size(path, in, double(lattice.dims[0]) * double(lattice.dims[1]) * double(lattice.dims[2]) * item);
  lattice.values.resize(std::size_t(lattice.dims[0] * lattice.dims[1] * lattice.dims[2]));
  read_values(path, in, item, lattice);
  place_in_bounds(lattice, bounds);
  return lattice;
}

namespace {

// Format 1.0's header: magic, version, the dict's length (2 bytes, little-endian), then the dict
// padded with spaces and ended by a newline so that the data starts at a multiple of 64 bytes
// (numpy's alignment, which memory-mapping readers count on).
std::string npy_header(const Dims& dims) {
  std::string dict = "{'descr': '<f4', 'fortran_order': False, 'shape': " + shape_text({dims[0], dims[1], dims[2]}) + ", }";
  const std::size_t unpadded = 10 + dict.size() + 1;
  dict.append((64 - unpadded % 64) % 64, ' ');
  dict += '\n';
  std::string header("\x93NUMPY\x01\x00", 8);
  header += char(dict.size() & 0xff);
  header += char(dict.size() >> 8);
  return header + dict;
}

}  // namespace

void write_npy(const std::string& path, const std::vector<float>& values, const Dims& dims) {
  const auto cannot = [&path]() { return grid_error(path, std::string("cannot write the .npy file (") + std::strerror(errno) + ")"); };
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw cannot();
  const std::string header = npy_header(dims);
  out.write(header.data(), std::streamsize(header.size()));
  out.write(reinterpret_cast<const char*>(values.data()), std::streamsize(values.size() * sizeof(float)));
  out.close();
  if (!out) throw cannot();
}

}  // namespace stf::media
