// Small helpers over the HDF5 C++ API shared by the table, model and plot files.
#pragma once

#include <H5Cpp.h>

#include <cstdint>
#include <functional>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "stf/core/reading_input.h"

namespace stf::h5 {

inline constexpr double kMaxFinite = std::numeric_limits<double>::max();
inline constexpr std::int64_t kMinInt64 = std::numeric_limits<std::int64_t>::min();
inline constexpr std::int64_t kMaxInt64 = std::numeric_limits<std::int64_t>::max();
inline constexpr int kMinInt = std::numeric_limits<int>::min(), kMaxInt = std::numeric_limits<int>::max();

// An HDF5 file built in memory (HDF5's core driver, no backing store). Its bytes reach the
// disk only through one checked write (write_durably, replace_file): HDF5 never writes to disk
// itself, so a full disk cannot leave it holding a file it failed to close, which crashes the
// library when the process exits. Files are compressed, so the image is small beside the data.
class MemoryFile {
 public:
  MemoryFile();
  H5::H5File& file() { return file_; }
  // The finished file's bytes, stf's checksum in their user block (open_file); the file is
  // closed then.
  std::string bytes();

 private:
  H5::H5File file_;
};

void put_attr(H5::H5Object& obj, const char* name, double value);
void put_attr(H5::H5Object& obj, const char* name, std::int64_t value);
void put_attr(H5::H5Object& obj, const char* name, int value);
void put_attr(H5::H5Object& obj, const char* name, const std::string& value);

// The readers of attributes and datasets. A file may come from anywhere, so each checks the
// object's class, shape and type, and a number's finiteness and range, before the value is
// used; it throws std::runtime_error naming the object and what it expected ("attribute
// 'paths' of /: expected one whole number in [1, 9.2e18], found an array of 1000 values"),
// and read_file adds the file's name.
//
// A number: a scalar (or one-element) attribute of integer or float class, finite, in [lo, hi];
// a whole number where an integer belongs.
double get_double(const H5::H5Object& obj, const char* name, double lo = -kMaxFinite, double hi = kMaxFinite);
std::int64_t get_int64(const H5::H5Object& obj, const char* name, std::int64_t lo = kMinInt64,
                       std::int64_t hi = kMaxInt64);
int get_int(const H5::H5Object& obj, const char* name, int lo = kMinInt, int hi = kMaxInt);
// A scalar string attribute of at most kMaxStringBytes bytes, without NUL.
std::string get_string(const H5::H5Object& obj, const char* name);
bool has_attr(const H5::H5Object& obj, const char* name);
inline constexpr std::size_t kMaxStringBytes = 4096;
// Copies every attribute of `from` (any type and shape, variable-length strings included) to `to`;
// throws std::runtime_error naming one that cannot be copied (too large for a new file, say).
void copy_attributes(const H5::H5Object& from, H5::H5Object& to);

// Row-major dataset; chunked and deflated when large (tables are mostly zeros far from the
// forward lobe).
void put_dataset(H5::Group& group, const char* name, const std::vector<hsize_t>& dims,
                 const double* data);
void put_dataset(H5::Group& group, const char* name, const std::vector<hsize_t>& dims,
                 const std::int32_t* data);
void put_dataset(H5::Group& group, const char* name, const std::vector<hsize_t>& dims,
                 const std::int8_t* data);
// A float64 dataset of shape `dims` written one row (the last dimension) at a time:
// row(r) points at row r's values. For tables too large to gather into one array first.
void put_rows(H5::Group& group, const char* name, const std::vector<hsize_t>& dims,
              const std::function<const double*(hsize_t)>& row);
// Reads a numeric dataset of shape `expect` one row at a time into row(r) as float64.
void get_rows(const H5::H5File& file, const char* path, const std::vector<hsize_t>& expect,
              const std::function<double*(hsize_t)>& row);
// Reads a numeric dataset (integer or float class) and checks its shape; an empty `expect`
// accepts any shape of at most kMaxFreeElements values.
std::vector<double> get_dataset(const H5::H5File& file, const char* path,
                                const std::vector<hsize_t>& expect);
std::vector<std::int32_t> get_int_dataset(const H5::H5File& file, const char* path,
                                          const std::vector<hsize_t>& expect);
inline constexpr hsize_t kMaxFreeElements = hsize_t(1) << 24;
// The numeric dataset at `path` of shape `expect` (empty: any), checked as get_dataset checks.
H5::DataSet open_dataset(const H5::H5File& file, const char* path, const std::vector<hsize_t>& expect);
// The shape of the dataset at `path` (missing, or not a dataset: one line naming it).
std::vector<hsize_t> dataset_shape(const H5::H5File& file, const char* path);
// True when `path` names an object of the file: every link on the way a group (a dataset or
// a missing link where a group belongs reads as "no such object", never an HDF5 error).
bool has_object(const H5::H5File& file, const std::string& path);
// The group at `path`: one line naming it when it is missing or not a group.
H5::Group open_group(const H5::H5File& file, const std::string& path);
// Fails naming `what` when `bytes` would not fit in this machine's memory (a file that claims
// a dataset of terabytes is refused before anything is allocated).
void require_memory(double bytes, const std::string& what);

// stf's own files carry a checksum of their bytes in the HDF5 user block (the first
// kUserBlockBytes bytes, which libhdf5 skips), written by MemoryFile::bytes(); open_file checks
// it before libhdf5 parses a byte, so a corrupted or edited file is refused in one line rather
// than reaching libhdf5's own bugs. Files without it (foreign tables, older outputs) open as
// they are.
inline constexpr std::size_t kUserBlockBytes = 512;
// Throws std::runtime_error naming `path` when the file holds stf's checksum and its bytes do
// not match it; does nothing for a file without one.
void verify_checksum(const std::string& path);
// `path` opened read-only after verify_checksum.
H5::H5File open_file(const std::string& path);
// Writes the checksum of an HDF5 file image with a user block of kUserBlockBytes into it.
void stamp_checksum(std::string& image);

// The object a reader is at, for the message of an HDF5 error that no check caught.
const std::string& current_object();

// read(file) on `path` opened read-only, any failure rethrown in one line naming the file.
// While it runs, reading_input() is true (stf/core/reading_input.h).
template <typename Read>
auto read_file(const std::string& path, Read read) {
  ReadingInput reading;
  try {
    H5::Exception::dontPrint();
    H5::H5File file = open_file(path);
    return read(file);
  } catch (const H5::Exception& e) {
    const std::string& at = current_object();
    throw std::runtime_error("cannot read " + path + (at.empty() ? "" : " at " + at) + ": " + e.getDetailMsg());
  } catch (const std::runtime_error& e) {  // a missing attribute or dataset, a bad value
    const std::string what = e.what();
    throw std::runtime_error(what.rfind(path + ":", 0) == 0 ? what : path + ": " + what);
  }
}

}  // namespace stf::h5
