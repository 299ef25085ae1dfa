#include "stf/core/reading_input.h"

#include <atomic>

namespace stf::h5 {

namespace {
std::atomic<int> readers{0};
}  // namespace

ReadingInput::ReadingInput() { ++readers; }
ReadingInput::~ReadingInput() { --readers; }
bool reading_input() { return readers.load() > 0; }

}  // namespace stf::h5
