// stf's checksum in the HDF5 user block (h5io.h): written by every stf writer, checked before
// libhdf5 reads a byte of the file.
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <xxhash.h>

#include <atomic>
#include <cerrno>
#include <cinttypes>
#include <cstdio>
#include <cstring>
#include <memory>
#include <stdexcept>

#include "stf/core/h5io.h"

namespace stf::h5 {

namespace {

// The user block's first line: the tag, the hash of the bytes after the block and the file's
// size in bytes.
constexpr const char* kTag = "stf-checksum xxh3-64 ";

std::string block_line(std::uint64_t hash, std::uint64_t size) {
  char line[96];
  std::snprintf(line, sizeof line, "%s%016" PRIx64 " %" PRIu64 "\n", kTag, hash, size);
  return line;
}

struct Fd {
  int fd;
  ~Fd() {
    if (fd >= 0) ::close(fd);
  }
};

// Reads up to n bytes at the file's current position; fewer only at its end.
std::size_t read_some(int fd, char* p, std::size_t n, const std::string& path) {
  std::size_t done = 0;
  while (done < n) {
    const ssize_t got = ::read(fd, p + done, n - done);
    if (got < 0 && errno == EINTR) continue;
    if (got < 0) throw std::runtime_error("cannot read " + path + ": " + std::strerror(errno));
    if (got == 0) break;
    done += std::size_t(got);
  }
  return done;
}

// The hash of what follows the user block, and how many bytes the file holds in all.
std::uint64_t hash_after_block(int fd, const std::string& path, std::uint64_t& size) {
  std::unique_ptr<XXH3_state_t, decltype(&XXH3_freeState)> state(XXH3_createState(), XXH3_freeState);
  XXH3_64bits_reset(state.get());
  std::vector<char> buffer(std::size_t(1) << 20);
  size = kUserBlockBytes;
  for (std::size_t got; (got = read_some(fd, buffer.data(), buffer.size(), path)) > 0; size += got)
    XXH3_64bits_update(state.get(), buffer.data(), got);
  return XXH3_64bits_digest(state.get());
}

// A user block whose tag survives in at least half its bytes: stf's, even where corruption hit
// the tag itself (a foreign user block matches it by chance in hardly any).
bool looks_stamped(const char* block) {
  const std::size_t tag = std::strlen(kTag);
  std::size_t same = 0;
  for (std::size_t i = 0; i < tag; ++i) same += block[i] == kTag[i];
  return 2 * same >= tag;
}

}  // namespace

void stamp_checksum(std::string& image) {
  if (image.size() < kUserBlockBytes) throw std::runtime_error("an HDF5 file image without its user block");
  const std::string line =
      block_line(XXH3_64bits(image.data() + kUserBlockBytes, image.size() - kUserBlockBytes), image.size());
  std::memcpy(image.data(), line.data(), line.size());
}

void verify_checksum(const std::string& path) {
  // Without blocking: a FIFO would wait for a writer in open() itself.
  Fd file{::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK)};
  if (file.fd < 0) throw std::runtime_error("cannot read " + path + ": " + std::strerror(errno));
  struct stat st;
  if (::fstat(file.fd, &st) != 0 || !S_ISREG(st.st_mode)) throw std::runtime_error(path + " is not a regular file");
  ::fcntl(file.fd, F_SETFL, ::fcntl(file.fd, F_GETFL) & ~O_NONBLOCK);
  char block[kUserBlockBytes];
  const std::size_t got = read_some(file.fd, block, sizeof block, path);
  const std::size_t tag = std::strlen(kTag);
  if (got < sizeof block || !looks_stamped(block)) return;  // a file stf did not write
  std::uint64_t hash = 0, size = 0, actual_size = 0;
  const std::string line(block, strnlen(block, sizeof block));
  const bool parsed = std::sscanf(line.c_str() + tag, "%16" SCNx64 " %" SCNu64, &hash, &size) == 2;
  const std::uint64_t actual = hash_after_block(file.fd, path, actual_size);
  if (!parsed || line != block_line(hash, size) || actual != hash || actual_size != size)
    throw std::runtime_error(path + ": its bytes do not match the checksum stf wrote into it (corrupted, or changed by "
                             "another program); to read it as a file stf did not write, clear its first 512 bytes "
                             "(dd if=/dev/zero of=FILE bs=512 count=1 conv=notrunc)");
}

H5::H5File open_file(const std::string& path) {
  verify_checksum(path);
  return H5::H5File(path, H5F_ACC_RDONLY);
}

}  // namespace stf::h5
