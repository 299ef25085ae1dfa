#include "stf/render/png.h"

#include <algorithm>
#include <array>
#include <cmath>

namespace stf::render {

namespace {

std::uint32_t crc32(const std::uint8_t* data, std::size_t n, std::uint32_t crc = 0) {
  static const std::array<std::uint32_t, 256> table = [] {
    std::array<std::uint32_t, 256> t{};
    for (std::uint32_t i = 0; i < 256; ++i) {
      std::uint32_t c = i;
      for (int k = 0; k < 8; ++k) c = (c & 1) ? 0xedb88320u ^ (c >> 1) : c >> 1;
      t[i] = c;
    }
    return t;
  }();
  crc = ~crc;
  for (std::size_t i = 0; i < n; ++i) crc = table[(crc ^ data[i]) & 0xff] ^ (crc >> 8);
  return ~crc;
}

void put_u32(std::vector<std::uint8_t>& out, std::uint32_t v) {
  for (int shift = 24; shift >= 0; shift -= 8) out.push_back(std::uint8_t(v >> shift));
}

void put_chunk(std::vector<std::uint8_t>& out, const char* type, const std::vector<std::uint8_t>& data) {
  put_u32(out, std::uint32_t(data.size()));
  const std::size_t start = out.size();
  out.insert(out.end(), type, type + 4);
  out.insert(out.end(), data.begin(), data.end());
  put_u32(out, crc32(out.data() + start, out.size() - start));
}

// A zlib stream of stored (uncompressed) deflate blocks of at most 65535 bytes.
std::vector<std::uint8_t> zlib_stored(const std::vector<std::uint8_t>& raw) {
  std::vector<std::uint8_t> z{0x78, 0x01};
  std::uint32_t a = 1, b = 0;  // Adler-32
  for (std::uint8_t v : raw) a = (a + v) % 65521, b = (b + a) % 65521;
  std::size_t pos = 0;
  do {
    const std::size_t n = std::min<std::size_t>(65535, raw.size() - pos);
    const bool last = pos + n == raw.size();
    z.push_back(last ? 1 : 0);
    z.push_back(std::uint8_t(n)), z.push_back(std::uint8_t(n >> 8));
    z.push_back(std::uint8_t(~n)), z.push_back(std::uint8_t(~n >> 8));
    z.insert(z.end(), raw.begin() + std::ptrdiff_t(pos), raw.begin() + std::ptrdiff_t(pos + n));
    pos += n;
  } while (pos < raw.size());
  put_u32(z, (b << 16) | a);
  return z;
}

}  // namespace

std::vector<std::uint8_t> encode_png(const std::vector<std::uint8_t>& grey, int width, int height) {
  std::vector<std::uint8_t> png{0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  std::vector<std::uint8_t> header;
  put_u32(header, std::uint32_t(width));
  put_u32(header, std::uint32_t(height));
  header.insert(header.end(), {8, 0, 0, 0, 0});  // 8 bits, greyscale, deflate, no filter, no interlace
  put_chunk(png, "IHDR", header);
  std::vector<std::uint8_t> raw;
  raw.reserve(std::size_t(height) * std::size_t(width + 1));
  for (int y = 0; y < height; ++y) {
    raw.push_back(0);  // filter type of the row: none
    raw.insert(raw.end(), grey.begin() + std::ptrdiff_t(y) * width, grey.begin() + std::ptrdiff_t(y + 1) * width);
  }
  put_chunk(png, "IDAT", zlib_stored(raw));
  put_chunk(png, "IEND", {});
  return png;
}

std::vector<std::uint8_t> tone_map(const std::vector<double>& radiance) {
  std::vector<std::uint8_t> out(radiance.size());
  for (std::size_t i = 0; i < radiance.size(); ++i) {
    const double v = 1 - std::exp(-std::max(0.0, radiance[i]));
    const double srgb = v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1 / 2.4) - 0.055;
    out[i] = std::uint8_t(std::lround(255 * std::clamp(srgb, 0.0, 1.0)));
  }
  return out;
}

}  // namespace stf::render
