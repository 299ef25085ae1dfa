#include "stf/core/h5io.h"

#include <algorithm>
#include <atomic>
#include <stdexcept>
#include <string_view>

namespace stf::h5 {

namespace {

template <typename T>
void put_scalar(H5::H5Object& obj, const char* name, const H5::PredType& type, T value) {
  obj.createAttribute(name, type, H5::DataSpace()).write(type, &value);
}


// Chunks of about 1 MiB, filled from the last (fastest) dimension: one chunk per row made a
// million-row file hold a million chunks, whose index alone took gigabytes to write and read.
constexpr hsize_t kChunkBytes = hsize_t(1) << 20;

std::vector<hsize_t> chunk_shape(const std::vector<hsize_t>& dims, std::size_t element_bytes) {
  std::vector<hsize_t> chunk(dims.size(), 1);
  hsize_t room = std::max<hsize_t>(1, kChunkBytes / element_bytes);
  for (std::size_t i = dims.size(); i-- > 0 && room > 1;) {
    chunk[i] = std::min(dims[i], room);
    room /= chunk[i];
  }
  return chunk;
}

hsize_t product(const std::vector<hsize_t>& dims) {
  hsize_t total = 1;
  for (hsize_t d : dims) total *= d;
  return total;
}

// Large datasets are chunked and deflated (tables are mostly zeros far from the forward lobe).
H5::DataSet create(H5::Group& group, const char* name, const std::vector<hsize_t>& dims, std::size_t element_bytes,
                   const H5::PredType& type) {
  H5::DataSpace space(int(dims.size()), dims.data());
  H5::DSetCreatPropList props;
  if (product(dims) >= 4096) {
    std::vector<hsize_t> chunk = chunk_shape(dims, element_bytes);
    props.setChunk(int(chunk.size()), chunk.data());
    props.setShuffle();
    props.setDeflate(4);
  }
  return group.createDataSet(name, type, space, props);
}

template <typename T>
void put_array(H5::Group& group, const char* name, const std::vector<hsize_t>& dims,
               const T* data, const H5::PredType& type) {
  create(group, name, dims, sizeof(T), type).write(data, type);
}

// Row r of a dataset whose rows are its last dimension, as a hyperslab of the file's space.
H5::DataSpace row_space(const H5::DataSet& set, const std::vector<hsize_t>& dims, hsize_t r) {
  H5::DataSpace space = set.getSpace();
  std::vector<hsize_t> start(dims.size(), 0), count(dims.size(), 1);
  for (std::size_t i = dims.size() - 1; i-- > 0; r /= dims[i]) start[i] = r % dims[i];
  count.back() = dims.back();
  space.selectHyperslab(H5S_SELECT_SET, count.data(), start.data());
  return space;
}


// Each memory file needs a name of its own while it is open.
std::string memory_file_name() {
  static std::atomic<long> count{0};
  return "stf-memory-file-" + std::to_string(count++);
}

H5::FileAccPropList in_memory() {
  H5::FileAccPropList props;
  props.setCore(std::size_t(4) << 20, false);  // grows 4 MiB at a time, never backed by a file
  return props;
}

// Room at the file's start for stf's checksum (verify_checksum).
H5::FileCreatPropList with_user_block() {
  H5::FileCreatPropList props;
  props.setUserblock(kUserBlockBytes);
  return props;
}

}  // namespace

MemoryFile::MemoryFile() : file_(memory_file_name(), H5F_ACC_TRUNC, with_user_block(), in_memory()) {}

std::string MemoryFile::bytes() {
  file_.flush(H5F_SCOPE_LOCAL);
  const ssize_t size = H5Fget_file_image(file_.getId(), nullptr, 0);
  if (size < 0) throw std::runtime_error("cannot take the image of an HDF5 file in memory");
  std::string image(std::size_t(size), '\0');
  if (H5Fget_file_image(file_.getId(), image.data(), image.size()) != size)
    throw std::runtime_error("cannot take the image of an HDF5 file in memory");
  file_.close();
  // The image starts at the superblock (libhdf5 1.10 leaves the user block it was made with
  // out); checked, so that a library that kept it would not get a second one.
  constexpr std::string_view kSignature("\x89HDF\r\n\x1a\n", 8);
  if (image.compare(0, kSignature.size(), kSignature) == 0) image.insert(0, kUserBlockBytes, '\0');
  else if (image.compare(kUserBlockBytes, kSignature.size(), kSignature) != 0)
    throw std::runtime_error("an HDF5 file image in memory has no superblock where stf expects it");
  stamp_checksum(image);
  return image;
}

void put_attr(H5::H5Object& obj, const char* name, double value) {
  put_scalar(obj, name, H5::PredType::NATIVE_DOUBLE, value);
}
void put_attr(H5::H5Object& obj, const char* name, std::int64_t value) {
  put_scalar(obj, name, H5::PredType::NATIVE_INT64, value);
}
void put_attr(H5::H5Object& obj, const char* name, int value) {
  put_scalar(obj, name, H5::PredType::NATIVE_INT, value);
}
void put_attr(H5::H5Object& obj, const char* name, const std::string& value) {
  H5::StrType type(H5::PredType::C_S1, H5T_VARIABLE);
  type.setCset(H5T_CSET_UTF8);
  const char* c = value.c_str();
  obj.createAttribute(name, type, H5::DataSpace()).write(type, &c);
}


void copy_attributes(const H5::H5Object& from, H5::H5Object& to) {
  for (int i = 0, n = from.getNumAttrs(); i < n; ++i) {
    H5::Attribute attr = from.openAttribute(unsigned(i));
    const H5::DataType type = attr.getDataType();
    const H5::DataSpace space = attr.getSpace();
    // In the file's own type: variable-length data come as pointers that the write follows and
    // the reclaim frees.
    const hid_t memory = H5Tget_native_type(type.getId(), H5T_DIR_DEFAULT);
    if (memory < 0) throw std::runtime_error("cannot copy attribute " + attr.getName());
    std::vector<char> buffer(std::size_t(space.getSimpleExtentNpoints()) * H5Tget_size(memory) + 1);
    const bool ok = H5Aread(attr.getId(), memory, buffer.data()) >= 0;
    bool written = false;
    try {
      H5::Attribute copy = to.createAttribute(attr.getName(), type, space);
      written = ok && H5Awrite(copy.getId(), memory, buffer.data()) >= 0;
    } catch (const H5::Exception&) {  // too large for an attribute of stf's files, say
    }
    if (ok && (H5Tdetect_class(memory, H5T_VLEN) > 0 || H5Tis_variable_str(memory) > 0))
      H5Dvlen_reclaim(memory, space.getId(), H5P_DEFAULT, buffer.data());
    H5Tclose(memory);
    if (!written)
      throw std::runtime_error("attribute '" + attr.getName() + "' cannot be copied into a new file (too large, or of a type HDF5 cannot convert)");
  }
}

void put_dataset(H5::Group& group, const char* name, const std::vector<hsize_t>& dims,
                 const double* data) {
  put_array(group, name, dims, data, H5::PredType::NATIVE_DOUBLE);
}
void put_dataset(H5::Group& group, const char* name, const std::vector<hsize_t>& dims,
                 const std::int32_t* data) {
  put_array(group, name, dims, data, H5::PredType::NATIVE_INT32);
}
void put_dataset(H5::Group& group, const char* name, const std::vector<hsize_t>& dims,
                 const std::int8_t* data) {
  put_array(group, name, dims, data, H5::PredType::NATIVE_INT8);
}

void get_rows(const H5::H5File& file, const char* path, const std::vector<hsize_t>& expect,
              const std::function<double*(hsize_t)>& row) {
  H5::DataSet set = open_dataset(file, path, expect);
  H5::DataSpace memory(1, &expect.back());
  for (hsize_t r = 0, rows = product(expect) / expect.back(); r < rows; ++r)
    set.read(row(r), H5::PredType::NATIVE_DOUBLE, memory, row_space(set, expect, r));
}

void put_rows(H5::Group& group, const char* name, const std::vector<hsize_t>& dims,
              const std::function<const double*(hsize_t)>& row) {
  H5::DataSet set = create(group, name, dims, sizeof(double), H5::PredType::NATIVE_DOUBLE);
  H5::DataSpace memory(1, &dims.back());
  for (hsize_t r = 0, rows = product(dims) / dims.back(); r < rows; ++r)
    set.write(row(r), H5::PredType::NATIVE_DOUBLE, memory, row_space(set, dims, r));
}


}  // namespace stf::h5
