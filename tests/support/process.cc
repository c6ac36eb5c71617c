#include "tests/support/process.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <system_error>
#include <utility>

#include "tests/support/wait.h"

extern char** environ;

namespace fleetgw::testing {
namespace fs = std::filesystem;

namespace {

pid_t spawn(const std::vector<std::string>& argv, const fs::path& output,
            const std::optional<fs::path>& error_output) {
  if (argv.empty()) throw std::invalid_argument("spawn: empty argv");
  std::vector<char*> args;
  args.reserve(argv.size() + 1);
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, output.c_str(),
                                   O_WRONLY | O_CREAT | O_APPEND, 0600);
  if (error_output) {
    posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, error_output->c_str(),
                                     O_WRONLY | O_CREAT | O_APPEND, 0600);
  } else {
    posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
  }
  posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  pid_t pid = -1;
  const int rc = posix_spawnp(&pid, args[0], &actions, nullptr, args.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) {
    throw std::system_error(rc, std::generic_category(), "cannot start " + argv[0]);
  }
  return pid;
}

int code_of(int status) {
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  if (WIFSIGNALED(status)) return 128 + WTERMSIG(status);
  return -1;
}

}  // namespace

ChildProcess::ChildProcess(std::vector<std::string> argv, fs::path log_file,
                           const std::optional<fs::path>& stderr_file)
    : pid_(spawn(argv, log_file, stderr_file)), log_file_(std::move(log_file)) {}

ChildProcess::ChildProcess(ChildProcess&& other) noexcept
    : pid_(std::exchange(other.pid_, -1)),
      exit_code_(std::move(other.exit_code_)),
      log_file_(std::move(other.log_file_)) {}

ChildProcess::~ChildProcess() {
  kill();
}

void ChildProcess::reaped(int status) {
  exit_code_ = code_of(status);
}

bool ChildProcess::running() {
  // A moved-from object has no pid: never signal pid -1 (every process) or 0 (our group).
  return pid_ > 0 && !exit_code().has_value();
}

std::optional<int> ChildProcess::exit_code() {
  if (exit_code_ || pid_ <= 0) return exit_code_;
  int status = 0;
  if (::waitpid(pid_, &status, WNOHANG) == pid_) reaped(status);
  return exit_code_;
}

std::optional<int> ChildProcess::wait_exit(std::chrono::milliseconds timeout) {
  wait_until([&] { return exit_code().has_value(); }, timeout);
  return exit_code_;
}

int ChildProcess::stop(std::chrono::milliseconds grace) {
  if (running()) {
    ::kill(pid_, SIGTERM);
    if (!wait_exit(grace)) return kill();
  }
  return exit_code_.value_or(-1);
}

int ChildProcess::wait() {
  if (pid_ <= 0) return -1;
  if (exit_code_) return *exit_code_;
  int status = 0;
  while (::waitpid(pid_, &status, 0) < 0) {
    if (errno != EINTR) {
      exit_code_ = -1;
      return -1;
    }
  }
  reaped(status);
  return *exit_code_;
}

int ChildProcess::kill() {
  if (running()) {
    ::kill(pid_, SIGKILL);
    return wait();
  }
  return exit_code_.value_or(-1);
}

void ChildProcess::signal(int sig) {
  if (running()) ::kill(pid_, sig);
}

std::string ChildProcess::log() const {
  return read_text_file(log_file_);
}

bool ChildProcess::log_contains(std::string_view text) const {
  return log().find(text) != std::string::npos;
}

GatewayProcess::GatewayProcess(const fs::path& binary, const fs::path& config,
                               const std::vector<std::string>& extra_args)
    : ChildProcess(
          [&] {
            std::vector<std::string> argv{binary.string(), "run", "--config", config.string()};
            argv.insert(argv.end(), extra_args.begin(), extra_args.end());
            return argv;
          }(),
          config.parent_path() / "fleetgw.log") {}

int run_for_exit_code(const std::vector<std::string>& argv, const fs::path& output_file,
                      const std::optional<fs::path>& stderr_file) {
  ChildProcess child(argv, output_file, stderr_file);
  return child.wait();
}

void run_program(const std::vector<std::string>& argv, const fs::path& output_file) {
  const int code = run_for_exit_code(argv, output_file);
  if (code != 0) {
    std::string cmd;
    for (const auto& a : argv) cmd += a + " ";
    throw std::runtime_error("command failed: " + cmd + "\n" + read_text_file(output_file));
  }
}

std::uint16_t free_loopback_port() {
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) throw std::system_error(errno, std::generic_category(), "socket");
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = 0;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    const int err = errno;
    ::close(fd);
    throw std::system_error(err, std::generic_category(), "bind 127.0.0.1:0");
  }
  socklen_t len = sizeof addr;
  ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len);
  ::close(fd);
  return ntohs(addr.sin_port);
}

std::string CapturedChild::err() const {
  return read_text_file(err_);
}

CapturedRun run_captured(const std::vector<std::string>& argv, const fs::path& dir,
                         std::chrono::milliseconds timeout) {
  // Numbered per process: several runs of one test keep their own output.
  static std::atomic<int> counter{0};
  const auto n = std::to_string(++counter);
  CapturedChild c(argv, dir / ("out." + n), dir / ("err." + n));
  const auto code = c.wait(timeout);
  return {code.value_or(-1), c.out(), c.err()};
}

}  // namespace fleetgw::testing
