// Whether the process is still reading its inputs, having written nothing: then a first Ctrl-C
// may end it at once (stf's signal handler), since a library stuck in a malformed file, or a
// reader of millions of triangles, could keep it from ever polling the flag.
#pragma once

namespace stf::h5 {

// True while a ReadingInput lives in any thread.
bool reading_input();

// Marks its scope as reading inputs (HDF5 files, meshes).
class ReadingInput {
 public:
  ReadingInput();
  ~ReadingInput();
  ReadingInput(const ReadingInput&) = delete;
  ReadingInput& operator=(const ReadingInput&) = delete;
};

}  // namespace stf::h5
