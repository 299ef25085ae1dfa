// Shared pieces of the `stf` command line: the one error reporter, number parsing, atomic
// output files and interruption.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <initializer_list>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "stf/core/parallel.h"

namespace CLI {
class App;
}

namespace stf {
struct Medium;
}

namespace stf::fit {
struct FitSettings;
}

namespace stf::cli {

// A user error. main() prints it as one line, "stf: error: <message>", and exits with status 2;
// throwing (not exiting) lets destructors remove temporary files first.
struct Error : std::runtime_error {
  using std::runtime_error::runtime_error;
};
[[noreturn]] void fail(const std::string& message);

// Ctrl-C or SIGTERM: main() prints the line and exits with status 128 + the signal (130 for
// SIGINT, 143 for SIGTERM), as shells expect.
struct Interrupted : Error {
  Interrupted() : Error("interrupted; nothing written") {}
};
// `stf build --strict` when an entry is not certified within the tolerance: exit status 3.
struct ToleranceNotMet : Error {
  using Error::Error;
};
// Throws Interrupted when the `interrupted` flag is set.
void stop_if_interrupted();

// Parses a count given in plain or exponent notation ("1e6"); it must be a whole number in
// [min, max]. Fails naming `option` otherwise.
std::int64_t parse_count(const std::string& text, const std::string& option, std::int64_t min,
                         std::int64_t max);

// Checks the TOML syntax of a --config file before CLI11 reads it (CLI11 would take a broken
// line for an unknown key); fails with one line naming the file, the line and what is wrong.
void check_config_syntax(int argc, char** argv);
// The --config file of this command line ("" when none or not a regular file), set by
// check_config_syntax: every AtomicOutput refuses to be it.
std::string& config_file();

// Folder of the Python drawing scripts: $STF_TOOLS_DIR, else the source tree's tools/.
std::string tools_dir();

// Set by the first SIGINT / SIGTERM once install_interrupt_handler() ran; long loops poll it
// and stop cleanly. A second signal removes the temporary files and locks of every open
// AtomicOutput and ends the process at once. `interrupt_signal` is the first signal's number.
extern std::atomic<bool> interrupted;
extern std::atomic<int> interrupt_signal;
// The exit status of an interrupted command: 128 + the first signal (130 for SIGINT).
int interrupted_status();
void install_interrupt_handler();

// A file a command reads or writes, with the option that named it (for messages).
struct NamedFile {
  std::string path, option;
};

// A temporary file in $TMPDIR (default /tmp) for a command's own use, stf-PID-XXXXXX, removed
// when it goes out of scope (or by a second Ctrl-C); those of processes that no longer run
// (killed with SIGKILL) are removed when the next one is made.
class ScratchFile {
 public:
  explicit ScratchFile(const std::string& what = "scratch");
  ~ScratchFile();
  ScratchFile(const ScratchFile&) = delete;
  ScratchFile& operator=(const ScratchFile&) = delete;
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

// One writer per output file: an advisory lock (flock) on TARGET.lock for the command's whole
// life, so a second stf writing the same file (or its checkpoint) is refused at once instead of
// mixing its temporaries with the first's. The lock file goes with its holder; one a killed
// process left is taken over.
class OutputLock {
 public:
  OutputLock(const std::string& target, const std::string& option, const std::string& path);
  ~OutputLock();
  OutputLock(const OutputLock&) = delete;
  OutputLock& operator=(const OutputLock&) = delete;

 private:
  std::string lock_;
  int fd_ = -1;
};

// True when `path` is written in place rather than replaced: "-" (standard output), a device,
// a FIFO or a /proc or /dev/fd link.
bool written_in_place(const std::string& path);

// An output file that never clobbers what it must not, and never shows half a file.
// A new or regular file is written under a temporary name in the folder of its final target
// (symbolic links followed, so a link stays a link), flushed to the device, and renamed into
// place on commit(), keeping the old file's permissions; an existing file survives any failure,
// a full disk included. A device, a FIFO or "-" (standard output) is never replaced: commit()
// copies the finished bytes into it. The constructor, which runs before any work, takes the
// output's lock and refuses a folder, an unwritable place or file and a file that is one of
// `keep` (the command's inputs and other outputs; the same file, not just the same name) or the
// --config file, with one line naming `option`. The destructor removes the temporary file unless committed.
class AtomicOutput {
 public:
  AtomicOutput(std::string path, std::string option, const std::vector<NamedFile>& keep = {});
  ~AtomicOutput();
  AtomicOutput(const AtomicOutput&) = delete;
  AtomicOutput& operator=(const AtomicOutput&) = delete;
  NamedFile named() const { return {path_, option_}; }
  bool in_place() const { return in_place_; }
  // Writes the whole file's bytes to the temporary (every step checked, one line naming the
  // output and the system's reason on failure) and commits.
  void write(std::string_view bytes);
  // The same without the commit, for outputs that go into place together.
  void stage(std::string_view bytes);
  // For a writer that needs a path (a Python script): write the temporary, then commit().
  const std::string& temp_path() const { return temp_; }
  // Puts the finished file in place, unless the command was interrupted (then nothing is).
  void commit();
  // Several staged outputs into place together: interrupted before the first or not at all.
  friend void commit_all(std::initializer_list<AtomicOutput*> outputs);

 private:
  void put_in_place();
  std::string path_, option_, target_, temp_;
  std::optional<OutputLock> lock_;
  std::optional<ScratchFile> scratch_;  // the temporary file of a device, FIFO or stdout
  bool in_place_ = false;  // device, FIFO or stdout: copy into it on commit
  bool committed_ = false;
};

void commit_all(std::initializer_list<AtomicOutput*> outputs);

// Fails naming the option when one of `inputs` is not an existing file. (For positional lists,
// where CLI11's own check would run before it reports an unknown option.)
void require_files(const std::vector<NamedFile>& inputs);

// Fails naming `option` unless `folder` is a folder this process may write in, or does not
// exist yet and could be made (its nearest existing parent is such a folder): checked before
// any work, so a cache that is a file does not fail a long run at its end.
void require_writable_folder(const std::string& folder, const std::string& option);

// True when the file `path` (which may not exist yet) lies in `folder` itself (links followed).
bool inside_folder(const std::string& path, const std::string& folder);

// Fails when `path` (an output) is the same file as one of `keep`.
void refuse_same_file(const std::string& path, const std::string& option, const std::vector<NamedFile>& keep);

// A byte vector (a pack, a PNG) as the bytes AtomicOutput takes.
inline std::string_view bytes_of(const std::vector<std::uint8_t>& v) {
  return {reinterpret_cast<const char*>(v.data()), v.size()};
}

// Writes `bytes` (a string or a byte vector) into an AtomicOutput and commits it.
template <typename Bytes>
void write_file(AtomicOutput& out, const Bytes& bytes) {
  out.write(std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
}

// Runs `/usr/bin/python3 tools_dir()/SCRIPT ARGS...` in its own process group; Ctrl-C (the
// `interrupted` flag) stops it and fails with "interrupted". A non-zero exit fails naming `what`.
void run_python(const std::string& script, const std::vector<std::string>& args, const std::string& what);

// A progress bar with rate and ETA on stderr, shown only when stderr is a terminal.
class ProgressBar {
 public:
  ProgressBar(std::string label, bool quiet);
  void update(std::int64_t done, std::int64_t total);
  void finish();
  // update() as a run's progress (stf/core/parallel.h); the run tells from one thread.
  ProgressFn progress() {
    return [this](std::string_view, std::int64_t done, std::int64_t total) { update(done, total); };
  }

 private:
  std::string label_;
  bool enabled_;
  bool drawn_ = false;
  const std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
};

// Progress over the spheres a pack needs, one call as each sphere starts: on a terminal one bar
// over all spheres with the time left (from the seconds the finished ones took), else a line
// per sphere saying the same. `command` heads the lines ("stf render").
class SphereProgress {
 public:
  SphereProgress(std::string command, bool quiet);
  ~SphereProgress() { finish(); }
  void start(int index, int count, const std::string& sphere);
  void finish();

 private:
  std::string command_;
  bool quiet_, terminal_;
  bool drawn_ = false;
  const std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
};

// One status line on stderr, shown only when stderr is a terminal, for work done in named steps
// of unknown number (a fit): the step, how much of it is done, the seconds so far. update() may
// be called from any thread; a call that finds another drawing is dropped.
class StepStatus {
 public:
  StepStatus(std::string label, bool quiet);
  ~StepStatus() { finish(); }  // an error's line starts on a line of its own
  void update(std::string_view step, std::int64_t done, std::int64_t total);
  void finish();  // clears the line
  ProgressFn progress() {
    return [this](std::string_view step, std::int64_t done, std::int64_t total) { update(step, done, total); };
  }

 private:
  std::string label_;
  bool enabled_;
  std::mutex mutex_;
  const std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
  double shown_ = -1;  // seconds when last drawn
};

// --sigma-s, --sigma-a, --g (required when `required`) and --radius, into `medium`.
void add_medium_options(CLI::App& cmd, Medium& medium, bool required);

// --model and --threads of the commands that fit (fit, smooth), and the settings they name:
// one line and exit 2 where they name none.
void add_fit_options(CLI::App& cmd, std::string& model, std::string& threads);
fit::FitSettings fit_settings(const std::string& model, const std::string& threads);

void add_precompute_command(CLI::App& app);
void add_merge_command(CLI::App& app);
void add_plot_command(CLI::App& app);
void add_pack_command(CLI::App& app);
void add_sample_command(CLI::App& app);
void add_build_command(CLI::App& app);
void add_report_command(CLI::App& app);
void add_fit_command(CLI::App& app);
void add_eval_command(CLI::App& app);
void add_render_command(CLI::App& app);
void add_import_command(CLI::App& app);
void add_smooth_command(CLI::App& app);
void add_mesh_command(CLI::App& app);
void add_grid_command(CLI::App& app);

}  // namespace stf::cli
