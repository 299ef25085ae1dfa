// Turns an HDF5 file stf wrote into one it did not write: the checksum stf keeps in the file's
// user block is cleared, so a test can edit the file with HDF5 and have the readers meet the
// edit itself rather than refuse the changed bytes. A file without the checksum fails the test:
// the edit would then meet another reader than the one the test means.
#pragma once

#include <gtest/gtest.h>

#include <cstring>
#include <fstream>
#include <string>

namespace stf::test {

inline void forget_checksum(const std::string& path) {
  std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
  char block[512] = {};
  f.read(block, sizeof block);
  if (!f || std::strncmp(block, "stf-checksum ", 13) != 0) {
    ADD_FAILURE() << path << " carries no stf checksum to clear";
    return;
  }
  std::memset(block, 0, sizeof block);
  f.seekp(0);
  f.write(block, sizeof block);
}

}  // namespace stf::test
