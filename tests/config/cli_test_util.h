// Test helpers for tests that run the real `fleetgw` binary: a child process with its stdout and
// stderr in files (tests/support/process.h underneath), waited for with a deadline (never a
// fixed sleep), and polling helpers.
#pragma once

#include <signal.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <functional>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "tests/support/process.h"

namespace fleetgw::testing {

// `text` cut at its newlines (a last line without one included).
inline std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string l; std::getline(in, l);) out.push_back(l);
  return out;
}

inline std::string slurp(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

inline void write_text(const std::filesystem::path& p, const std::string& text) {
  std::ofstream(p, std::ios::binary | std::ios::trunc) << text;
}

// Polls `done` every 20 ms until it holds or `timeout` passes; returns its last value.
inline bool wait_for(const std::function<bool()>& done, std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (true) {
    if (done()) return true;
    if (std::chrono::steady_clock::now() >= deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
}

// A child process with stdout and stderr in their own files: tests/support/process.h's
// ChildProcess (killed and reaped on destruction), with the names these CLI tests read best.
class Child : public ChildProcess {
 public:
  Child(const std::vector<std::string>& argv, const std::filesystem::path& out,
        const std::filesystem::path& err)
      : ChildProcess(argv, out, err), err_(err) {}
  // Exit code once the child has exited within `timeout` (128 + signal for a signal), or nullopt.
  std::optional<int> wait(std::chrono::milliseconds timeout) { return wait_exit(timeout); }
  std::string out() const { return log(); }
  std::string err() const { return slurp(err_); }

 private:
  std::filesystem::path err_;
};

struct Result {
  int code = -1;
  std::string out;
  std::string err;
};

// Runs the program to completion (at most `timeout`, else it is killed and the test fails).
inline Result run(const std::vector<std::string>& argv, const std::filesystem::path& dir,
                  std::chrono::milliseconds timeout = std::chrono::seconds(30)) {
  static int counter = 0;
  const auto n = std::to_string(++counter);
  Child c(argv, dir / ("out." + n), dir / ("err." + n));
  const auto code = c.wait(timeout);
  return {code.value_or(-1), c.out(), c.err()};
}

}  // namespace fleetgw::testing
