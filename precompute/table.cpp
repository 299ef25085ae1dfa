#include "table.h"

#include <H5Cpp.h>

#include <stdexcept>

namespace stf {

std::vector<double> Table::weight() const {
  std::vector<double> sum(weight_half[0]);
  for (std::size_t i = 0; i < sum.size(); ++i) sum[i] += weight_half[1][i];
  return sum;
}

namespace {

constexpr int kFormatVersion = 1;

template <typename T>
const H5::PredType& h5_type();
template <>
const H5::PredType& h5_type<double>() { return H5::PredType::NATIVE_DOUBLE; }
template <>
const H5::PredType& h5_type<std::int64_t>() { return H5::PredType::NATIVE_INT64; }
template <>
const H5::PredType& h5_type<int>() { return H5::PredType::NATIVE_INT; }

template <typename T>
void put_attr(H5::H5Object& obj, const char* name, T value) {
  obj.createAttribute(name, h5_type<T>(), H5::DataSpace()).write(h5_type<T>(), &value);
}

void put_attr(H5::H5Object& obj, const char* name, const std::string& value) {
  H5::StrType type(H5::PredType::C_S1, H5T_VARIABLE);
  type.setCset(H5T_CSET_UTF8);
  const char* c = value.c_str();
  obj.createAttribute(name, type, H5::DataSpace()).write(type, &c);
}

template <typename T>
T get_attr(const H5::H5Object& obj, const char* name) {
  if (!obj.attrExists(name)) throw std::runtime_error(std::string("missing attribute ") + name);
  T value{};
  obj.openAttribute(name).read(h5_type<T>(), &value);
  return value;
}

std::string get_string_attr(const H5::H5Object& obj, const char* name) {
  if (!obj.attrExists(name)) throw std::runtime_error(std::string("missing attribute ") + name);
  H5::Attribute attr = obj.openAttribute(name);
  std::string value;
  attr.read(attr.getStrType(), value);
  return value;
}

// Row-major dataset of doubles; chunked and deflated when large (tables are mostly zeros far
// from the forward lobe).
void put_dataset(H5::Group& group, const char* name, const std::vector<hsize_t>& dims,
                 const double* data) {
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
  group.createDataSet(name, H5::PredType::NATIVE_DOUBLE, space, props)
      .write(data, H5::PredType::NATIVE_DOUBLE);
}

std::vector<double> get_dataset(const H5::H5File& file, const char* path,
                                const std::vector<hsize_t>& expect) {
  if (!file.nameExists(path)) throw std::runtime_error(std::string("missing dataset ") + path);
  H5::DataSet set = file.openDataSet(path);
  H5::DataSpace space = set.getSpace();
  std::vector<hsize_t> dims(space.getSimpleExtentNdims());
  space.getSimpleExtentDims(dims.data());
  if (dims != expect) throw std::runtime_error(std::string("unexpected shape of ") + path);
  hsize_t total = 1;
  for (hsize_t d : dims) total *= d;
  std::vector<double> data(total);
  set.read(data.data(), H5::PredType::NATIVE_DOUBLE);
  return data;
}

}  // namespace

void write_table(const Table& t, const std::string& path) {
  try {
    H5::Exception::dontPrint();
    H5::H5File file(path, H5F_ACC_TRUNC);
    put_attr(file, "format", std::string("stf-table"));
    put_attr(file, "format_version", kFormatVersion);
    put_attr(file, "sigma_s", t.medium.sigma_s);
    put_attr(file, "sigma_a", t.medium.sigma_a);
    put_attr(file, "g", t.medium.g);
    put_attr(file, "radius", t.medium.radius);
    put_attr(file, "tau", t.medium.tau());
    put_attr(file, "albedo", t.medium.albedo());
    put_attr(file, "paths", t.paths);
    put_attr(file, "seed", t.seed);
    put_attr(file, "max_scatter", t.max_scatter);
    put_attr(file, "safety_cap", t.safety_cap);
    put_attr(file, "grid", t.grid);
    put_attr(file, "escaped_weight", t.escaped_weight);
    put_attr(file, "absorbed_weight", t.absorbed_weight);
    put_attr(file, "truncated_weight", t.truncated_weight);
    put_attr(file, "collisions", t.collisions);
    put_attr(file, "runtime_s", t.runtime_s);
    put_attr(file, "generator", t.generator);

    const hsize_t bins = hsize_t(t.alpha_bins), cells = hsize_t(t.cells);
    H5::Group escape = file.createGroup("/escape");
    std::vector<double> weight = t.weight();
    put_dataset(escape, "weight", {bins, cells}, weight.data());
    std::vector<double> halves(2 * weight.size());
    std::copy(t.weight_half[0].begin(), t.weight_half[0].end(), halves.begin());
    std::copy(t.weight_half[1].begin(), t.weight_half[1].end(), halves.begin() + weight.size());
    put_dataset(escape, "weight_half", {2, bins, cells}, halves.data());
    put_dataset(escape, "alpha_edges", {bins + 1}, t.alpha_edges.data());

    H5::Group grid = file.createGroup("/grid");
    put_dataset(grid, "direction", {cells, 3}, t.direction.front().data());
    put_dataset(grid, "solid_angle", {cells}, t.solid_angle.data());
  } catch (const H5::Exception& e) {
    throw std::runtime_error("cannot write " + path + ": " + e.getDetailMsg());
  }
}

Table read_table(const std::string& path) {
  try {
    H5::Exception::dontPrint();
    H5::H5File file(path, H5F_ACC_RDONLY);
    if (get_string_attr(file, "format") != "stf-table")
      throw std::runtime_error("not an stf table (format attribute is not 'stf-table')");
    if (int v = get_attr<int>(file, "format_version"); v != kFormatVersion)
      throw std::runtime_error("unsupported table format_version " + std::to_string(v));
    Table t;
    t.medium = {get_attr<double>(file, "sigma_s"), get_attr<double>(file, "sigma_a"),
                get_attr<double>(file, "g"), get_attr<double>(file, "radius")};
    t.paths = get_attr<std::int64_t>(file, "paths");
    t.seed = get_attr<std::int64_t>(file, "seed");
    t.max_scatter = get_attr<std::int64_t>(file, "max_scatter");
    t.safety_cap = get_attr<std::int64_t>(file, "safety_cap");
    t.grid = get_string_attr(file, "grid");
    t.escaped_weight = get_attr<double>(file, "escaped_weight");
    t.absorbed_weight = get_attr<double>(file, "absorbed_weight");
    t.truncated_weight = get_attr<double>(file, "truncated_weight");
    t.collisions = get_attr<std::int64_t>(file, "collisions");
    t.runtime_s = get_attr<double>(file, "runtime_s");
    t.generator = get_string_attr(file, "generator");

    H5::DataSpace space = file.openDataSet("/escape/weight").getSpace();
    hsize_t dims[2] = {0, 0};
    if (space.getSimpleExtentNdims() != 2) throw std::runtime_error("/escape/weight is not 2D");
    space.getSimpleExtentDims(dims);
    t.alpha_bins = int(dims[0]);
    t.cells = std::int64_t(dims[1]);
    std::vector<double> halves = get_dataset(file, "/escape/weight_half", {2, dims[0], dims[1]});
    auto mid = halves.begin() + std::ptrdiff_t(dims[0] * dims[1]);
    t.weight_half[0].assign(halves.begin(), mid);
    t.weight_half[1].assign(mid, halves.end());
    t.alpha_edges = get_dataset(file, "/escape/alpha_edges", {dims[0] + 1});
    t.solid_angle = get_dataset(file, "/grid/solid_angle", {dims[1]});
    std::vector<double> dir = get_dataset(file, "/grid/direction", {dims[1], 3});
    t.direction.resize(dims[1]);
    for (std::size_t i = 0; i < dims[1]; ++i) t.direction[i] = {dir[3 * i], dir[3 * i + 1], dir[3 * i + 2]};
    return t;
  } catch (const H5::Exception& e) {
    throw std::runtime_error("cannot read " + path + ": " + e.getDetailMsg());
  }
}

}  // namespace stf
