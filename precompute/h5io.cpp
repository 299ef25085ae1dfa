#include "h5io.h"

#include <stdexcept>

namespace stf::h5 {

namespace {

template <typename T>
void put_scalar(H5::H5Object& obj, const char* name, const H5::PredType& type, T value) {
  obj.createAttribute(name, type, H5::DataSpace()).write(type, &value);
}

template <typename T>
T get_scalar(const H5::H5Object& obj, const char* name, const H5::PredType& type) {
  if (!obj.attrExists(name)) throw std::runtime_error(std::string("missing attribute ") + name);
  T value{};
  obj.openAttribute(name).read(type, &value);
  return value;
}

template <typename T>
void put_array(H5::Group& group, const char* name, const std::vector<hsize_t>& dims,
               const T* data, const H5::PredType& type) {
  H5::DataSpace space(int(dims.size()), dims.data());
  H5::DSetCreatPropList props;
  hsize_t total = 1;
  for (hsize_t d : dims) total *= d;
  if (total >= 4096) {
    std::vector<hsize_t> chunk(dims);
    chunk.front() = 1;
    props.setChunk(int(chunk.size()), chunk.data());
    props.setShuffle();
    props.setDeflate(4);
  }
  group.createDataSet(name, type, space, props).write(data, type);
}

template <typename T>
std::vector<T> get_array(const H5::H5File& file, const char* path,
                         const std::vector<hsize_t>& expect, const H5::PredType& type) {
  std::vector<hsize_t> dims = dataset_shape(file, path);
  if (!expect.empty() && dims != expect)
    throw std::runtime_error(std::string("unexpected shape of ") + path);
  hsize_t total = 1;
  for (hsize_t d : dims) total *= d;
  std::vector<T> data(total);
  if (total > 0) file.openDataSet(path).read(data.data(), type);
  return data;
}

}  // namespace

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

double get_double(const H5::H5Object& obj, const char* name) {
  return get_scalar<double>(obj, name, H5::PredType::NATIVE_DOUBLE);
}
std::int64_t get_int64(const H5::H5Object& obj, const char* name) {
  return get_scalar<std::int64_t>(obj, name, H5::PredType::NATIVE_INT64);
}
int get_int(const H5::H5Object& obj, const char* name) {
  return get_scalar<int>(obj, name, H5::PredType::NATIVE_INT);
}
std::string get_string(const H5::H5Object& obj, const char* name) {
  if (!obj.attrExists(name)) throw std::runtime_error(std::string("missing attribute ") + name);
  H5::Attribute attr = obj.openAttribute(name);
  std::string value;
  attr.read(attr.getStrType(), value);
  return value;
}
bool has_attr(const H5::H5Object& obj, const char* name) { return obj.attrExists(name); }

void put_dataset(H5::Group& group, const char* name, const std::vector<hsize_t>& dims,
                 const double* data) {
  put_array(group, name, dims, data, H5::PredType::NATIVE_DOUBLE);
}
void put_dataset(H5::Group& group, const char* name, const std::vector<hsize_t>& dims,
                 const std::int32_t* data) {
  put_array(group, name, dims, data, H5::PredType::NATIVE_INT32);
}

std::vector<double> get_dataset(const H5::H5File& file, const char* path,
                                const std::vector<hsize_t>& expect) {
  return get_array<double>(file, path, expect, H5::PredType::NATIVE_DOUBLE);
}
std::vector<std::int32_t> get_int_dataset(const H5::H5File& file, const char* path,
                                          const std::vector<hsize_t>& expect) {
  return get_array<std::int32_t>(file, path, expect, H5::PredType::NATIVE_INT32);
}

std::vector<hsize_t> dataset_shape(const H5::H5File& file, const char* path) {
  if (!file.nameExists(path)) throw std::runtime_error(std::string("missing dataset ") + path);
  H5::DataSpace space = file.openDataSet(path).getSpace();
  std::vector<hsize_t> dims(space.getSimpleExtentNdims());
  space.getSimpleExtentDims(dims.data());
  return dims;
}

}  // namespace stf::h5
