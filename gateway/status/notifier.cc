#include "gateway/status/notifier.h"

#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <charconv>
#include <cstdlib>
#include <cstring>

namespace fleetgw::status {
namespace {

// Owns one file descriptor.
class Fd {
 public:
  explicit Fd(int fd) : fd_(fd) {}
  ~Fd() {
    if (fd_ >= 0) ::close(fd_);
  }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  int get() const { return fd_; }

 private:
  int fd_;
};

// NOTIFY_SOCKET is either an absolute path or "@name" (abstract namespace). Anything else
// (systemd >= 254 also knows "vsock:...", which a node's own init never hands out) is refused.
bool usable_socket(std::string_view s) {
  return s.size() > 1 && (s.front() == '/' || s.front() == '@') &&
         s.size() < sizeof(sockaddr_un::sun_path);
}

}  // namespace

Notifier Notifier::from_environment() {
  const char* s = std::getenv("NOTIFY_SOCKET");
  return Notifier(s && usable_socket(s) ? std::string(s) : std::string());
}

Notifier::Notifier(std::string socket) : socket_(usable_socket(socket) ? std::move(socket) : "") {}

bool Notifier::notify(std::string_view state) {
  if (!enabled()) return false;
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::memcpy(addr.sun_path, socket_.data(), socket_.size());
  if (addr.sun_path[0] == '@') addr.sun_path[0] = '\0';
  const auto len = static_cast<socklen_t>(offsetof(sockaddr_un, sun_path) + socket_.size());
  // A fresh socket per message, as sd_notify() does: messages are rare (a ping every few
  // seconds) and nothing stays open across a service-manager restart.
  Fd fd(::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0));
  if (fd.get() < 0) return false;
  const ssize_t n = ::sendto(fd.get(), state.data(), state.size(), MSG_NOSIGNAL,
                             reinterpret_cast<const sockaddr*>(&addr), len);
  return n == static_cast<ssize_t>(state.size());
}

bool Notifier::ready(std::string_view status_text) {
  if (status_text.empty()) return notify("READY=1");
  std::string msg = "READY=1\nSTATUS=";
  msg += status_text;
  return notify(msg);
}

bool Notifier::watchdog() {
  return notify("WATCHDOG=1");
}

bool Notifier::status(std::string_view text) {
  std::string msg = "STATUS=";
  msg += text;
  return notify(msg);
}

bool Notifier::stopping() {
  return notify("STOPPING=1");
}

std::optional<std::chrono::microseconds> parse_watchdog_env(const char* usec, const char* pid,
                                                            long self_pid) {
  if (!usec) return std::nullopt;
  const std::string_view u(usec);
  uint64_t value = 0;
  const auto [end, ec] = std::from_chars(u.data(), u.data() + u.size(), value);
  if (ec != std::errc() || end != u.data() + u.size() || value == 0) return std::nullopt;
  // WATCHDOG_PID guards against a child inheriting the variables and pinging for us.
  if (pid) {
    const std::string_view p(pid);
    long owner = 0;
    const auto [pend, pec] = std::from_chars(p.data(), p.data() + p.size(), owner);
    if (pec != std::errc() || pend != p.data() + p.size() || owner != self_pid) {
      return std::nullopt;
    }
  }
  return std::chrono::microseconds(static_cast<int64_t>(value));
}

std::optional<std::chrono::microseconds> watchdog_timeout_from_environment() {
  return parse_watchdog_env(std::getenv("WATCHDOG_USEC"), std::getenv("WATCHDOG_PID"),
                            static_cast<long>(::getpid()));
}

Watchdog::Watchdog(Notifier& notifier, std::chrono::microseconds timeout)
    : notifier_(notifier),
      ping_period_(std::max<Clock::duration>(timeout / 2, std::chrono::milliseconds(1))) {}

bool Watchdog::loop_alive(Clock::time_point now) {
  if (last_ping_ && now - *last_ping_ < ping_period_) return false;
  last_ping_ = now;
  notifier_.watchdog();
  ++pings_;
  return true;
}

LoopWatchdog::LoopWatchdog(asio::io_context& io, Notifier& notifier,
                           std::chrono::microseconds timeout, Env& env)
    : watchdog_(notifier, timeout), timer_(io), env_(env) {}

LoopWatchdog::~LoopWatchdog() {
  stop();
}

void LoopWatchdog::start() {
  if (running_) return;
  running_ = true;
  timer_.expires_after(std::chrono::seconds(0));
  arm();
}

void LoopWatchdog::stop() {
  running_ = false;
  timer_.cancel();
}

void LoopWatchdog::arm() {
  timer_.async_wait([this](const std::error_code& ec) {
    // Cancelled (stop() or destruction): `this` may be gone, touch nothing.
    if (ec || !running_) return;
    watchdog_.loop_alive(env_.steady_now());
    timer_.expires_after(watchdog_.check_period());
    arm();
  });
}

}  // namespace fleetgw::status
