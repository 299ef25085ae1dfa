// Small helpers over the HDF5 C++ API shared by the table, model and plot files.
#pragma once

#include <H5Cpp.h>

#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

namespace stf::h5 {

// An HDF5 file built in memory (HDF5's core driver, no backing store). Its bytes reach the
// disk only through one checked write (write_durably, replace_file): HDF5 never writes to disk
// itself, so a full disk cannot leave it holding a file it failed to close, which crashes the
// library when the process exits. Files are compressed, so the image is small beside the data.
class MemoryFile {
 public:
  MemoryFile();
  H5::H5File& file() { return file_; }
  // The finished file's bytes; the file is closed then.
  std::string bytes();

 private:
  H5::H5File file_;
};

void put_attr(H5::H5Object& obj, const char* name, double value);
void put_attr(H5::H5Object& obj, const char* name, std::int64_t value);
void put_attr(H5::H5Object& obj, const char* name, int value);
void put_attr(H5::H5Object& obj, const char* name, const std::string& value);

double get_double(const H5::H5Object& obj, const char* name);
std::int64_t get_int64(const H5::H5Object& obj, const char* name);
int get_int(const H5::H5Object& obj, const char* name);
std::string get_string(const H5::H5Object& obj, const char* name);
bool has_attr(const H5::H5Object& obj, const char* name);
// Copies every attribute of `from` (any type and shape, variable-length strings included) to `to`.
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
// Reads a float64 dataset of shape `expect` one row at a time into row(r).
void get_rows(const H5::H5File& file, const char* path, const std::vector<hsize_t>& expect,
              const std::function<double*(hsize_t)>& row);
// Reads a dataset and checks its shape; an empty `expect` accepts any shape.
std::vector<double> get_dataset(const H5::H5File& file, const char* path,
                                const std::vector<hsize_t>& expect);
std::vector<std::int32_t> get_int_dataset(const H5::H5File& file, const char* path,
                                          const std::vector<hsize_t>& expect);
std::vector<hsize_t> dataset_shape(const H5::H5File& file, const char* path);

// read(file) on `path` opened read-only, any failure rethrown in one line naming the file.
template <typename Read>
auto read_file(const std::string& path, Read read) {
  try {
    H5::Exception::dontPrint();
    H5::H5File file(path, H5F_ACC_RDONLY);
    return read(file);
  } catch (const H5::Exception& e) {
    throw std::runtime_error("cannot read " + path + ": " + e.getDetailMsg());
  } catch (const std::runtime_error& e) {  // a missing attribute or dataset, a bad value
    throw std::runtime_error(path + ": " + e.what());
  }
}

}  // namespace stf::h5
