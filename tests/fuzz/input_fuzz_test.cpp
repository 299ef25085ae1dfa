// Files stf reads and may not have written, through the readers built from their own sources
// under AddressSanitizer and UndefinedBehaviorSanitizer: tables (stf's, with halves, and
// foreign ones, without), models (vMF and SH) and import inputs (.npy and text). Structured
// mutations give every attribute and dataset the readers take each wrong class, shape, type and
// value at and past its limits; byte flips and truncations of stf-written files must all be
// caught by their checksum. Every case loads (and is then usable) or fails with one line
// naming the file; a case running past its time limit fails the test (SIGALRM).
#include <H5Cpp.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>

#include "stf/core/files.h"
#include "stf/core/grid.h"
#include "stf/core/h5io.h"
#include "stf/core/import.h"
#include "stf/core/minimal_table.h"
#include "stf/fit/model_io.h"
#include "stf/core/rng.h"
#include "stf/sampler.h"
#include "stf/core/table.h"
#include "test_models.h"

namespace stf {
namespace {

namespace fs = std::filesystem;

// The case in progress, for the watchdog's message.
char current_case[256];
constexpr unsigned kCaseSeconds = 20;

void on_alarm(int) {
  const char head[] = "input_fuzz_test: a case ran past its time limit (a hang): ";
  [[maybe_unused]] ssize_t n = ::write(STDERR_FILENO, head, sizeof head - 1);
  n = ::write(STDERR_FILENO, current_case, std::strlen(current_case));
  n = ::write(STDERR_FILENO, "\n", 1);
  ::_exit(1);
}


void write_bytes(const std::string& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary | std::ios::trunc).write(bytes.data(), std::streamsize(bytes.size()));
}

std::string read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// An stf table with halves, tallied singular parts and a medium, as precompute writes it.
std::string tallied_table() {
  Table t;
  lay_out(t, *make_grid("healpix:2"), 6);
  std::uint64_t state = 5;
  const std::size_t n = std::size_t(t.alpha_bins) * std::size_t(t.cells);
  for (auto& half : t.weight_half) {
    half.resize(n);
    for (double& w : half) w = double(splitmix64(state) % 7);
  }
  t.once[2 * 3 + 0] = std::min(1.0, t.weight_half[0][3]);
  t.uncollided_half = {std::min(1.0, t.weight_half[0][0]), 0};
  t.medium = {4, 0.1, 0.5, 1};
  t.escaped_weight = 0;
  for (const auto& half : t.weight_half)
    for (double w : half) t.escaped_weight += w;
  t.absorbed_weight = 50;
  t.paths = std::int64_t(t.escaped_weight) + 50;
  t.collisions = 4 * t.paths;
  t.seed = 7;
  t.chunk_first = 0, t.chunk_last = 1, t.chunk_count = 1, t.run_paths = t.paths;
  t.generator = "input_fuzz_test";
  return table_file(t);
}

// A table stf did not make: the four datasets and a few attributes.
std::string foreign_table() {
  Table t;
  lay_out(t, *make_grid("csc:2"), 5);
  std::vector<double> weight(std::size_t(t.alpha_bins) * std::size_t(t.cells));
  for (std::size_t i = 0; i < weight.size(); ++i) weight[i] = double((i * 7) % 5);
  std::string bytes = minimal_table_file(t, weight, [](H5::H5File& f) {
    h5::put_attr(f, "paths", std::int64_t(1000));
    put_medium(f, {2, 0.5, -0.3, 1});
  });
  std::memset(bytes.data(), 0, h5::kUserBlockBytes);  // no checksum: foreign
  return bytes;
}

std::string model_bytes(const StfModel& m) {
  fit::FitReport report;
  report.bins.resize(std::size_t(m.bins()));
  return fit::model_file(m, report, {});
}

// A table reader's case: a loaded table is consistent.
void read_and_check_table(const std::string& path) {
  const Table t = read_table(path);
  EXPECT_EQ(table_error(t), "") << current_case;
}

// A model reader's case: a loaded model samples finitely.
void read_and_sample_model(const std::string& path) {
  const StfModel m = fit::read_model(path);
  ShellSampler sampler(m);
  for (double u : {0.0, 0.3, 0.999999})
    EXPECT_TRUE(std::isfinite(sampler.sample(u, 0.6, 1 - u, 0.9).pdf)) << current_case;
}


// ---- Structured mutations: an attribute or dataset of every wrong kind.

using P = H5::PredType;
constexpr int kAttributeVariants = 23, kDatasetVariants = 15;

// Replaces attribute `name` of `obj` by variant v: removed, arrays, strings, non-finite and
// extreme numbers, other integer and float types, a compound.
void replace_attribute(H5::H5Object& obj, const char* name, int v) {
  if (obj.attrExists(name)) obj.removeAttr(name);
  auto scalar = [&](const H5::DataType& type, const void* value) {
    obj.createAttribute(name, type, H5::DataSpace()).write(type, value);
  };
  auto array = [&](const H5::DataType& type, hsize_t n, const void* values) {
    H5::DataSpace space(1, &n);
    obj.createAttribute(name, type, space).write(type, values);
  };
  std::vector<double> many(1000);
  for (std::size_t i = 0; i < many.size(); ++i) many[i] = double(i);
  const double doubles[] = {std::nan(""), INFINITY, -INFINITY, 1e308, 1e-300, 0.5};
  const std::int64_t int64s[] = {-5, std::numeric_limits<std::int64_t>::max(), 5, 6};
  const std::uint64_t huge = std::numeric_limits<std::uint64_t>::max();
  const int ints[] = {0, 1, 2};
  const float one_and_half = 1.5f;
  const std::int8_t minus_one = -1;
  struct Pair { std::int64_t a; double b; } pair{1, 2};
  H5::CompType compound(sizeof(Pair));
  compound.insertMember("a", HOFFSET(Pair, a), P::NATIVE_INT64);
  compound.insertMember("b", HOFFSET(Pair, b), P::NATIVE_DOUBLE);
  switch (v) {
    case 0: return;
    case 1: return array(P::NATIVE_DOUBLE, 1000, many.data());
    case 2: return array(P::NATIVE_INT64, 2, &int64s[2]);
    case 3: return h5::put_attr(obj, name, std::string("8"));
    case 4: case 5: case 6: case 7: case 8: case 9: return scalar(P::NATIVE_DOUBLE, &doubles[v - 4]);
    case 10: case 11: return scalar(P::NATIVE_INT64, &int64s[v - 10]);
    case 12: return scalar(P::NATIVE_UINT64, &huge);
    case 13: case 14: case 15: return scalar(P::NATIVE_INT, &ints[v - 13]);
    case 16: return scalar(P::NATIVE_FLOAT, &one_and_half);
    case 17: return scalar(P::NATIVE_INT8, &minus_one);
    case 18: return scalar(compound, &pair);
    case 19: return array(P::NATIVE_DOUBLE, 1, many.data());
    case 20: return h5::put_attr(obj, name, std::string(5000, 'x'));
    case 21: return h5::put_attr(obj, name, std::string("healpix:2048"));
    default: return h5::put_attr(obj, name, std::string("csc:8"));
  }
}

// The values and shape of the numeric dataset at `path` (empty when there is none).
std::vector<double> dataset_values(H5::H5File& f, const std::string& path, std::vector<hsize_t>& dims) {
  dims.clear();
  if (!h5::has_object(f, path) || f.childObjType(path) != H5O_TYPE_DATASET) return {};
  H5::DataSet set = f.openDataSet(path);
  H5::DataSpace space = set.getSpace();
  dims.resize(std::size_t(space.getSimpleExtentNdims()));
  space.getSimpleExtentDims(dims.data());
  std::vector<double> values(std::size_t(space.getSimpleExtentNpoints()));
  if (!values.empty()) set.read(values.data(), P::NATIVE_DOUBLE);
  return values;
}

// Replaces the dataset at `path` by variant v: removed, of another class, type or shape,
// holding NaN, a negative or huge values, or a group in its place.
void replace_dataset(H5::H5File& f, const std::string& path, int v) {
  std::vector<hsize_t> dims;
  std::vector<double> values = dataset_values(f, path, dims);
  if (dims.empty()) dims = {3}, values = {1, 2, 3};
  if (h5::has_object(f, path)) f.unlink(path);
  const std::size_t slash = path.find_last_of('/');
  H5::Group group = f.openGroup(slash == 0 ? "/" : path.substr(0, slash));
  const std::string name = path.substr(slash + 1);
  H5::DataSpace space(int(dims.size()), dims.data());
  auto typed = [&](const H5::DataType& type) { group.createDataSet(name, type, space).write(values.data(), P::NATIVE_DOUBLE); };
  std::vector<hsize_t> other = dims;
  switch (v) {
    case 0: return;
    case 1: group.createDataSet(name, H5::StrType(P::C_S1, 8), space); return;
    case 2: { H5::CompType c(std::size_t(16)); c.insertMember("a", 0, P::NATIVE_DOUBLE); c.insertMember("b", 8, P::NATIVE_DOUBLE);
              group.createDataSet(name, c, space); return; }
    case 3: return typed(P::NATIVE_INT32);
    case 4: return typed(P::NATIVE_FLOAT);
    case 5: other = {hsize_t(values.size())}; break;
    case 6: other[0] = other[0] > 0 ? other[0] - 1 : 0; break;
    case 7: other.push_back(1); break;
    case 8: other = {}; values.resize(1); break;
    case 9: values[0] = std::nan(""); break;
    case 10: values.back() = -1; break;
    case 11: for (double& x : values) x = 1e308; break;
    case 12: for (double& x : values) x *= 2; break;
    case 13: group.createGroup(name); return;
    default: other[0] = 0; break;
  }
  std::size_t count = 1;
  for (hsize_t d : other) count *= d;
  values.resize(std::max<std::size_t>(count, 1));
  H5::DataSpace changed = other.empty() ? H5::DataSpace() : H5::DataSpace(int(other.size()), other.data());
  H5::DataSet set = group.createDataSet(name, P::NATIVE_DOUBLE, changed);
  if (count > 0) set.write(values.data(), P::NATIVE_DOUBLE);
}

// `base` (its checksum cleared: a file another program changed) after edit(file), or "" when
// HDF5 itself refused the edit.
std::string edited(const std::string& base, const std::string& scratch, const std::function<void(H5::H5File&)>& edit) {
  std::string bytes = base;
  std::memset(bytes.data(), 0, h5::kUserBlockBytes);
  write_bytes(scratch, bytes);
  try {
    H5::H5File f(scratch, H5F_ACC_RDWR);
    edit(f);
  } catch (const H5::Exception&) {
    return "";
  }
  return read_bytes(scratch);
}

struct Target {
  std::string group;  // "/" for the root
  std::vector<const char*> attributes, datasets;
};

const Target kTableRoot{"/", {"format", "format_version", "sigma_s", "sigma_a", "g", "radius", "tau", "albedo", "paths",
                              "seed", "max_scatter", "safety_cap", "grid", "escaped_weight", "absorbed_weight",
                              "truncated_weight", "collisions", "absorbed_collisions", "runtime_s", "generator",
                              "chunk_first", "chunk_last", "chunk_count", "run_paths"},
                        {"/escape/weight", "/escape/alpha_edges", "/grid/direction", "/grid/solid_angle",
                         "/escape/weight_half", "/escape/uncollided_half", "/escape/once_half",
                         "/escape/multiple_sub_half"}};
const Target kModelRoot{"/", {"format", "format_version", "model", "sigma_s", "sigma_a", "g", "radius", "tau", "albedo",
                              "escape_probability", "absorbed_fraction", "truncated_fraction", "uncollided_fraction",
                              "once_fraction", "hemispherical", "alpha_blend"},
                        {"/alpha/probability", "/alpha/edges", "/alpha/status", "/alpha/tilt", "/alpha/turn",
                         "/alpha/blend", "/vmf/weight", "/vmf/kappa", "/vmf/mean", "/sh/coefficients", "/sh/chebyshev"}};
const Target kVmfGroup{"/vmf", {"lobes"}, {}};
const Target kShGroup{"/sh", {"band_limit", "table_nz", "alpha_degree"}, {}};

class InputFuzz : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("stf-input-fuzz-" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    ::signal(SIGALRM, on_alarm);
  }
  void TearDown() override {
    ::alarm(0);
    fs::remove_all(dir_);
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  // Runs read(path) on `bytes` written to a file: it must return (check(result) then holds)
  // or throw std::runtime_error naming the file. Returns whether it loaded.
  template <typename Read>
  bool run_case(const std::string& name, const std::string& bytes, Read read) {
    std::snprintf(current_case, sizeof current_case, "%s", name.c_str());
    const std::string file = path(file_name_);
    write_bytes(file, bytes);
    ::alarm(kCaseSeconds);
    bool loaded = false;
    try {
      read(file);
      loaded = true;
    } catch (const std::runtime_error& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(file), std::string::npos) << name << ": " << what;
      EXPECT_EQ(what.find('\n'), std::string::npos) << name << ": " << what;
    }
    ::alarm(0);
    return loaded;
  }

  // Every variant of every attribute and dataset of `target` in `base` through read(path);
  // counts the cases loaded and refused.
  template <typename Read>
  void mutate_all(const std::string& base, const Target& target, const std::string& label, Read read) {
    auto one = [&](const std::string& name, const std::function<void(H5::H5File&)>& edit) {
      const std::string bytes = edited(base, path("scratch.h5"), edit);
      if (!bytes.empty()) (run_case(label + " " + name, bytes, read) ? loaded_ : refused_) += 1;
    };
    for (const char* a : target.attributes)
      for (int v = 0; v < kAttributeVariants; ++v)
        one(std::string(a) + " variant " + std::to_string(v), [&](H5::H5File& f) {
          if (target.group == "/") return replace_attribute(f, a, v);
          H5::Group g = f.openGroup(target.group);
          replace_attribute(g, a, v);
        });
    for (const char* d : target.datasets)
      for (int v = 0; v < kDatasetVariants; ++v)
        one(std::string(d) + " variant " + std::to_string(v), [&](H5::H5File& f) { replace_dataset(f, d, v); });
  }

  fs::path dir_;
  std::string file_name_ = "case.h5";
  int loaded_ = 0, refused_ = 0;
};

// The user block's checksum line ends at its first newline, and the NUL after it ends what the
// reader takes as the line; the rest of the block is padding that no reader looks at.
std::size_t checksum_line_end(const std::string& bytes) { return bytes.find('\n') + 1; }

// A copy of `base` with 1-8 random bytes set to random values, or cut short; `changed` says
// whether any byte a reader relies on differs (outside the user block's padding).
std::string flipped(const std::string& base, std::uint64_t& state, bool& changed) {
  std::string bytes = base;
  const std::size_t line_end = checksum_line_end(base);
  if (splitmix64(state) % 4 == 0) {
    bytes.resize(splitmix64(state) % bytes.size());
    changed = true;
    return bytes;
  }
  for (int f = 0, flips = 1 + int(splitmix64(state) % 8); f < flips; ++f) {
    // Half the flips land in the user block, where the checksum line and its padding are.
    const std::size_t at = splitmix64(state) % (f % 2 ? bytes.size() : h5::kUserBlockBytes);
    bytes[at] = char(splitmix64(state));
  }
  changed = false;
  for (std::size_t i = 0; i < bytes.size(); ++i) changed = changed || (bytes[i] != base[i] && (i <= line_end || i >= h5::kUserBlockBytes));
  return bytes;
}

TEST_F(InputFuzz, TablesWithEveryAttributeAndDatasetMutatedLoadOrFailInOneLine) {
  mutate_all(tallied_table(), kTableRoot, "tallied table", read_and_check_table);
  mutate_all(foreign_table(), kTableRoot, "foreign table", read_and_check_table);
  EXPECT_GT(refused_, 500);
  EXPECT_GT(loaded_, 50);  // an attribute removed or a harmless type is still a table
}

TEST_F(InputFuzz, ModelsWithEveryAttributeAndDatasetMutatedLoadOrFailInOneLine) {
  const std::string vmf = model_bytes(test::turned(test::blended_by_bin(test::tilted(test::make_vmf_model()))));
  const std::string hvmf = model_bytes(test::hemispherical(test::with_uncollided(test::make_vmf_model())));
  const std::string sh = model_bytes(test::make_sh_model());
  for (const auto& [label, bytes] : {std::pair{"vmf model", vmf}, {"hvmf model", hvmf}, {"sh model", sh}}) {
    mutate_all(bytes, kModelRoot, label, read_and_sample_model);
    mutate_all(bytes, kVmfGroup, label, read_and_sample_model);
    mutate_all(bytes, kShGroup, label, read_and_sample_model);
  }
  EXPECT_GT(refused_, 500);
  EXPECT_GT(loaded_, 50);
}

TEST_F(InputFuzz, FlippedOrTruncatedStfFilesAreRefusedByTheirChecksum) {
  const std::vector<std::pair<std::string, std::function<void(const std::string&)>>> bases = {
      {tallied_table(), read_and_check_table},
      {model_bytes(test::make_vmf_model()), read_and_sample_model},
      {model_bytes(test::make_sh_model()), read_and_sample_model}};
  std::uint64_t state = 41;
  int refused = 0;
  for (int round = 0; round < 1500; ++round) {
    const auto& [base, read] = bases[std::size_t(round) % bases.size()];
    bool changed = false;
    const std::string bytes = flipped(base, state, changed);
    const bool loaded = run_case("flip round " + std::to_string(round), bytes, read);
    EXPECT_EQ(loaded, !changed) << "round " << round;
    refused += !loaded;
  }
  EXPECT_GT(refused, 1000);
}

// A .npy of [6, 48] float64 counts.
std::string npy_counts() {
  const std::string dict = "{'descr': '<f8', 'fortran_order': False, 'shape': (6, 48), }";
  std::string header = dict + std::string(64 - (10 + dict.size() + 1) % 64, ' ') + "\n";
  std::string bytes = std::string("\x93NUMPY\x01\x00", 8);
  bytes += char(header.size() & 0xff);
  bytes += char(header.size() >> 8);
  bytes += header;
  for (int i = 0; i < 6 * 48; ++i) {
    const double c = double(i % 9);
    bytes.append(reinterpret_cast<const char*>(&c), 8);
  }
  return bytes;
}

// Counts a reader returned are finite, >= 0, and sum to a total a table holds.
void check_counts(const std::vector<double>& counts) {
  double total = 0;
  for (double c : counts) {
    EXPECT_TRUE(std::isfinite(c) && c >= 0) << current_case;
    total += c;
  }
  EXPECT_LE(total, kMaxTotalWeight) << current_case;
}

// A text histogram of random rows from fields valid and not.
std::string random_rows(std::uint64_t& state) {
  static const char* fields[] = {"0", "1", "5", "47", "48", "-1", "3", "1e308", "nan", "inf", "2.5", "0x10", "#",
                                 ",", "\r", "1e400", "99999999999999999999", "0.3", "3.14159", "-0", "\x01", ""};
  std::string text;
  for (int row = 0, rows = 1 + int(splitmix64(state) % 6); row < rows; ++row) {
    for (int f = 0, n = 1 + int(splitmix64(state) % 6); f < n; ++f)
      text += std::string(fields[splitmix64(state) % std::size(fields)]) + (splitmix64(state) % 3 ? " " : ",");
    text += splitmix64(state) % 7 ? "\n" : "\r";
  }
  return text;
}

TEST_F(InputFuzz, ImportInputsLoadOrFailInOneLine) {
  Table layout;
  const std::unique_ptr<DirectionGrid> grid = make_grid("healpix:2");
  lay_out(layout, *grid, 6);
  const std::string npy = npy_counts();
  std::uint64_t state = 43;
  file_name_ = "case.npy";
  for (int round = 0; round < 1500; ++round) {
    std::string bytes = npy;
    if (round % 3 == 0) bytes.resize(splitmix64(state) % bytes.size());
    for (int f = 0, flips = int(splitmix64(state) % 4); f < flips; ++f)
      bytes[splitmix64(state) % std::min<std::size_t>(bytes.size(), round % 2 ? 128 : bytes.size())] = char(splitmix64(state));
    run_case("npy round " + std::to_string(round), bytes, [](const std::string& p) { check_counts(read_npy_counts(p, 6, 48)); });
  }
  file_name_ = "case.txt";
  for (int round = 0; round < 1500; ++round)
    run_case("text round " + std::to_string(round), random_rows(state),
             [&](const std::string& p) { check_counts(read_text_counts(p, layout, *grid)); });
}
}  // namespace
}  // namespace stf
