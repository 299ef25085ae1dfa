// The test fixture of the `stf` command-line tests: runs the built binary in a fresh folder
// per test and captures its exit status and stderr.
#pragma once

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace fs = std::filesystem;

struct Result {
  int status;
  std::string err;
};

class Cli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::path(::testing::TempDir()) / ("stf_cli_" + std::to_string(::getpid()) + "_" +
                                            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  Result stf(const std::string& args, std::string* out_text = nullptr) {
    std::string err = (dir_ / "stderr.txt").string(), out = (dir_ / "stdout.txt").string();
    std::string cmd = std::string(STF_BINARY) + " " + args + " 2>'" + err + "' >'" + out + "'";
    int raw = std::system(cmd.c_str());
    auto slurp = [](const std::string& path) {
      std::ifstream in(path);
      std::stringstream ss;
      ss << in.rdbuf();
      return ss.str();
    };
    std::string err_text = slurp(err);
    if (out_text) *out_text = slurp(out);
    fs::remove(err);
    fs::remove(out);
    return {WIFEXITED(raw) ? WEXITSTATUS(raw) : 128 + WTERMSIG(raw), err_text};
  }

  // Files in the test folder, other than the captured stderr.
  std::vector<std::string> files() const {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(dir_)) names.push_back(e.path().filename().string());
    return names;
  }

  std::string out(const std::string& name) const { return (dir_ / name).string(); }

  // No temporary, no lock and no file whose name starts with `also` anywhere below the test
  // folder.
  void expect_no_litter(const std::string& what, const std::string& also = "stf-") {
    for (const auto& e : fs::recursive_directory_iterator(dir_)) {
      const std::string name = e.path().filename().string();
      EXPECT_EQ(name.find(".tmp-"), std::string::npos) << what << ": " << e.path();
      EXPECT_FALSE(name.size() > 5 && name.compare(name.size() - 5, 5, ".lock") == 0)
          << what << ": " << e.path();
      EXPECT_NE(name.rfind(also, 0), 0u) << what << ": " << e.path();
    }
  }

  fs::path dir_;
};

inline const std::string kGood = "--sigma-s 2 --sigma-a 0.5 --g 0.3 --alpha-bins 6 --grid healpix:2 --paths 2000 --quiet";

// The mpirun prefix for `ranks` ranks (as root, OpenMPI needs to be told it may run).
inline std::string mpirun(int ranks) {
  std::string cmd = "mpirun --oversubscribe -n " + std::to_string(ranks) + " ";
  if (::geteuid() == 0) cmd += "--allow-run-as-root ";
  return cmd;
}

// Whether stf was built with MPI and mpirun is there.
inline bool have_mpi() {
#ifdef STF_TEST_MPI
  return std::system("mpirun --version >/dev/null 2>&1") == 0;
#else
  return false;
#endif
}

// Runs stf with `args`, sends SIGINT after `ms` milliseconds; returns the exit status, and in
// `seconds_to_exit` (when given) how long the process took to end after the signal.
inline int interrupt_after(std::vector<std::string> args, int ms, double* seconds_to_exit = nullptr) {
  pid_t pid = ::fork();
  if (pid == 0) {
    std::vector<char*> argv = {const_cast<char*>(STF_BINARY)};
    for (std::string& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    ::execv(STF_BINARY, argv.data());
    ::_exit(127);
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(ms));
  ::kill(pid, SIGINT);
  const auto sent = std::chrono::steady_clock::now();
  int status = 0;
  ::waitpid(pid, &status, 0);
  if (seconds_to_exit) *seconds_to_exit = std::chrono::duration<double>(std::chrono::steady_clock::now() - sent).count();
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

