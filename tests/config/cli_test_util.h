// Test helpers for tests that run the real `fleetgw` binary: the CLI tests' names for the
// toolkit's child process with its stdout and stderr in files, waited for with a deadline
// (never a fixed sleep), and its polling (tests/support).
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

#include "tests/support/files.h"
#include "tests/support/process.h"
#include "tests/support/wait.h"

namespace fleetgw::testing {

// The CLI tests' names for the toolkit's child with its output in files (tests/support).
using Child = CapturedChild;
using Result = CapturedRun;

// Runs the program to completion (at most `timeout`, else it is killed and the test fails).
inline Result run(const std::vector<std::string>& argv, const std::filesystem::path& dir,
                  std::chrono::milliseconds timeout = std::chrono::seconds(30)) {
  return run_captured(argv, dir, timeout);
}

}  // namespace fleetgw::testing
