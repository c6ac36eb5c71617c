// UDP tunnel: cannelloni wire format, two transports on loopback, two processes, and malformed
// datagrams rejected.
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <asio/io_context.hpp>
#include <asio/ip/udp.hpp>
#include <asio/steady_timer.hpp>

#include "gateway/can/candump.h"
#include "gateway/can/udp_transport.h"

namespace fleetgw::can {
namespace {

using motinova::CanFrame;
using motinova::Micros;

CanFrame frame(uint32_t id, std::vector<uint8_t> bytes) {
  CanFrame f;
  f.id = id;
  f.len = static_cast<uint8_t>(bytes.size());
  for (std::size_t i = 0; i < bytes.size(); ++i) f.data[i] = bytes[i];
  return f;
}

// Runs the loop until `done` or the deadline; returns done().
template <typename Pred>
bool run_until(asio::io_context& io, Pred done,
               std::chrono::milliseconds limit = std::chrono::milliseconds(3000)) {
  const auto deadline = std::chrono::steady_clock::now() + limit;
  while (!done() && std::chrono::steady_clock::now() < deadline) {
    io.run_for(std::chrono::milliseconds(5));
    if (io.stopped()) io.restart();
  }
  return done();
}

TEST(Cannelloni, EncodesTheDocumentedLayout) {
  cannelloni::WireFrame a;
  a.can_id = 0x716;
  a.len = 3;
  a.data[0] = 0x01;
  a.data[1] = 0x02;
  a.data[2] = 0x03;
  cannelloni::WireFrame rtr;
  rtr.can_id = 0x123 | candump::kRtrFlag;
  rtr.len = 4;  // remote frames carry a DLC but no data bytes on the wire
  const std::vector<cannelloni::WireFrame> frames = {a, rtr};
  const auto bytes = cannelloni::encode(0x2A, frames);
  const std::vector<uint8_t> want = {
      0x02, 0x00, 0x2A, 0x00, 0x02,                    // version 2, DATA, seq, count=2 (BE)
      0x00, 0x00, 0x07, 0x16, 0x03, 0x01, 0x02, 0x03,  // can_id BE, len, data
      0x40, 0x00, 0x01, 0x23, 0x04};                   // RTR flag in can_id, len, no data
  EXPECT_EQ(bytes, want);

  std::string error;
  const auto d = cannelloni::decode(bytes, error);
  ASSERT_TRUE(d) << error;
  EXPECT_EQ(d->sequence, 0x2A);
  ASSERT_EQ(d->frames.size(), 2U);
  EXPECT_EQ(d->frames[0], a);
  EXPECT_EQ(d->frames[1].can_id, rtr.can_id);
  EXPECT_EQ(d->frames[1].len, 4);
}

TEST(Cannelloni, DecodesCanFdFramesWithFlagsByte) {
  const std::vector<uint8_t> bytes = {0x02, 0x00, 0x07, 0x00, 0x01, 0x00, 0x00,
                                      0x07, 0x10, 0x82, 0x01, 0xAA, 0xBB};
  std::string error;
  const auto d = cannelloni::decode(bytes, error);
  ASSERT_TRUE(d) << error;
  ASSERT_EQ(d->frames.size(), 1U);
  EXPECT_TRUE(d->frames[0].fd);
  EXPECT_EQ(d->frames[0].len, 2);
}

struct BadDatagram {
  std::vector<uint8_t> bytes;
  const char* what;
};

class CannelloniErrors : public ::testing::TestWithParam<BadDatagram> {};

TEST_P(CannelloniErrors, RejectedWithOffsetAndReason) {
  std::string error;
  EXPECT_FALSE(cannelloni::decode(GetParam().bytes, error));
  EXPECT_NE(error.find(GetParam().what), std::string::npos) << error;
  EXPECT_EQ(error.rfind("byte ", 0), 0U) << error;
}

INSTANTIATE_TEST_SUITE_P(
    AllKinds, CannelloniErrors,
    ::testing::Values(
        BadDatagram{{0x02, 0x00, 0x00}, "shorter than the 5-byte header"},
        BadDatagram{{0x01, 0x00, 0x00, 0x00, 0x00}, "unsupported version 1"},
        BadDatagram{{0x02, 0x01, 0x00, 0x00, 0x00}, "op code 1 is not DATA"},
        BadDatagram{{0x02, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00}, "frame 1 of 1 truncated"},
        BadDatagram{
            {0x02, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x07, 0x10, 0x09, 0, 0, 0, 0, 0, 0, 0, 0, 0},
            "length 9 > 8"},
        BadDatagram{{0x02, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x07, 0x10, 0x04, 0xAA},
                    "4 data bytes announced, 1 left"},
        BadDatagram{{0x02, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x07, 0x10, 0x00, 0xFF},
                    "1 trailing bytes after 1 frames"},
        BadDatagram{{0x02, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x07, 0x10, 0x81},
                    "missing flags byte"}));

// Two transports wired to each other on loopback.
struct Pair {
  asio::io_context io;
  UdpTransport a{io, UdpOptions{}};
  UdpTransport b{io, [this] {
                   UdpOptions o;
                   o.remote_port = a.local_port();
                   return o;
                 }()};
  Pair() { a.set_remote("127.0.0.1", b.local_port()); }
};

TEST(UdpTransport, CarriesFramesBothWaysInOrder) {
  Pair p;
  std::vector<std::pair<CanFrame, Micros>> at_a, at_b;
  p.a.start([&](const CanFrame& f, Micros ts) { at_a.emplace_back(f, ts); }, nullptr);
  p.b.start([&](const CanFrame& f, Micros ts) { at_b.emplace_back(f, ts); }, nullptr);
  EXPECT_EQ(p.a.health().state, ControllerState::kUp);

  std::vector<CanFrame> sent;
  for (int i = 0; i < 300; ++i) {  // more than one datagram's worth: exercises splitting
    sent.push_back(frame(0x700 + (i % 0x100), {static_cast<uint8_t>(i), 0xEE}));
    ASSERT_TRUE(p.a.send(sent.back()));
  }
  ASSERT_TRUE(p.b.send(frame(0x761, {})));
  ASSERT_TRUE(run_until(p.io, [&] { return at_b.size() == sent.size() && at_a.size() == 1; }))
      << at_b.size() << " / " << at_a.size();
  for (std::size_t i = 0; i < sent.size(); ++i) EXPECT_EQ(at_b[i].first, sent[i]) << i;
  EXPECT_EQ(at_a[0].first, frame(0x761, {}));
  const auto now =
      std::chrono::duration_cast<Micros>(std::chrono::system_clock::now().time_since_epoch());
  EXPECT_LE(at_b[0].second, now);
  EXPECT_GT(at_b[0].second, now - std::chrono::seconds(10));
  EXPECT_EQ(p.a.health().tx_frames, 300U);
  EXPECT_EQ(p.b.health().rx_frames, 300U);
  EXPECT_EQ(p.a.stats().datagrams_tx, 2U) << "300 frames in one turn should need 2 datagrams";
  EXPECT_EQ(p.b.stats().sequence_gaps, 0U);
}

TEST(UdpTransport, QueueLimitAndMissingRemoteFailSend) {
  asio::io_context io;
  UdpOptions o;
  o.tx_queue_limit = 2;
  UdpTransport t(io, o);
  t.start(nullptr, nullptr);
  EXPECT_FALSE(t.send(frame(0x710, {})));  // no remote yet
  t.set_remote("127.0.0.1", 9);            // discard port: nobody needs to listen
  EXPECT_TRUE(t.send(frame(0x710, {})));
  EXPECT_TRUE(t.send(frame(0x711, {})));
  EXPECT_FALSE(t.send(frame(0x712, {})));  // queue full
  EXPECT_FALSE(t.send(frame(0x800, {})));  // not an 11-bit ID
  EXPECT_EQ(t.health().tx_failures, 3U);
  run_until(io, [&] { return t.health().tx_frames == 2; });
  EXPECT_EQ(t.health().tx_frames, 2U);
  EXPECT_TRUE(t.send(frame(0x712, {})));  // drained: room again
}

TEST(UdpTransport, BadAddressesFailClearly) {
  asio::io_context io;
  UdpOptions o;
  o.local_address = "not-an-ip";
  try {
    UdpTransport t(io, o);
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("invalid local address 'not-an-ip'"), std::string::npos);
  }
  UdpTransport first(io, UdpOptions{});
  UdpOptions clash;
  clash.local_port = first.local_port();
  try {
    UdpTransport t(io, clash);
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(
        std::string(e.what()).find("cannot bind 127.0.0.1:" + std::to_string(first.local_port())),
        std::string::npos)
        << e.what();
  }
}

TEST(UdpTransport, RejectsMalformedAndForeignDatagramsAndFilters) {
  asio::io_context io;
  asio::ip::udp::socket peer(io, asio::ip::udp::endpoint(asio::ip::make_address("127.0.0.1"), 0));
  asio::ip::udp::socket stranger(io,
                                 asio::ip::udp::endpoint(asio::ip::make_address("127.0.0.1"), 0));
  UdpOptions o;
  o.remote_port = peer.local_endpoint().port();
  UdpTransport t(io, o);
  std::vector<CanFrame> got;
  std::vector<BusHealth> health;
  t.start([&](const CanFrame& f, Micros) { got.push_back(f); },
          [&](const BusHealth& h) { health.push_back(h); });
  const asio::ip::udp::endpoint to(asio::ip::make_address("127.0.0.1"), t.local_port());

  auto wire = [](uint32_t id, std::vector<uint8_t> data) {
    cannelloni::WireFrame w;
    w.can_id = id;
    w.len = static_cast<uint8_t>(data.size());
    std::copy(data.begin(), data.end(), w.data.begin());
    return w;
  };
  // 1: truncated datagram (a valid frame followed by a cut-off one): nothing of it delivered.
  auto truncated = cannelloni::encode(0, std::vector{wire(0x710, {1}), wire(0x711, {1, 2, 3})});
  truncated.pop_back();
  peer.send_to(asio::buffer(truncated), to);
  // 2: wrong version.
  peer.send_to(asio::buffer(std::vector<uint8_t>{0x03, 0x00, 0x00, 0x00, 0x00}), to);
  // 3: a good datagram from a stranger.
  stranger.send_to(asio::buffer(cannelloni::encode(0, std::vector{wire(0x712, {})})), to);
  // 4: good datagram from the peer: one delivered frame, plus filtered, error and FD frames.
  auto good =
      cannelloni::encode(1, std::vector{wire(0x123, {}), wire(0x18FF0710 | candump::kEffFlag, {}),
                                        wire(0x040 | candump::kErrFlag, {0, 0, 0, 0, 0, 0, 0, 0}),
                                        wire(0x713, {7, 7})});
  const std::vector<uint8_t> fd = {0x00, 0x00, 0x07, 0x14, 0x81, 0x00, 0x55};
  good.insert(good.end(), fd.begin(), fd.end());
  good[4] = 5;  // count now includes the FD frame
  peer.send_to(asio::buffer(good), to);

  ASSERT_TRUE(run_until(io, [&] { return got.size() == 1; }));
  run_until(
      io, [] { return false; }, std::chrono::milliseconds(50));  // nothing else arrives
  ASSERT_EQ(got.size(), 1U);
  EXPECT_EQ(got[0], frame(0x713, {7, 7}));
  EXPECT_EQ(t.stats().malformed_datagrams, 2U);
  EXPECT_EQ(t.stats().foreign_datagrams, 1U);
  EXPECT_EQ(t.stats().filtered_frames, 2U);
  EXPECT_EQ(t.stats().unsupported_frames, 1U);
  EXPECT_EQ(t.stats().datagrams_rx, 1U);
  EXPECT_EQ(t.health().error_frames, 1U);
  EXPECT_EQ(t.health().state, ControllerState::kBusOff);
  ASSERT_FALSE(health.empty());
  EXPECT_EQ(health.back().state, ControllerState::kBusOff);
}

// The child process: echoes every frame back with the ID's target nibble set to 0xF and the
// payload incremented, until it sees ID 0x7FF; exit code 0 when everything went as expected.
[[noreturn]] void echo_child(uint16_t port, uint16_t parent_port) {
  int rc = 1;
  {
    asio::io_context io;
    UdpOptions o;
    o.local_port = port;
    o.remote_port = parent_port;
    UdpTransport t(io, o);
    bool done = false;
    t.start(
        [&](const CanFrame& f, Micros) {
          if (f.id == 0x7FF) {
            done = true;
            return;
          }
          CanFrame r = f;
          r.id = f.id | 0xF;
          for (uint8_t i = 0; i < r.len; ++i) ++r.data[i];
          t.send(r);
        },
        nullptr);
    // Announce readiness so the parent does not send into the void.
    t.send(CanFrame{0x7F0, 0, {}});
    if (run_until(
            io, [&] { return done; }, std::chrono::milliseconds(10000)))
      rc = 0;
    run_until(
        io, [] { return false; }, std::chrono::milliseconds(20));  // flush replies
  }
  std::_Exit(rc);
}

TEST(UdpTransport, TwoProcessesExchangeFrames) {
  asio::io_context io;
  // Reserve the child's port by binding it here first, then hand it over via the fork.
  asio::ip::udp::socket reserve(io,
                                asio::ip::udp::endpoint(asio::ip::make_address("127.0.0.1"), 0));
  const uint16_t child_port = reserve.local_endpoint().port();
  reserve.close();
  UdpOptions o;
  o.remote_port = child_port;
  UdpTransport parent(io, o);
  const uint16_t parent_port = parent.local_port();

  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) echo_child(child_port, parent_port);

  std::vector<CanFrame> replies;
  bool child_ready = false;
  parent.start(
      [&](const CanFrame& f, Micros) {
        if (f.id == 0x7F0) {
          child_ready = true;
          for (uint8_t i = 0; i < 50; ++i)
            parent.send(frame(0x760, {i, static_cast<uint8_t>(i * 2)}));
          return;
        }
        replies.push_back(f);
        if (replies.size() == 50) parent.send(frame(0x7FF, {}));
      },
      nullptr);
  const bool ok = run_until(
      io, [&] { return replies.size() == 50; }, std::chrono::milliseconds(10000));
  run_until(
      io, [] { return false; }, std::chrono::milliseconds(20));  // let 0x7FF go out
  int status = 0;
  if (!ok) ::kill(pid, SIGKILL);
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(child_ready) << "child never announced itself";
  ASSERT_TRUE(ok) << "got " << replies.size() << " of 50 replies";
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "child status " << status;
  for (uint8_t i = 0; i < 50; ++i) {
    EXPECT_EQ(replies[i],
              frame(0x76F, {static_cast<uint8_t>(i + 1), static_cast<uint8_t>(i * 2 + 1)}))
        << int{i};
  }
}

}  // namespace
}  // namespace fleetgw::can
