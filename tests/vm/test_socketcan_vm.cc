// The real SocketCAN code path, against a real Linux kernel's vcan0. Run by run-vm-tests.sh inside
// a QEMU guest (the build hosts' kernel has no CAN); on any machine without PF_CAN or without
// vcan0 every test skips with a message saying so.
//
// Needs: vcan0 up, `ip` (busybox is enough), and for the last test cansend/candump on PATH.
#include <linux/can.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <asio/io_context.hpp>

#include "env/env.h"
#include "gateway/can/candump.h"
#include "gateway/can/socketcan_transport.h"
#include "gateway/can/timed_work_timer.h"
#include "tests/support/wait.h"

namespace fleetgw::can {
namespace {

using motinova::CanFrame;
using motinova::Micros;
using namespace std::chrono_literals;

constexpr const char* kIf = "vcan0";

std::optional<std::string> why_no_vcan() {
  const int fd = ::socket(PF_CAN, SOCK_RAW, CAN_RAW);
  if (fd < 0) {
    return std::string("no SocketCAN in this kernel (socket(PF_CAN): ") + std::strerror(errno) +
           "); run tests/vm/run-vm-tests.sh to test in a VM";
  }
  ::close(fd);
  if (::if_nametoindex(kIf) == 0) {
    return std::string(
        "no vcan0 interface (ip link add dev vcan0 type vcan; ip link set up "
        "vcan0)");
  }
  return std::nullopt;
}

// CAN_RAW receivers the kernel lists on vcan0 (one per bound socket and filter): a new one
// means a program such as candump has bound and will see the next frame.
std::size_t raw_receivers() {
  std::ifstream in("/proc/net/can/rcvlist_all");
  std::size_t n = 0;
  for (std::string line; std::getline(in, line);) {
    std::istringstream words(line);
    std::string first;
    words >> first;
    if (first == kIf && line.find("raw") != std::string::npos) ++n;
  }
  return n;
}

void sh(const std::string& cmd) {
  const int rc = std::system(cmd.c_str());
  ASSERT_EQ(rc, 0) << "command failed: " << cmd;
}

// A plain raw socket on vcan0 with no filter: the other node on the bus.
class Peer {
 public:
  Peer() {
    fd_ = ::socket(PF_CAN, SOCK_RAW, CAN_RAW);
    if (fd_ < 0) throw std::runtime_error("peer socket");
    const can_err_mask_t all = CAN_ERR_MASK;
    ::setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &all, sizeof all);
    timeval tv{0, 200'000};
    ::setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    sockaddr_can addr{};
    addr.can_family = AF_CAN;
    addr.can_ifindex = static_cast<int>(::if_nametoindex(kIf));
    if (::bind(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) < 0) {
      throw std::runtime_error(std::string("peer bind: ") + std::strerror(errno));
    }
  }
  ~Peer() { ::close(fd_); }
  Peer(const Peer&) = delete;
  Peer& operator=(const Peer&) = delete;

  void send(canid_t id, std::vector<uint8_t> data) {
    can_frame f{};
    f.can_id = id;
    f.can_dlc = static_cast<uint8_t>(data.size());
    if (!data.empty()) std::memcpy(f.data, data.data(), data.size());
    ASSERT_EQ(::write(fd_, &f, sizeof f), static_cast<ssize_t>(sizeof f))
        << "peer write: " << std::strerror(errno);
  }
  std::optional<can_frame> receive() {
    can_frame f{};
    if (::read(fd_, &f, sizeof f) != static_cast<ssize_t>(sizeof f)) return std::nullopt;
    return f;
  }

 private:
  int fd_ = -1;
};

template <typename Pred>
bool run_until(asio::io_context& io, Pred done, std::chrono::milliseconds limit = 3000ms) {
  const auto deadline = std::chrono::steady_clock::now() + limit;
  while (!done() && std::chrono::steady_clock::now() < deadline) {
    io.run_for(5ms);
    if (io.stopped()) io.restart();
  }
  return done();
}

CanFrame frame(uint32_t id, std::vector<uint8_t> bytes) {
  CanFrame f;
  f.id = id;
  f.len = static_cast<uint8_t>(bytes.size());
  for (std::size_t i = 0; i < bytes.size(); ++i) f.data[i] = bytes[i];
  return f;
}

class SocketCanVm : public ::testing::Test {
 protected:
  void SetUp() override {
    if (auto why = why_no_vcan()) {
      // Inside the VM a missing vcan0 is a broken set-up, not a reason to skip.
      if (std::getenv("FLEETGW_REQUIRE_VCAN") != nullptr) FAIL() << *why;
      GTEST_SKIP() << *why;
    }
    sh(std::string("ip link set ") + kIf + " up");
  }

  SocketCanOptions options() const {
    SocketCanOptions o;
    o.interface = kIf;
    o.reopen_interval = 50ms;
    o.reopen_max = 50ms;  // a fixed spacing: the tests count attempts in real time
    return o;
  }

  struct Rx {
    CanFrame frame;
    Micros ts;
  };
  asio::io_context io;
  std::vector<Rx> rx;
  std::vector<BusHealth> health;
  auto on_frame() {
    return [this](const CanFrame& f, Micros ts) { rx.push_back({f, ts}); };
  }
  auto on_health() {
    return [this](const BusHealth& h) { health.push_back(h); };
  }
};

TEST_F(SocketCanVm, KernelFilterPassesOnlyStandardDataFramesInMotinovaRange) {
  SocketCanTransport t(io, options());
  t.start(on_frame(), on_health());
  EXPECT_EQ(t.health().state, ControllerState::kUp);
  Peer peer;
  peer.send(0x123, {1});                           // outside the range
  peer.send(0x6FF, {2});                           // just below
  peer.send(0x710 | CAN_EFF_FLAG, {3});            // extended with a MOTINOVA-looking ID
  peer.send(0x18FF0710 | CAN_EFF_FLAG, {4});       // extended
  peer.send(0x710 | CAN_RTR_FLAG, {});             // remote
  peer.send(0x700, {5});                           // first of the range
  peer.send(0x7FF, {6, 7, 8, 9, 10, 11, 12, 13});  // last of the range
  ASSERT_TRUE(run_until(io, [&] { return rx.size() >= 2; }));
  run_until(
      io, [] { return false; }, 100ms);
  ASSERT_EQ(rx.size(), 2U);
  EXPECT_EQ(rx[0].frame, frame(0x700, {5}));
  EXPECT_EQ(rx[1].frame, frame(0x7FF, {6, 7, 8, 9, 10, 11, 12, 13}));
  EXPECT_EQ(t.stats().rx_unexpected, 0U) << "the kernel filter let something through";
  EXPECT_EQ(t.health().rx_frames, 2U);
}

TEST_F(SocketCanVm, SendsAndReceivesInOrder) {
  SocketCanTransport t(io, options());
  t.start(on_frame(), on_health());
  Peer peer;
  for (uint8_t i = 0; i < 40; ++i) ASSERT_TRUE(t.send(frame(0x760, {i, 0xA5})));
  run_until(io, [&] { return t.health().tx_frames == 40; });
  EXPECT_EQ(t.health().tx_frames, 40U);
  for (uint8_t i = 0; i < 40; ++i) {
    const auto f = peer.receive();
    ASSERT_TRUE(f) << "peer missed frame " << int{i};
    EXPECT_EQ(f->can_id, 0x760U);
    ASSERT_EQ(f->can_dlc, 2);
    EXPECT_EQ(f->data[0], i);
  }
  for (uint8_t i = 0; i < 40; ++i) peer.send(0x716, {i});
  ASSERT_TRUE(run_until(io, [&] { return rx.size() == 40; })) << rx.size();
  for (uint8_t i = 0; i < 40; ++i) EXPECT_EQ(rx[i].frame, frame(0x716, {i}));
  EXPECT_TRUE(rx.size() == 40 && t.tx_queue_size() == 0);
}

TEST_F(SocketCanVm, BoundedTxQueueRefusesWhenFull) {
  SocketCanOptions o = options();
  o.tx_queue_limit = 8;
  SocketCanTransport t(io, o);
  t.start(on_frame(), on_health());
  Peer peer;
  int accepted = 0;
  for (uint8_t i = 0; i < 12; ++i) accepted += t.send(frame(0x761, {i})) ? 1 : 0;
  EXPECT_EQ(accepted, 8);
  EXPECT_EQ(t.health().tx_failures, 4U);
  ASSERT_TRUE(run_until(io, [&] { return t.health().tx_frames == 8; }));
  for (uint8_t i = 0; i < 8; ++i) {
    const auto f = peer.receive();
    ASSERT_TRUE(f);
    EXPECT_EQ(f->data[0], i);
  }
  EXPECT_TRUE(t.send(frame(0x761, {99})));
}

TEST_F(SocketCanVm, KernelTimestampsArePresentAndMonotonic) {
  SocketCanTransport t(io, options());
  t.start(on_frame(), on_health());
  Peer peer;
  // Warm-up: the kernel switches receive stamping on asynchronously when the first socket asks
  // for it, so a frame right after that may be stamped at read time instead (TimestampGuard
  // covers that in production). Measure only once stamping is on: a probe left unread for
  // 20 ms (the stimulus, not a wait) carries a stamp from its arrival, not from its reading.
  const auto stamped_on_arrival = [&] {
    rx.clear();
    const auto sent =
        std::chrono::duration_cast<Micros>(std::chrono::system_clock::now().time_since_epoch());
    peer.send(0x712, {0xFF});
    std::this_thread::sleep_for(20ms);
    return run_until(io, [&] { return rx.size() == 1; }) && rx[0].ts - sent < Micros{10'000};
  };
  ASSERT_TRUE(fleetgw::testing::wait_until(stamped_on_arrival, 5s, 1ms))
      << "receive timestamps still taken at read time after 5 s";
  rx.clear();
  const auto before =
      std::chrono::duration_cast<Micros>(std::chrono::system_clock::now().time_since_epoch());
  for (uint8_t i = 0; i < 5; ++i) {
    peer.send(0x712, {i});
    std::this_thread::sleep_for(20ms);
  }
  // Read only after all were sent: kernel timestamps still show the 20 ms gaps, which a
  // read-time timestamp would not.
  ASSERT_TRUE(run_until(io, [&] { return rx.size() == 5; }));
  const auto after =
      std::chrono::duration_cast<Micros>(std::chrono::system_clock::now().time_since_epoch());
  EXPECT_EQ(t.stats().rx_no_timestamp, 0U);
  EXPECT_EQ(t.stats().rx_clock_steps, 0U);
  EXPECT_EQ(t.stats().rx_timestamps_clamped, 0U);
  for (std::size_t i = 0; i < rx.size(); ++i) {
    EXPECT_GE(rx[i].ts, before) << i;
    EXPECT_LE(rx[i].ts, after) << i;
    if (i > 0) {
      EXPECT_GT(rx[i].ts, rx[i - 1].ts) << i;
      EXPECT_GE(rx[i].ts - rx[i - 1].ts, Micros{15'000}) << "gap " << i;
    }
  }
}

TEST_F(SocketCanVm, ErrorFramesDriveHealth) {
  SocketCanTransport t(io, options());
  t.start(on_frame(), on_health());
  Peer peer;
  // vcan delivers whatever is written, so a peer can play the controller reporting errors.
  peer.send(CAN_ERR_FLAG | CAN_ERR_CRTL, {0, CAN_ERR_CRTL_TX_PASSIVE, 0, 0, 0, 0, 0, 0});
  ASSERT_TRUE(run_until(io, [&] { return t.health().state == ControllerState::kErrorPassive; }));
  peer.send(CAN_ERR_FLAG | CAN_ERR_BUSOFF, {0, 0, 0, 0, 0, 0, 0, 0});
  ASSERT_TRUE(run_until(io, [&] { return t.health().state == ControllerState::kBusOff; }));
  EXPECT_EQ(t.health().detail, "bus-off");
  peer.send(CAN_ERR_FLAG | CAN_ERR_RESTARTED, {0, 0, 0, 0, 0, 0, 0, 0});
  ASSERT_TRUE(run_until(io, [&] { return t.health().state == ControllerState::kUp; }));
  // Lost arbitration is not subscribed: it must not even arrive.
  peer.send(CAN_ERR_FLAG | CAN_ERR_LOSTARB, {0, 0, 0, 0, 0, 0, 0, 0});
  peer.send(0x710, {1});
  ASSERT_TRUE(run_until(io, [&] { return rx.size() == 1; }));
  EXPECT_EQ(t.health().error_frames, 3U);
  EXPECT_EQ(rx[0].frame, frame(0x710, {1}));
}

TEST_F(SocketCanVm, RecoversWhenTheInterfaceGoesDownAndUp) {
  SocketCanTransport t(io, options());
  TimedWorkTimer timed(io, *t.timed_work());  // the engine's part, without the engine
  timed.start();
  t.start(on_frame(), on_health());
  Peer peer;
  peer.send(0x711, {1});
  ASSERT_TRUE(run_until(io, [&] { return rx.size() == 1; }));

  sh(std::string("ip link set ") + kIf + " down");
  ASSERT_TRUE(run_until(io, [&] { return t.health().state == ControllerState::kDown; }))
      << "transport did not notice the interface going down";
  EXPECT_NE(t.health().detail.find("ENETDOWN"), std::string::npos) << t.health().detail;
  EXPECT_FALSE(t.send(frame(0x760, {}))) << "send() must fail while the link is down";
  run_until(
      io, [] { return false; }, 200ms);  // several failed re-open attempts
  EXPECT_EQ(t.health().state, ControllerState::kDown);
  EXPECT_EQ(t.health().reopens, 0U);
  EXPECT_GE(t.stats().reopen_attempts, 2U);

  sh(std::string("ip link set ") + kIf + " up");
  ASSERT_TRUE(run_until(io, [&] { return t.health().state == ControllerState::kUp; }))
      << "transport did not come back";
  EXPECT_EQ(t.health().reopens, 1U);
  Peer peer2;  // the old peer socket saw ENETDOWN too; a fresh one avoids that noise
  peer2.send(0x711, {2});
  ASSERT_TRUE(run_until(io, [&] { return rx.size() == 2; }));
  EXPECT_EQ(rx[1].frame, frame(0x711, {2}));
  EXPECT_TRUE(t.send(frame(0x760, {3})));
  ASSERT_TRUE(run_until(io, [&] { return t.health().tx_frames == 1; }));

  // The health handler saw up → down → up.
  ASSERT_GE(health.size(), 3U);
  EXPECT_EQ(health.front().state, ControllerState::kUp);
  bool saw_down = false;
  for (const auto& h : health) saw_down = saw_down || h.state == ControllerState::kDown;
  EXPECT_TRUE(saw_down);
  EXPECT_EQ(health.back().state, ControllerState::kUp);
}

TEST_F(SocketCanVm, StartsDownWhenTheInterfaceIsDownAndComesUpLater) {
  sh(std::string("ip link set ") + kIf + " down");
  SocketCanTransport t(io, options());
  TimedWorkTimer timed(io, *t.timed_work());
  timed.start();
  t.start(on_frame(), on_health());
  EXPECT_EQ(t.health().state, ControllerState::kDown);
  EXPECT_NE(t.health().detail.find("is down"), std::string::npos) << t.health().detail;
  run_until(
      io, [] { return false; }, 100ms);
  sh(std::string("ip link set ") + kIf + " up");
  ASSERT_TRUE(run_until(io, [&] { return t.health().state == ControllerState::kUp; }));
  Peer peer;
  peer.send(0x713, {9});
  ASSERT_TRUE(run_until(io, [&] { return rx.size() == 1; }));
}

// The transport keeps no timer: a lost link is reported by the next poll(), and re-opened only
// when its owner polls again (the gateway's engine, whose back-off spaces the attempts).
TEST_F(SocketCanVm, ReopensOnlyWhenPolledAndReportsTheLossFirst) {
  sh(std::string("ip link set ") + kIf + " down");
  ManualEnv env;
  SocketCanTransport t(io, options(), env);
  TimedWork& work = *t.timed_work();
  int wakes = 0;
  work.set_wake([&] { ++wakes; });
  t.start(on_frame(), on_health());
  EXPECT_EQ(wakes, 1) << "the owner is told a re-open is due";
  EXPECT_EQ(work.next_deadline(), env.steady_now());
  const auto loss = work.poll(env.steady_now());
  ASSERT_TRUE(loss.has_value()) << "the loss is the first poll's failure (the back-off waits)";
  EXPECT_NE(loss->find("is down"), std::string::npos) << *loss;
  EXPECT_EQ(t.stats().reopen_attempts, 0U);
  run_until(
      io, [] { return false; }, 200ms);
  EXPECT_EQ(t.stats().reopen_attempts, 0U) << "no timer of its own";
  const auto failed = work.poll(env.steady_now());
  ASSERT_TRUE(failed.has_value());
  EXPECT_EQ(t.stats().reopen_attempts, 1U);
  sh(std::string("ip link set ") + kIf + " up");
  EXPECT_EQ(work.poll(env.steady_now()), std::nullopt);
  EXPECT_EQ(t.health().state, ControllerState::kUp);
  EXPECT_EQ(t.health().reopens, 1U);
  EXPECT_EQ(work.next_deadline(), std::nullopt) << "nothing due while the link is up";
}

TEST_F(SocketCanVm, MissingInterfaceIsAClearConfigurationError) {
  SocketCanOptions o = options();
  o.interface = "vcan9";
  try {
    SocketCanTransport t(io, o);
    FAIL() << "constructed on a missing interface";
  } catch (const SocketCanError& e) {
    EXPECT_NE(std::string(e.what()).find("CAN interface 'vcan9' does not exist"), std::string::npos)
        << e.what();
  }
}

TEST_F(SocketCanVm, InteroperatesWithCanUtils) {
  if (std::system("command -v cansend >/dev/null && command -v candump >/dev/null") != 0) {
    GTEST_SKIP() << "cansend/candump not on PATH";
  }
  SocketCanTransport t(io, options());
  t.start(on_frame(), on_health());

  // cansend → our transport.
  sh(std::string("cansend ") + kIf + " 715#DEADBEEF");
  sh(std::string("cansend ") + kIf + " 123#01");  // filtered
  sh(std::string("cansend ") + kIf + " 7FE#");
  ASSERT_TRUE(run_until(io, [&] { return rx.size() == 2; }));
  EXPECT_EQ(rx[0].frame, frame(0x715, {0xDE, 0xAD, 0xBE, 0xEF}));
  EXPECT_EQ(rx[1].frame, frame(0x7FE, {}));

  // Our transport → candump -L, parsed back with our own candump reader.
  const std::string log = "/tmp/fleetgw_candump.log";
  std::remove(log.c_str());
  const std::size_t receivers = raw_receivers();
  sh(std::string("candump -L -n 3 ") + kIf + " > " + log + " 2>&1 &");
  ASSERT_TRUE(fleetgw::testing::wait_until([&] { return raw_receivers() > receivers; }, 5s))
      << "candump did not bind (no new receiver in /proc/net/can/rcvlist_all)";
  const std::vector<CanFrame> sent = {frame(0x716, {1, 2, 3}), frame(0x700, {}),
                                      frame(0x7FF, {0, 1, 2, 3, 4, 5, 6, 7})};
  for (const auto& f : sent) ASSERT_TRUE(t.send(f));
  run_until(io, [&] { return t.health().tx_frames == 3; });

  std::vector<candump::LogRecord> records;
  std::vector<std::string> errors;
  fleetgw::testing::wait_until(
      [&] {
        std::ifstream in(log);
        candump::LineReader reader(in);
        records.clear();
        while (auto r = reader.next()) records.push_back(*r);
        errors.clear();
        for (const auto& e : reader.errors()) errors.push_back(e.message);
        return records.size() == 3;
      },
      5s, 50ms);
  ASSERT_EQ(records.size(), 3U) << "candump output incomplete";
  EXPECT_TRUE(errors.empty()) << errors.front();
  const auto now =
      std::chrono::duration_cast<Micros>(std::chrono::system_clock::now().time_since_epoch());
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(records[i].interface, kIf);
    EXPECT_EQ(records[i].frame, sent[i]) << i;
    EXPECT_LE(records[i].timestamp, now);
    EXPECT_GT(records[i].timestamp, now - Micros{60'000'000});
    // What candump wrote, our writer writes identically.
    std::ifstream in(log);
    std::string line;
    for (std::size_t k = 0; k <= i; ++k) std::getline(in, line);
    EXPECT_EQ(candump::format_record(records[i]), line);
  }
}

}  // namespace
}  // namespace fleetgw::can
