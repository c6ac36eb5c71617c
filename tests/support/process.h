// Test support: child processes as a user runs them, above all the real `fleetgw` binary.
//
// Contract:
//  * ChildProcess starts argv[0] (searched on PATH, no shell) with stdin from /dev/null and
//    stdout+stderr appended to `log_file` (stderr to `stderr_file` instead when given);
//    std::system_error names the program when it cannot be started. The log can be read at any time
//    (log(), log_contains()).
//  * running()/wait_exit() reap the child; exit codes are the process's own, or 128 + signal
//    when a signal ended it (as a shell reports it).
//  * stop() sends SIGTERM and waits up to `grace`, then SIGKILL; kill() is SIGKILL at once. The
//    destructor kills and reaps a child that is still running and never throws.
//  * GatewayProcess is a ChildProcess running `<binary> run --config <config> [extra args]`,
//    its log in the config's directory.
//  * Not thread-safe: drive one instance from one thread.
#pragma once

#include <sys/types.h>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "tests/support/files.h"

namespace fleetgw::testing {

class ChildProcess {
 public:
  ChildProcess(std::vector<std::string> argv, std::filesystem::path log_file,
               const std::optional<std::filesystem::path>& stderr_file = std::nullopt);
  ~ChildProcess();
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;
  ChildProcess(ChildProcess&& other) noexcept;
  ChildProcess& operator=(ChildProcess&& other) = delete;

  pid_t pid() const { return pid_; }
  bool running();
  // The exit code once the process has ended (nullopt while it runs).
  std::optional<int> exit_code();
  // Waits (blocking) for the process to end by itself; returns the exit code.
  int wait();
  // Waits for the process to end by itself; nullopt when it still runs after `timeout`.
  std::optional<int> wait_exit(std::chrono::milliseconds timeout);
  // SIGTERM, then SIGKILL after `grace`; returns the exit code.
  int stop(std::chrono::milliseconds grace = std::chrono::seconds(10));
  // SIGKILL; returns the exit code (128 + 9 unless it had already ended).
  int kill();
  // Sends `sig` (e.g. SIGSTOP/SIGCONT) if the process still runs.
  void signal(int sig);

  const std::filesystem::path& log_file() const { return log_file_; }
  std::string log() const;
  bool log_contains(std::string_view text) const;

 private:
  void reaped(int status);

  pid_t pid_ = -1;
  std::optional<int> exit_code_;
  std::filesystem::path log_file_;
};

class GatewayProcess : public ChildProcess {
 public:
  GatewayProcess(const std::filesystem::path& binary, const std::filesystem::path& config,
                 const std::vector<std::string>& extra_args = {});
};

// `<binary> run --config <config>`, its output in `log`; stopped with SIGTERM (and reaped) on
// destruction, so the service shuts down as it does in the field (GatewayProcess is killed).
class ServiceProcess : public ChildProcess {
 public:
  ServiceProcess(const std::filesystem::path& binary, const std::filesystem::path& config,
                 const std::filesystem::path& log)
      : ChildProcess({binary.string(), "run", "--config", config.string()}, log) {}
  ~ServiceProcess() { stop(); }
  ServiceProcess(const ServiceProcess&) = delete;
  ServiceProcess& operator=(const ServiceProcess&) = delete;
};

// Runs a program (no shell) and waits; throws std::runtime_error with its output on failure.
void run_program(const std::vector<std::string>& argv, const std::filesystem::path& output_file);

// Runs a program (no shell) with stdout+stderr appended to `output_file` (stderr to
// `stderr_file` when given); returns its exit code (128 + signal when killed).
int run_for_exit_code(const std::vector<std::string>& argv,
                      const std::filesystem::path& output_file,
                      const std::optional<std::filesystem::path>& stderr_file = std::nullopt);

// A free TCP port on 127.0.0.1 (bound and released; the usual tiny race applies).
std::uint16_t free_loopback_port();

// A program run to completion with its stdout and stderr in their own files.
struct CapturedRun {
  int code = -1;  // exit code (128 + signal); -1 when it did not end within the timeout
  std::string out;
  std::string err;
};

// A child process with stdout and stderr in their own files (killed and reaped on
// destruction).
class CapturedChild : public ChildProcess {
 public:
  CapturedChild(const std::vector<std::string>& argv, const std::filesystem::path& out,
                const std::filesystem::path& err)
      : ChildProcess(argv, out, err), err_(err) {}
  // Exit code once the child has exited within `timeout` (128 + signal for a signal), or nullopt.
  std::optional<int> wait(std::chrono::milliseconds timeout) { return wait_exit(timeout); }
  std::string out() const { return log(); }
  std::string err() const;

 private:
  std::filesystem::path err_;
};

// Runs `argv` to completion, its output in numbered files in `dir`; after `timeout` (a safety
// net for a hang, not a timing goal) it is killed and `code` is -1.
CapturedRun run_captured(const std::vector<std::string>& argv, const std::filesystem::path& dir,
                         std::chrono::milliseconds timeout = std::chrono::seconds(60));

}  // namespace fleetgw::testing
