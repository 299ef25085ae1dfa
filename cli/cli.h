// Shared pieces of the `stf` command line: the one error reporter, number parsing, atomic
// output files and interruption.
#pragma once

#include <atomic>
#include <cstdint>
#include <fstream>
#include <stdexcept>
#include <vector>
#include <string>

namespace CLI {
class App;
}

namespace stf::cli {

// A user error. main() prints it as one line, "stf: error: <message>", and exits with status 2;
// throwing (not exiting) lets destructors remove temporary files first.
struct Error : std::runtime_error {
  using std::runtime_error::runtime_error;
};
[[noreturn]] void fail(const std::string& message);

// Parses a count given in plain or exponent notation ("1e6"); it must be a whole number in
// [min, max]. Fails naming `option` otherwise.
std::int64_t parse_count(const std::string& text, const std::string& option, std::int64_t min,
                         std::int64_t max);

// Folder of the Python drawing scripts: $STF_TOOLS_DIR, else the source tree's tools/.
std::string tools_dir();

// Set by SIGINT / SIGTERM once install_interrupt_handler() ran.
extern std::atomic<bool> interrupted;
void install_interrupt_handler();

// An output file written under a temporary name in the same folder and renamed into place
// on commit(), so readers never see half a file and an existing file survives failures.
// The constructor checks that the folder is writable (failing with a message naming
// `option`); the destructor removes the temporary file unless committed.
class AtomicOutput {
 public:
  AtomicOutput(std::string path, const std::string& option);
  ~AtomicOutput();
  AtomicOutput(const AtomicOutput&) = delete;
  AtomicOutput& operator=(const AtomicOutput&) = delete;
  const std::string& temp_path() const { return temp_; }
  void commit();

 private:
  std::string path_, temp_;
  bool committed_ = false;
};

// Writes `bytes` (a string or a byte vector) to `path` through an AtomicOutput named by
// `option`.
template <typename Bytes>
void write_file(const std::string& path, const std::string& option, const Bytes& bytes) {
  AtomicOutput out(path, option);
  {
    std::ofstream f(out.temp_path(), std::ios::binary);
    f.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
    if (!f) fail("cannot write " + path);
  }
  out.commit();
}

// A progress bar with rate and ETA on stderr, shown only when stderr is a terminal.
class ProgressBar {
 public:
  ProgressBar(std::string label, bool quiet);
  void update(std::int64_t done, std::int64_t total, double seconds);
  void finish();

 private:
  std::string label_;
  bool enabled_;
  bool drawn_ = false;
};

void add_precompute_command(CLI::App& app);
void add_plot_command(CLI::App& app);
void add_pack_command(CLI::App& app);
void add_sample_command(CLI::App& app);
void add_build_command(CLI::App& app);
void add_report_command(CLI::App& app);
void add_fit_command(CLI::App& app);
void add_eval_command(CLI::App& app);

}  // namespace stf::cli
