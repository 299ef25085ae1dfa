// The checked readers of attributes and datasets (h5io.h): every value a file holds is checked
// for class, shape, type and range before stf uses it.
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <stdexcept>

#include "stf/core/h5io.h"

namespace stf::h5 {

namespace {

thread_local std::string at_object;

std::string object_name(const H5::H5Object& obj) {
  try {
    return obj.getObjName();
  } catch (const H5::Exception&) {
    return "?";
  }
}

std::string attr_where(const H5::H5Object& obj, const char* name) {
  return "attribute '" + std::string(name) + "' of " + object_name(obj);
}

const char* class_name(H5T_class_t c) {
  switch (c) {
    case H5T_INTEGER: return "an integer";
    case H5T_FLOAT: return "a float";
    case H5T_STRING: return "a string";
    case H5T_COMPOUND: return "a compound";
    case H5T_ENUM: return "an enum";
    case H5T_ARRAY: return "an array type";
    case H5T_VLEN: return "a variable-length sequence";
    case H5T_REFERENCE: return "a reference";
    case H5T_OPAQUE: return "an opaque value";
    case H5T_BITFIELD: return "a bitfield";
    default: return "a value of an unknown class";
  }
}

std::string format_number(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.6g", v);
  return text;
}

// The attribute `name`, checked to hold one value; `where` names it in messages.
H5::Attribute one_value(const H5::H5Object& obj, const char* name, const std::string& where) {
  at_object = where;
  if (!obj.attrExists(name)) throw std::runtime_error("missing " + where);
  H5::Attribute attr = obj.openAttribute(name);
  const hssize_t points = attr.getSpace().getSimpleExtentNpoints();
  if (points != 1) throw std::runtime_error(where + ": expected one value, found an array of " + std::to_string(points) + " values");
  return attr;
}

// A number attribute as a double: integer or float class.
double number(const H5::H5Object& obj, const char* name, const std::string& where, const std::string& expected) {
  H5::Attribute attr = one_value(obj, name, where);
  const H5T_class_t c = attr.getTypeClass();
  if (c != H5T_INTEGER && c != H5T_FLOAT) throw std::runtime_error(where + ": expected " + expected + ", found " + class_name(c));
  if (c == H5T_FLOAT) {
    double v = 0;
    attr.read(H5::PredType::NATIVE_DOUBLE, &v);
    return v;
  }
  std::int64_t v = 0;  // exact for whole numbers beyond 2^53
  attr.read(H5::PredType::NATIVE_INT64, &v);
  return double(v);
}

std::string shape_text(const std::vector<hsize_t>& dims) {
  std::string text = "[";
  for (std::size_t i = 0; i < dims.size(); ++i) text += (i ? ", " : "") + std::to_string(dims[i]);
  return text + "]";
}

std::string range_text(double lo, double hi) { return "[" + format_number(lo) + ", " + format_number(hi) + "]"; }

}  // namespace

const std::string& current_object() { return at_object; }

double get_double(const H5::H5Object& obj, const char* name, double lo, double hi) {
  const std::string where = attr_where(obj, name), expected = "a finite number in " + range_text(lo, hi);
  const double v = number(obj, name, where, expected);
  if (!(std::isfinite(v) && v >= lo && v <= hi)) throw std::runtime_error(where + ": expected " + expected + ", found " + format_number(v));
  return v;
}

std::int64_t get_int64(const H5::H5Object& obj, const char* name, std::int64_t lo, std::int64_t hi) {
  const std::string where = attr_where(obj, name), expected = "a whole number in " + range_text(double(lo), double(hi));
  H5::Attribute attr = one_value(obj, name, where);
  std::int64_t v = 0;
  if (attr.getTypeClass() == H5T_INTEGER) {
    attr.read(H5::PredType::NATIVE_INT64, &v);
  } else {
    const double d = number(obj, name, where, expected);
    if (!(d == std::floor(d) && std::abs(d) < 0x1p63)) throw std::runtime_error(where + ": expected " + expected + ", found " + format_number(d));
    v = std::int64_t(d);
  }
  if (v < lo || v > hi) throw std::runtime_error(where + ": expected " + expected + ", found " + std::to_string(v));
  return v;
}

int get_int(const H5::H5Object& obj, const char* name, int lo, int hi) { return int(get_int64(obj, name, lo, hi)); }

std::string get_string(const H5::H5Object& obj, const char* name) {
  const std::string where = attr_where(obj, name);
  H5::Attribute attr = one_value(obj, name, where);
  if (attr.getTypeClass() != H5T_STRING)
    throw std::runtime_error(where + ": expected a string, found " + class_name(attr.getTypeClass()));
  const H5::StrType type = attr.getStrType();
  if (!type.isVariableStr() && type.getSize() > kMaxStringBytes)
    throw std::runtime_error(where + ": a string of over " + std::to_string(kMaxStringBytes) + " bytes");
  std::string value;
  attr.read(type, value);
  if (value.size() > kMaxStringBytes) throw std::runtime_error(where + ": a string of over " + std::to_string(kMaxStringBytes) + " bytes");
  // A fixed-length string is padded with NULs; one inside would cut the text short elsewhere.
  if (!type.isVariableStr()) value.erase(value.find_last_not_of('\0') + 1);
  if (value.find('\0') != std::string::npos) throw std::runtime_error(where + ": a string holding a NUL byte");
  return value;
}

bool has_attr(const H5::H5Object& obj, const char* name) { return obj.attrExists(name); }

bool has_object(const H5::H5File& file, const std::string& path) {
  at_object = path;
  // Each link on the way must exist and lead to a group (H5Lexists fails on a path through a
  // dataset).
  for (std::size_t slash = path.find('/', 1);; slash = path.find('/', slash + 1)) {
    const std::string prefix = path.substr(0, slash);
    if (H5Lexists(file.getId(), prefix.c_str(), H5P_DEFAULT) <= 0) return false;
    if (slash == std::string::npos) return true;
    if (file.childObjType(prefix) != H5O_TYPE_GROUP) return false;
  }
}

H5::Group open_group(const H5::H5File& file, const std::string& path) {
  if (!has_object(file, path)) throw std::runtime_error("missing group " + path);
  if (file.childObjType(path) != H5O_TYPE_GROUP) throw std::runtime_error(path + " is not a group");
  return file.openGroup(path);
}

std::vector<hsize_t> dataset_shape(const H5::H5File& file, const char* path) {
  if (!has_object(file, path)) throw std::runtime_error(std::string("missing dataset ") + path);
  if (file.childObjType(path) != H5O_TYPE_DATASET) throw std::runtime_error(std::string(path) + " is not a dataset");
  H5::DataSpace space = file.openDataSet(path).getSpace();
  std::vector<hsize_t> dims(std::size_t(std::max(0, space.getSimpleExtentNdims())));
  space.getSimpleExtentDims(dims.data());
  return dims;
}


void require_memory(double bytes, const std::string& what) {
  const double memory = double(::sysconf(_SC_PHYS_PAGES)) * double(::sysconf(_SC_PAGESIZE));
  if (bytes > 0.8 * memory)
    throw std::runtime_error(what + " needs " + format_number(bytes / 1e9) + " GB, more than this machine's memory (" +
                             format_number(memory / 1e9) + " GB)");
}

H5::DataSet open_dataset(const H5::H5File& file, const char* path, const std::vector<hsize_t>& expect) {
  const std::vector<hsize_t> dims = dataset_shape(file, path);
  if (!expect.empty() && dims != expect)
    throw std::runtime_error(std::string(path) + ": expected shape " + shape_text(expect) + ", found " + shape_text(dims));
  H5::DataSet set = file.openDataSet(path);
  const H5T_class_t c = set.getTypeClass();
  if (c != H5T_INTEGER && c != H5T_FLOAT)
    throw std::runtime_error(std::string(path) + ": expected numbers, found " + class_name(c) + " dataset");
  double total = 1;
  for (hsize_t d : dims) total *= double(d);
  if (expect.empty() && total > double(kMaxFreeElements))
    throw std::runtime_error(std::string(path) + ": " + format_number(total) + " values, more than " +
                             std::to_string(kMaxFreeElements) + " this reader takes");
  require_memory(total * 8, path);
  return set;
}

namespace {

template <typename T>
std::vector<T> get_array(const H5::H5File& file, const char* path, const std::vector<hsize_t>& expect,
                         const H5::PredType& type) {
  H5::DataSet set = open_dataset(file, path, expect);
  const H5::DataSpace space = set.getSpace();
  std::vector<T> data(std::size_t(space.getSimpleExtentNpoints()));
  if (!data.empty()) set.read(data.data(), type);
  return data;
}

}  // namespace

std::vector<double> get_dataset(const H5::H5File& file, const char* path, const std::vector<hsize_t>& expect) {
  return get_array<double>(file, path, expect, H5::PredType::NATIVE_DOUBLE);
}

std::vector<std::int32_t> get_int_dataset(const H5::H5File& file, const char* path,
                                          const std::vector<hsize_t>& expect) {
  return get_array<std::int32_t>(file, path, expect, H5::PredType::NATIVE_INT32);
}

}  // namespace stf::h5
