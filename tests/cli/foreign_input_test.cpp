// Inputs stf did not write, or that another program changed: tables and models edited with
// HDF5, histograms to import, a cache that is a file. Each is refused in one line that names the
// file and what is wrong in it, with exit 1 or 2, and nothing left behind.
#include <H5Cpp.h>

#include <algorithm>
#include <cstdint>
#include <functional>
#include <numeric>
#include <stdexcept>
#include <utility>

#include "cli_fixture.h"
#include "forget_checksum.h"

namespace {

const std::string kMedium =
    "precompute --sigma-s 4 --sigma-a 0.1 --g 0.5 --grid healpix:8 --alpha-bins 18 --paths 2e4 "
    "--threads 2 --quiet ";

std::string bytes_of(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// Inverts every bit of the byte at `offset`.
void flip_byte(const std::string& path, std::streamoff offset) {
  std::fstream f(path, std::ios::binary | std::ios::in | std::ios::out);
  char c = 0;
  f.seekg(offset);
  f.get(c);
  f.seekp(offset);
  f.put(char(~c));
  if (!f) throw std::runtime_error("cannot flip a byte of " + path);
}

// A new value of an attribute, written into a group under the attribute's name.
using Value = std::function<void(H5::Group&, const char*)>;

Value array_of(hsize_t n) {  // 0, 1, ..., n - 1 (as numpy.arange(n))
  return [n](H5::Group& g, const char* name) {
    std::vector<std::int64_t> v(n);
    std::iota(v.begin(), v.end(), 0);
    g.createAttribute(name, H5::PredType::NATIVE_INT64, H5::DataSpace(1, &n))
        .write(H5::PredType::NATIVE_INT64, v.data());
  };
}
Value integer(std::int64_t x) {
  return [x](H5::Group& g, const char* name) {
    g.createAttribute(name, H5::PredType::NATIVE_INT64, H5::DataSpace())
        .write(H5::PredType::NATIVE_INT64, &x);
  };
}
Value real(double x) {
  return [x](H5::Group& g, const char* name) {
    g.createAttribute(name, H5::PredType::NATIVE_DOUBLE, H5::DataSpace())
        .write(H5::PredType::NATIVE_DOUBLE, &x);
  };
}
Value text(const std::string& s) {  // a variable-length UTF-8 string, as stf writes its own
  return [s](H5::Group& g, const char* name) {
    H5::StrType type(H5::PredType::C_S1, H5T_VARIABLE);
    type.setCset(H5T_CSET_UTF8);
    const char* c = s.c_str();
    g.createAttribute(name, type, H5::DataSpace()).write(type, &c);
  };
}

// Replaces attribute `name` of the group `object` ("/" for the file's own) by `value`.
void replace_attr(const std::string& file, const char* object, const char* name,
                  const Value& value) {
  H5::H5File f(file, H5F_ACC_RDWR);
  H5::Group g = f.openGroup(object);
  if (g.attrExists(name)) g.removeAttr(name);
  value(g, name);
}

// Points every cell's /grid/direction the other way.
void negate_directions(const std::string& file) {
  H5::H5File f(file, H5F_ACC_RDWR);
  H5::DataSet d = f.openDataSet("/grid/direction");
  std::vector<double> v(std::size_t(d.getSpace().getSimpleExtentNpoints()));
  d.read(v.data(), H5::PredType::NATIVE_DOUBLE);
  for (double& x : v) x = -x;
  d.write(v.data(), H5::PredType::NATIVE_DOUBLE);
}

// A .npy file (format 1.0) of float64 counts [rows, cols].
void write_npy(const std::string& path, int rows, int cols, const std::vector<double>& counts) {
  std::string header = "{'descr': '<f8', 'fortran_order': False, 'shape': (" +
                       std::to_string(rows) + ", " + std::to_string(cols) + "), }";
  const std::size_t size = (10 + header.size() + 1 + 63) / 64 * 64 - 10;  // the data 64-aligned
  header.resize(size - 1, ' ');
  header += '\n';
  std::ofstream f(path, std::ios::binary);
  f.write("\x93NUMPY\x01\x00", 8);
  f.put(char(size & 0xff));
  f.put(char(size >> 8));
  f << header;
  f.write(reinterpret_cast<const char*>(counts.data()),
          std::streamsize(counts.size() * sizeof(double)));
}

// One stf table and its vmf:2 model, written by stf (with its checksum), for the whole suite.
class ForeignInput : public Cli {
 protected:
  static fs::path base() {
    return fs::path(::testing::TempDir()) / ("stf_foreign_" + std::to_string(::getpid()));
  }
  static void SetUpTestSuite() {
    fs::remove_all(base());
    fs::create_directories(base());
    const std::string stf = std::string(STF_BINARY) + " ";
    const std::string table = (base() / "t.h5").string(), model = (base() / "m.h5").string();
    ASSERT_EQ(std::system((stf + kMedium + "-o " + table).c_str()), 0);
    ASSERT_EQ(std::system((stf + "fit " + table + " --model vmf:2 --quiet -o " + model).c_str()),
              0);
  }
  static void TearDownTestSuite() { fs::remove_all(base()); }

  // The suite's `base_name` ("t.h5" or "m.h5") copied into the test folder as `name`.
  std::string copy_of(const char* base_name, const std::string& name) {
    fs::copy_file(base() / base_name, dir_ / name, fs::copy_options::overwrite_existing);
    return out(name);
  }
  // A copy of the suite's `base_name` as a file stf did not write, its attribute `attr` of
  // `object` replaced by `value`.
  std::string edited(const char* base_name, const std::string& name, const char* object,
                     const char* attr, const Value& value) {
    const std::string path = copy_of(base_name, name);
    stf::test::forget_checksum(path);
    replace_attr(path, object, attr, value);
    return path;
  }

  // Commands over an input; the outputs of refused commands are all named x.*.
  std::string fit(const std::string& table) {
    return "fit " + table + " --model vmf:2 --quiet -o " + out("x.h5");
  }
  std::string eval_of(const std::string& input) {  // as the model, against the suite's table
    return "eval " + input + " --reference " + (base() / "t.h5").string() + " --json " +
           out("x.json");
  }
  std::string eval_against(const std::string& table) {  // as the reference of the suite's model
    return "eval " + (base() / "m.h5").string() + " --reference " + table + " --json " +
           out("x.json");
  }
  std::string sample(const std::string& model, const std::string& output = "x.h5") {
    return "sample " + model + " --count 10 -o " + out(output);
  }

  // stf with `args`, killed after 20 s (a hang reads as status 137).
  Result run(const std::string& args) {
    const std::string err = out("stderr.txt");
    const std::string cmd = "timeout -s KILL 20 " + std::string(STF_BINARY) + " " + args + " 2>'" +
                            err + "' >/dev/null";
    const int raw = std::system(cmd.c_str());
    const std::string text = bytes_of(err);
    fs::remove(err);
    return {WIFEXITED(raw) ? WEXITSTATUS(raw) : 128 + WTERMSIG(raw), text};
  }

  // No lock, no temporary and no output of a refused command (x.*) anywhere in the test folder.
  void expect_no_litter(const std::string& what) { Cli::expect_no_litter(what, "x."); }

  // `args` refused: exit 1 or 2 (neither a success nor a signal), one line on stderr that starts
  // "stf: error:" and holds each of `names`, and no litter.
  Result expect_refused(const std::string& args, const std::vector<std::string>& names) {
    const Result r = run(args);
    EXPECT_TRUE(r.status == 1 || r.status == 2) << args << ": status " << r.status << "\n" << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << args << "\n" << r.err;
    EXPECT_EQ(r.err.rfind("stf: error:", 0), 0u) << args << "\n" << r.err;
    for (const std::string& name : names)
      EXPECT_NE(r.err.find(name), std::string::npos) << args << ": no '" << name << "' in\n"
                                                     << r.err;
    expect_no_litter(args);
    return r;
  }
};

// Finding 1: a scalar attribute given as an array (numpy.arange) is refused naming it, not read
// as its first element nor as garbage.
TEST_F(ForeignInput, ScalarAttributesGivenAsArraysAreRefused) {
  for (const char* attr : {"paths", "seed", "sigma_s"}) {
    const std::string table =
        edited("t.h5", std::string("a_") + attr + ".h5", "/", attr, array_of(1000));
    expect_refused(fit(table), {table, "'" + std::string(attr) + "'"});
  }
  const std::string two = edited("t.h5", "two.h5", "/", "paths", array_of(2));
  expect_refused(fit(two), {two, "'paths'"});
  for (const char* attr : {"tau", "format_version"}) {
    const std::string model =
        edited("m.h5", std::string("a_") + attr + ".h5", "/", attr, array_of(1000));
    expect_refused(sample(model), {model, "'" + std::string(attr) + "'"});
  }
  const std::string lobes = edited("m.h5", "lobes.h5", "/vmf", "lobes", array_of(1000));
  expect_refused(sample(lobes), {lobes, "'lobes'"});
}

// Finding 2: a grid attribute that names another grid than the table's cells, or directions
// that are not the grid's: one line from every reader, never an abort or a 50-million-cell
// allocation.
TEST_F(ForeignInput, TablesWhoseGridIsNotTheirCellsAreRefused) {
  std::vector<std::pair<std::string, std::string>> tables;  // file, what the line must name
  int i = 0;
  for (const char* grid : {"healpix:16", "healpix:4", "healpix:2048", "csc:8"}) {
    const std::string name = "grid" + std::to_string(i++) + ".h5";
    tables.push_back({edited("t.h5", name, "/", "grid", text(grid)), grid});
  }
  const std::string turned = copy_of("t.h5", "turned.h5");
  stf::test::forget_checksum(turned);
  negate_directions(turned);
  tables.push_back({turned, "/grid/direction"});
  for (const auto& [table, names] : tables)
    for (const std::string& command : {fit(table), eval_of(table), eval_against(table)})
      expect_refused(command, {table, names});
}

// Finding 3: a negative number of paths is a bad value, not a missing attribute.
TEST_F(ForeignInput, NegativePathsAreRefusedAsAValue) {
  const std::string table = edited("t.h5", "negative.h5", "/", "paths", integer(-5));
  for (const std::string& command : {fit(table), eval_of(table), eval_against(table)}) {
    const Result r = expect_refused(command, {table, "'paths'", "-5"});
    EXPECT_EQ(r.err.find("missing"), std::string::npos) << r.err;
  }
}

// Finding 4: a model of optical radius 1e12 is refused at once (the run is killed after 20 s).
TEST_F(ForeignInput, AModelOfHugeTauIsRefusedWithoutHanging) {
  const std::string model = edited("m.h5", "tau.h5", "/", "tau", real(1e12));
  const auto start = std::chrono::steady_clock::now();
  expect_refused(sample(model), {model, "tau"});
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(10));
}

// Finding 5: counts that sum past the largest double, in text or .npy, and malformed rows are
// refused naming the file (and the row), and the old output stays as it was.
TEST_F(ForeignInput, ImportRefusesOverflowAndBadRowsKeepingTheOldOutput) {
  std::ofstream(out("good.txt")) << "0 0 1\n1 3 2\n";
  std::ofstream(out("huge.txt")) << "0 3 1e308\n0 3 1e308\n";
  std::ofstream(out("six.txt")) << "0 3 1 4 5 6\n";
  std::ofstream(out("cr.txt")) << "0 0 1\r1 3 2\r";
  std::vector<double> counts(2 * 12, 0.0);
  counts[1] = counts[12 + 5] = 1e308;
  write_npy(out("huge.npy"), 2, 12, counts);
  const std::string import = " --grid healpix:1 --alpha-bins 2 --quiet -o " + out("old.h5");
  const Result first = run("import " + out("good.txt") + import);
  ASSERT_EQ(first.status, 0) << first.err;
  const std::string old = bytes_of(out("old.h5"));
  const std::vector<std::pair<std::string, std::vector<std::string>>> cases = {
      {"huge.txt", {out("huge.txt"), "line 2"}},
      {"huge.npy", {out("huge.npy")}},
      {"six.txt", {out("six.txt"), "line 1", "6 fields"}},
      {"cr.txt", {out("cr.txt"), "carriage return"}},
  };
  for (const auto& [input, names] : cases) {
    expect_refused("import " + out(input) + import, names);
    EXPECT_EQ(bytes_of(out("old.h5")), old) << input;
  }
}

// Finding 6: a --cache that is a regular file is refused before any work (a precompute would
// take minutes), and the file is left as it was.
TEST_F(ForeignInput, ACacheThatIsAFileIsRefusedAtOnce) {
  const std::string cache = out("cache");
  std::ofstream(cache) << "not a folder\n";
  const std::string scene = std::string(STF_SOURCE_DIR) + "/data/scenes/default.toml";
  const std::string render = "render --sigma-s 10 --sigma-a 0.1 --g 0.5 --spp 1 --width 4 ";
  const std::vector<std::string> commands = {
      render + "--height 4 --method stf --cache " + cache + " -o " + out("x.h5"),
      "build " + scene + " --quiet --cache " + cache + " -o " + out("x.stfpack"),
  };
  for (const std::string& command : commands) {
    const auto start = std::chrono::steady_clock::now();
    expect_refused(command, {"--cache"});
    EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(3)) << command;
  }
  EXPECT_EQ(bytes_of(cache), "not a folder\n");
}

// Finding 7: a table that calls itself a model gets a line of stf's own, not libhdf5's.
TEST_F(ForeignInput, ATableMarkedAsAModelGetsOneClearLine) {
  const std::string model = edited("t.h5", "marked.h5", "/", "format", text("stf-model"));
  for (const std::string& command : {eval_of(model), sample(model)}) {
    const Result r = expect_refused(command, {model});
    EXPECT_EQ(r.err.find("H5"), std::string::npos) << r.err;  // e.g. "H5Lexists failed"
    EXPECT_EQ(r.err.find("failed"), std::string::npos) << r.err;
  }
}

// Finding 8: a grid stored as a number is refused saying a string was expected.
TEST_F(ForeignInput, AGridStoredAsANumberIsRefused) {
  const std::string table = edited("t.h5", "number.h5", "/", "grid", integer(8));
  for (const std::string& command : {fit(table), eval_of(table), eval_against(table)})
    expect_refused(command, {table, "'grid'", "expected a string"});
}

// stf's checksum: an stf file reads; one byte changed past the user block and it is refused
// naming the checksum (fit and sample alike); with its user block cleared it reads again.
TEST_F(ForeignInput, AChangedByteIsCaughtByTheChecksumAndClearingItReads) {
  for (const char* base_name : {"m.h5", "t.h5"})
    EXPECT_EQ(bytes_of((base() / base_name).string()).rfind("stf-checksum xxh3-64 ", 0), 0u);
  const Result plain = run(sample((base() / "m.h5").string(), "s.h5"));
  ASSERT_EQ(plain.status, 0) << plain.err;
  fs::remove(out("s.h5"));
  for (const char* base_name : {"m.h5", "t.h5"}) {
    const std::string changed = copy_of(base_name, std::string("changed_") + base_name);
    const auto size = fs::file_size(changed);
    ASSERT_GT(size, 1024u);
    flip_byte(changed, std::streamoff(512 + (size - 512) / 2));
    const std::string command = base_name[0] == 'm' ? sample(changed) : fit(changed);
    expect_refused(command, {changed, "checksum"});
  }
  const std::string cleared = copy_of("m.h5", "cleared.h5");
  stf::test::forget_checksum(cleared);
  const Result r = run(sample(cleared, "s.h5"));
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_TRUE(fs::exists(out("s.h5")));
  const std::string table = copy_of("t.h5", "cleared_t.h5");
  stf::test::forget_checksum(table);
  const Result fitted = run("fit " + table + " --model vmf:2 --quiet -o " + out("f.h5"));
  EXPECT_EQ(fitted.status, 0) << fitted.err;
}

}  // namespace
