#include "gateway/can/socketcan_transport.h"

#include <linux/can.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/uio.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <ctime>
#include <utility>

#include <spdlog/spdlog.h>
#include <asio/post.hpp>

#include "gateway/can/error_frame.h"

namespace fleetgw::can {
namespace {

std::string errno_text(int err) {
  const char* name = strerrorname_np(err);
  return std::string(name != nullptr ? name : "errno " + std::to_string(err)) + " (" +
         std::strerror(err) + ")";
}

// Owns a file descriptor until it is handed to the stream_descriptor.
class Fd {
 public:
  explicit Fd(int fd) : fd_(fd) {}
  ~Fd() {
    if (fd_ >= 0) ::close(fd_);
  }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  int get() const { return fd_; }
  int release() { return std::exchange(fd_, -1); }

 private:
  int fd_;
};

// Whether the kernel considers the interface administratively up. A raw socket bound to a down
// interface binds fine but only ever reports ENETDOWN, so "open" means bound *and* up.
bool interface_up(int fd, const std::string& ifname, int& err) {
  ifreq ifr{};
  std::strncpy(ifr.ifr_name, ifname.c_str(), IFNAMSIZ - 1);
  if (::ioctl(fd, SIOCGIFFLAGS, &ifr) < 0) {
    err = errno;
    return false;
  }
  err = 0;
  return (ifr.ifr_flags & IFF_UP) != 0;
}

bool is_link_error(int err) {
  return err == ENETDOWN || err == ENODEV || err == ENXIO || err == ENETUNREACH || err == EIO;
}

SocketCanOptions validated(SocketCanOptions options) {
  if (options.interface.empty() || options.interface.size() >= IFNAMSIZ) {
    throw SocketCanError("invalid CAN interface name '" + options.interface + "' (1-" +
                         std::to_string(IFNAMSIZ - 1) + " characters)");
  }
  if (options.tx_queue_limit == 0) throw SocketCanError("tx_queue_limit must be > 0");
  if (options.rx_batch == 0) throw SocketCanError("rx_batch must be > 0");
  return options;
}

}  // namespace

SocketCanTransport::SocketCanTransport(asio::io_context& io, SocketCanOptions options, Env& env)
    : io_(io),
      options_(validated(std::move(options))),
      env_(env),
      name_("socketcan:" + options_.interface),
      sock_(io),
      tx_(io, options_.tx_queue_limit, [this] { flush_tx(); }) {
  std::string why;
  if (!open(/*fatal_errors=*/true, why)) {
    health_.detail = why;
    spdlog::warn("SocketCAN {}: {}; re-opening until it is up", options_.interface, why);
  }
}

SocketCanTransport::~SocketCanTransport() {
  stop();
}

bool SocketCanTransport::open(bool fatal_errors, std::string& why) {
  const std::string& ifname = options_.interface;
  Fd fd(::socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW));
  if (fd.get() < 0) {
    const int err = errno;
    std::string msg;
    if (err == EAFNOSUPPORT) {
      msg = "this kernel has no SocketCAN support (socket(PF_CAN) failed with " + errno_text(err) +
            "); load the 'can' and 'can_raw' kernel modules, or use the replay or UDP transport";
    } else if (err == EPROTONOSUPPORT) {
      msg = "the kernel has SocketCAN but no CAN_RAW protocol (" + errno_text(err) +
            "); load the 'can_raw' kernel module";
    } else {
      msg = "socket(PF_CAN, SOCK_RAW, CAN_RAW) failed: " + errno_text(err);
    }
    if (fatal_errors) throw SocketCanError(msg);
    why = msg;
    return false;
  }

  const unsigned ifindex = ::if_nametoindex(ifname.c_str());
  if (ifindex == 0) {
    const std::string msg =
        "CAN interface '" + ifname + "' does not exist (" + errno_text(errno) + ")";
    if (fatal_errors) {
      throw SocketCanError(msg + "; check the interface name or create it (ip link add dev " +
                           ifname + " type vcan for a virtual bus)");
    }
    why = msg;
    return false;
  }

  // Only standard data frames of the MOTINOVA range: EFF and RTR are part of the mask and must
  // be 0, so extended and remote frames are dropped in the kernel.
  const can_filter filter{0x700, 0x700 | CAN_EFF_FLAG | CAN_RTR_FLAG};
  const can_err_mask_t err_mask = kSubscribedErrorClasses;
  const int on = 1;
  auto set = [&](int level, int opt, const void* val, socklen_t len, const char* what) {
    if (::setsockopt(fd.get(), level, opt, val, len) < 0) {
      throw SocketCanError("SocketCAN " + ifname + ": setsockopt(" + what +
                           ") failed: " + errno_text(errno));
    }
  };
  set(SOL_CAN_RAW, CAN_RAW_FILTER, &filter, sizeof filter, "CAN_RAW_FILTER");
  set(SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &err_mask, sizeof err_mask, "CAN_RAW_ERR_FILTER");
  set(SOL_SOCKET, SO_TIMESTAMPNS, &on, sizeof on, "SO_TIMESTAMPNS");

  sockaddr_can addr{};
  addr.can_family = AF_CAN;
  addr.can_ifindex = static_cast<int>(ifindex);
  if (::bind(fd.get(), reinterpret_cast<const sockaddr*>(&addr), sizeof addr) < 0) {
    const int err = errno;
    const std::string msg = "bind to CAN interface '" + ifname + "' failed: " + errno_text(err);
    // ENODEV here means "exists but is not a CAN device": a configuration error.
    if (fatal_errors && err == ENODEV) throw SocketCanError(msg + " (is it a CAN interface?)");
    why = msg;
    return false;
  }

  int err = 0;
  if (!interface_up(fd.get(), ifname, err)) {
    why = err != 0 ? "SIOCGIFFLAGS on " + ifname + " failed: " + errno_text(err)
                   : "CAN interface '" + ifname + "' is down";
    return false;
  }
  // Binding may have raced with a link change; drop any stale socket error so the first read
  // does not report an outage that is already over.
  int so_error = 0;
  socklen_t so_len = sizeof so_error;
  ::getsockopt(fd.get(), SOL_SOCKET, SO_ERROR, &so_error, &so_len);

  sock_.assign(fd.release());
  return true;
}

void SocketCanTransport::close_socket() {
  std::error_code ignored;
  sock_.close(ignored);  // cancels pending waits; their handlers see operation_aborted
  tx_retry_at_.reset();
  tx_.release();
}

void SocketCanTransport::start(FrameHandler on_frame, HealthHandler on_health) {
  if (started_) throw std::logic_error("SocketCanTransport::start called twice");
  started_ = true;
  on_frame_ = std::move(on_frame);
  on_health_ = std::move(on_health);
  tx_.start();
  if (sock_.is_open()) {
    set_state(ControllerState::kUp, "bound to " + options_.interface);
    wait_readable();
    if (!tx_.empty()) flush_tx();
  } else {
    set_state(ControllerState::kDown, health_.detail, /*force=*/true);
    loss_ = health_.detail;  // the first re-open waits the back-off, as after a loss
    wake();
  }
}

bool SocketCanTransport::send(const motinova::CanFrame& frame) {
  if (!is_sendable(frame)) {
    spdlog::error("SocketCAN {}: refusing to send invalid frame id=0x{:X} len={}",
                  options_.interface, frame.id, frame.len);
    ++health_.tx_failures;
    return false;
  }
  if (stopped_ || !sock_.is_open() || !tx_.push(frame)) {
    ++health_.tx_failures;
    return false;
  }
  return true;
}

void SocketCanTransport::stop() {
  stopped_ = true;
  alive_.reset();
  tx_.stop();
  close_socket();
  loss_.reset();
}

void SocketCanTransport::wait_readable() {
  sock_.async_wait(asio::posix::stream_descriptor::wait_read,
                   [this, token = std::weak_ptr<int>(alive_)](const std::error_code& ec) {
                     if (token.expired() || ec == asio::error::operation_aborted) return;
                     if (ec) {
                       link_lost(ec.value(), "wait for data");
                       return;
                     }
                     on_readable();
                   });
}

void SocketCanTransport::on_readable() {
  const std::weak_ptr<int> token = alive_;
  for (std::size_t n = 0; n < options_.rx_batch; ++n) {
    can_frame cf{};
    iovec iov{&cf, sizeof cf};
    alignas(cmsghdr) char control[CMSG_SPACE(sizeof(timespec)) + 64];
    msghdr msg{};
    msg.msg_iov = &iov;
    msg.msg_iovlen = 1;
    msg.msg_control = control;
    msg.msg_controllen = sizeof control;
    const ssize_t got = ::recvmsg(sock_.native_handle(), &msg, MSG_DONTWAIT);
    if (got < 0) {
      const int err = errno;
      if (err == EAGAIN || err == EWOULDBLOCK) {
        wait_readable();
        return;
      }
      if (err == EINTR) continue;
      link_lost(err, "read");
      return;
    }
    if (static_cast<std::size_t>(got) != sizeof cf) {
      ++stats_.rx_unexpected;
      continue;
    }

    motinova::Micros ts{-1};
    for (cmsghdr* c = CMSG_FIRSTHDR(&msg); c != nullptr; c = CMSG_NXTHDR(&msg, c)) {
      if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SCM_TIMESTAMPNS) {
        timespec t{};
        std::memcpy(&t, CMSG_DATA(c), sizeof t);
        ts = motinova::Micros{static_cast<int64_t>(t.tv_sec) * 1'000'000 + t.tv_nsec / 1000};
      }
    }
    if (ts.count() < 0) {
      // Should not happen with SO_TIMESTAMPNS set; the wall clock is the best remaining guess.
      ++stats_.rx_no_timestamp;
      ts = env_.wall_now();
    }

    ts = ts_guard_.apply(ts);
    stats_.rx_timestamps_clamped = ts_guard_.clamped();
    stats_.rx_clock_steps = ts_guard_.clock_steps();

    if (cf.can_id & CAN_ERR_FLAG) {
      handle_error_frame(cf.can_id & CAN_ERR_MASK, cf.data, cf.can_dlc);
    } else if ((cf.can_id & (CAN_EFF_FLAG | CAN_RTR_FLAG)) != 0 || cf.can_dlc > CAN_MAX_DLEN ||
               !motinova::is_motinova_id(cf.can_id & CAN_SFF_MASK)) {
      ++stats_.rx_unexpected;  // the kernel filter should have stopped it
    } else {
      motinova::CanFrame f;
      f.id = cf.can_id & CAN_SFF_MASK;
      f.len = cf.can_dlc;
      std::memcpy(f.data.data(), cf.data, f.len);
      ++health_.rx_frames;
      if (on_frame_) on_frame_(f, ts);
    }
    // The handler may have stopped or destroyed us.
    if (token.expired() || !sock_.is_open()) return;
  }
  // Batch used up with data still pending: let other work run, then continue.
  asio::post(io_, [this, token] {
    if (token.expired() || !sock_.is_open()) return;
    on_readable();
  });
}

void SocketCanTransport::handle_error_frame(uint32_t error_class, const uint8_t* data,
                                            uint8_t len) {
  ++health_.error_frames;
  const ErrorFrameInfo info =
      interpret_error_frame(error_class, std::span<const uint8_t>(data, std::min<uint8_t>(len, 8)));
  spdlog::warn("SocketCAN {}: CAN error frame: {}", options_.interface, info.description);
  set_state(info.state.value_or(health_.state), info.description, /*force=*/true);
}

void SocketCanTransport::flush_tx() {
  while (!tx_.empty() && sock_.is_open()) {
    const motinova::CanFrame& f = tx_.front();
    can_frame cf{};
    cf.can_id = f.id;
    cf.can_dlc = f.len;
    std::memcpy(cf.data, f.data.data(), f.len);
    const ssize_t put = ::write(sock_.native_handle(), &cf, sizeof cf);
    if (put == static_cast<ssize_t>(sizeof cf)) {
      ++health_.tx_frames;
      tx_.pop();
      continue;
    }
    const int err = put < 0 ? errno : EIO;
    if (err == EINTR) continue;
    if (err == EAGAIN || err == EWOULDBLOCK) {
      wait_writable();
      return;
    }
    if (err == ENOBUFS) {
      // The driver's TX queue is full; poll() does not signal when it drains, so retry later.
      ++stats_.tx_enobufs_retries;
      tx_.hold();
      tx_retry_at_ = env_.steady_now() + options_.tx_retry_interval;
      wake();  // the owner polls at tx_retry_at_
      return;
    }
    if (is_link_error(err)) {
      link_lost(err, "write");
      return;
    }
    // Anything else concerns this frame only (e.g. EINVAL): drop it, keep the rest.
    spdlog::error("SocketCAN {}: dropping frame id=0x{:03X}: write failed: {}", options_.interface,
                  f.id, errno_text(err));
    ++health_.tx_failures;
    tx_.pop();
  }
}

void SocketCanTransport::wait_writable() {
  tx_.hold();
  sock_.async_wait(asio::posix::stream_descriptor::wait_write,
                   [this, token = std::weak_ptr<int>(alive_)](const std::error_code& ec) {
                     if (token.expired() || ec == asio::error::operation_aborted) return;
                     tx_.release();
                     if (ec) {
                       link_lost(ec.value(), "wait for write");
                       return;
                     }
                     flush_tx();
                   });
}

void SocketCanTransport::link_lost(int err, std::string_view during) {
  if (!sock_.is_open()) return;
  const char* err_name = strerrorname_np(err);
  spdlog::warn("SocketCAN {}: {} during {}; closing, re-opening until it is back",
               options_.interface, errno_text(err), during);
  close_socket();
  health_.tx_failures += tx_.drop_all();
  set_state(ControllerState::kDown,
            std::string(err_name != nullptr ? err_name : "error") + " on " + options_.interface,
            /*force=*/true);
  if (stopped_) return;
  loss_ = errno_text(err) + " during " + std::string(during) + " on " + options_.interface;
  wake();
}

std::optional<TimedWork::Time> SocketCanTransport::next_deadline() const {
  if (stopped_ || !started_) return std::nullopt;
  // Closed: a re-open is due now (the owner's back-off holds it back after a failure).
  if (!sock_.is_open() || loss_) return env_.steady_now();
  return tx_retry_at_;
}

std::optional<std::string> SocketCanTransport::poll(TimedWork::Time now) {
  if (stopped_ || !started_) return std::nullopt;
  if (tx_retry_at_ && now >= *tx_retry_at_) {
    tx_retry_at_.reset();
    tx_.release();
    flush_tx();  // may lose the link: reported below
  }
  if (auto loss = std::exchange(loss_, std::nullopt)) return loss;
  if (!sock_.is_open()) return reopen();
  return std::nullopt;
}

std::optional<std::string> SocketCanTransport::reopen() {
  ++stats_.reopen_attempts;
  std::string why;
  bool ok = false;
  try {
    ok = open(/*fatal_errors=*/false, why);
  } catch (const SocketCanError& e) {  // setsockopt failures: keep trying, they may pass
    why = e.what();
  }
  if (!ok) {
    spdlog::debug("SocketCAN {}: re-open failed: {}", options_.interface, why);
    return "re-open failed: " + why;
  }
  ++health_.reopens;
  spdlog::info("SocketCAN {}: interface back, socket re-opened (re-open #{})", options_.interface,
               health_.reopens);
  const std::weak_ptr<int> token = alive_;
  set_state(ControllerState::kUp, "re-opened " + options_.interface, /*force=*/true);
  if (token.expired() || !sock_.is_open()) return std::nullopt;  // the handler stopped us
  wait_readable();
  return std::nullopt;
}

void SocketCanTransport::set_state(ControllerState s, std::string detail, bool force) {
  const bool changed = force || s != health_.state || detail != health_.detail;
  health_.state = s;
  health_.detail = std::move(detail);
  if (changed && on_health_) on_health_(health_);
}

}  // namespace fleetgw::can
