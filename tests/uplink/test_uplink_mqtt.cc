// Integration tests of the uplink against a real mosquitto broker started by the test itself
// (tests/support/mosquitto_fixture.h): delivery, outage, in-flight bound, TLS, ACL, commands,
// last will.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <map>
#include <set>
#include <thread>

#include "fleetgw/v1/command.pb.h"
#include "fleetgw/v1/envelope.pb.h"
#include "gateway/uplink/memory_outbox.h"
#include "gateway/uplink/tcp_nodelay.h"
#include "gateway/uplink/uplink.h"
#include "tests/support/mosquitto_fixture.h"
#include "tests/uplink/uplink_test_util.h"

extern char** environ;

namespace fleetgw::uplink {
namespace {

using namespace std::chrono_literals;
using testing::drive;
using testing::last_status;
using testing::MosquittoBroker;
using testing::MosquittoOptions;
using testing::plain_config;
using testing::Received;
using testing::received_sequences;
using testing::Subscriber;
using testing::wall_now;

std::set<std::uint64_t> as_set(const std::vector<std::uint64_t>& v) {
  return {v.begin(), v.end()};
}

std::set<std::uint64_t> range_set(std::uint64_t first, std::uint64_t last) {
  std::set<std::uint64_t> s;
  for (auto i = first; i <= last; ++i) s.insert(i);
  return s;
}

bool has_all(const std::vector<Received>& msgs, const std::string& vehicle, std::uint64_t n) {
  const auto got = as_set(received_sequences(msgs, vehicle));
  return got.size() >= n && got == range_set(1, n);
}

// ---------------------------------------------------------------------------------------------
TEST(UplinkMqtt, EndToEndEveryKindArrivesOnItsTopicWithContiguousSequences) {
  MosquittoBroker broker;
  broker.start();
  Subscriber sub(broker.uri(), "fleet/v1/#", "backend-e2e");
  MemoryOutbox box;
  // Interleaved kinds and priorities, as the trackers would produce them.
  std::map<std::uint64_t, std::string> kind_of;
  for (int i = 0; i < 600; ++i) {
    const auto t = wall_now().count();
    kind_of[box.push(5, kind::kTelemetry, t, testing::telemetry_payload(i))] = "telemetry";
    if (i % 20 == 0)
      kind_of[box.push(1, kind::kFault, t, testing::fault_payload(i / 20))] = "fault";
    if (i % 60 == 0)
      kind_of[box.push(2, kind::kRide, t, testing::ride_payload("r" + std::to_string(i)))] = "ride";
  }
  v1::DeviceInfo info;
  auto* node = info.add_nodes();
  node->set_node("mc");
  node->set_serial("MC123");
  kind_of[box.push(3, kind::kInfo, wall_now().count(), info.SerializeAsString())] = "info";
  v1::PackStatistics pack;
  pack.add_cells_mv(3701);
  pack.add_cells_mv(3699);
  kind_of[box.push(3, kind::kPack, wall_now().count(), pack.SerializeAsString())] = "pack";
  v1::CommandResult result;
  result.set_command_id("c-1");
  result.set_result(v1::COMMAND_RESULT_CODE_SUCCEEDED);
  kind_of[box.push(0, kind::kCommandResult, wall_now().count(), result.SerializeAsString())] =
      "cmd/result";
  const std::uint64_t n = kind_of.size();

  auto cfg = plain_config(broker.uri(), "bike-e2e");
  cfg.telemetry_batch_max_samples = 50;
  Uplink up(cfg, box);
  up.start(wall_now());
  ASSERT_TRUE(drive(
      up, [&] { return box.stats().depth == 0; }, 20s))
      << broker.log();
  ASSERT_TRUE(sub.wait_until([&](auto& m) { return has_all(m, "bike-e2e", n); }, 10s));

  const auto msgs = sub.messages();
  std::size_t telemetry_messages = 0;
  bool saw_online = false;
  for (const auto& m : msgs) {
    v1::Envelope env;
    ASSERT_TRUE(env.ParseFromString(m.payload)) << m.topic;
    EXPECT_EQ(env.vehicle_id(), "bike-e2e");
    EXPECT_EQ(env.gateway_fw_version(), "test-1.2.3");
    if (env.has_status()) {
      EXPECT_EQ(m.topic, "fleet/v1/bike-e2e/status");
      saw_online |= env.status().state() == v1::ONLINE_STATE_ONLINE;
      continue;
    }
    if (env.has_telemetry()) {
      ++telemetry_messages;
      EXPECT_EQ(m.topic, "fleet/v1/bike-e2e/telemetry");
      EXPECT_LE(env.telemetry().samples_size(), 50);
      EXPECT_EQ(env.sequence(), env.telemetry().samples(0).sequence());
      for (const auto& s : env.telemetry().samples()) {
        EXPECT_EQ(kind_of[s.sequence()], "telemetry");
        EXPECT_EQ(s.voltage_mv(), 48'123u);
        EXPECT_EQ(s.current_ma(), -1500);
        EXPECT_TRUE(s.has_speed_dkmh());
      }
      continue;
    }
    EXPECT_EQ(m.topic, "fleet/v1/bike-e2e/" + kind_of[env.sequence()]) << env.sequence();
    if (env.has_fault()) {
      EXPECT_EQ(env.fault().name(), "over_current_protect");
    }
    if (env.has_pack()) {
      EXPECT_EQ(env.pack().cells_mv_size(), 2);
    }
    if (env.has_info()) {
      EXPECT_EQ(env.info().nodes(0).serial(), "MC123");
    }
    if (env.has_command_result()) {
      EXPECT_EQ(env.command_result().command_id(), "c-1");
    }
  }
  EXPECT_TRUE(saw_online);
  EXPECT_EQ(telemetry_messages, 12u);  // 600 samples / 50 per batch
  // Speeds carried per sample match what was stored for that sequence (contents survive).
  std::map<std::uint32_t, int> speeds;
  for (const auto& m : msgs) {
    v1::Envelope env;
    env.ParseFromString(m.payload);
    if (env.has_telemetry()) {
      for (const auto& s : env.telemetry().samples()) ++speeds[s.speed_dkmh()];
    }
  }
  EXPECT_EQ(speeds.size(), 600u);
  const auto st = up.stats();
  EXPECT_EQ(st.acked_records, n);
  EXPECT_EQ(st.rejected_records, 0u);
  EXPECT_EQ(st.in_flight_messages, 0u);
  EXPECT_GT(st.last_publish_ok_us, 0);
  EXPECT_EQ(st.connects, 1u);
}

TEST(UplinkMqtt, PriorityDecidesTheOrderThenSequence) {
  MosquittoBroker broker;
  broker.start();
  Subscriber sub(broker.uri(), "fleet/v1/+/fault", "backend-prio");
  MemoryOutbox box;
  for (int i = 0; i < 30; ++i)
    box.push(i % 3, kind::kFault, wall_now().count(), testing::fault_payload(i));
  auto cfg = plain_config(broker.uri(), "bike-prio");
  cfg.max_in_flight = 1;  // one at a time: arrival order is publish order
  Uplink up(cfg, box);
  up.start(wall_now());
  ASSERT_TRUE(drive(
      up, [&] { return box.stats().depth == 0; }, 10s));
  ASSERT_TRUE(sub.wait_until([](auto& m) { return m.size() >= 30; }, 5s));
  std::vector<std::pair<std::uint32_t, std::uint64_t>> order;  // (priority, seq)
  for (const auto& m : sub.messages()) {
    v1::Envelope env;
    env.ParseFromString(m.payload);
    order.emplace_back(env.fault().bit() % 3, env.sequence());
  }
  EXPECT_TRUE(std::is_sorted(order.begin(), order.end()));
}

TEST(UplinkMqtt, LiveTelemetryUsesItsQosBacklogUsesQos1) {
  MosquittoBroker broker;
  broker.start();
  Subscriber sub(broker.uri(), "fleet/v1/+/telemetry", "backend-qos");
  MemoryOutbox box;
  auto cfg = plain_config(broker.uri(), "bike-qos");
  cfg.live_telemetry_qos = 0;
  Uplink up(cfg, box);
  box.push(5, kind::kTelemetry, wall_now().count() - 3'600'000'000LL,
           testing::telemetry_payload(1));
  up.start(wall_now());
  ASSERT_TRUE(drive(
      up, [&] { return box.stats().depth == 0; }, 10s));
  box.push(5, kind::kTelemetry, wall_now().count(), testing::telemetry_payload(2));
  ASSERT_TRUE(drive(
      up, [&] { return box.stats().depth == 0; }, 10s));
  ASSERT_TRUE(sub.wait_until([](auto& m) { return m.size() >= 2; }, 5s));
  const auto msgs = sub.messages();
  EXPECT_EQ(msgs[0].qos, 1);  // hour-old backlog
  EXPECT_EQ(msgs[1].qos, 0);  // live
}

TEST(UplinkMqtt, BadRecordsAreDroppedWithoutBlockingTheQueue) {
  MosquittoBroker broker;
  broker.start();
  Subscriber sub(broker.uri(), "fleet/v1/#", "backend-poison");
  MemoryOutbox box;
  box.push(0, "no_such_kind", 1, "x");
  box.push(0, kind::kTelemetry, 2, std::string("\xff\xff\xff\xff", 4));
  box.push(0, kind::kFault, 3, std::string("\x0a\x05" "ab", 4));  // a corrupted stored body
  box.push(1, kind::kRide, 4, testing::ride_payload("good"));
  Uplink up(plain_config(broker.uri(), "bike-poison"), box);
  up.start(wall_now());
  ASSERT_TRUE(drive(
      up, [&] { return box.stats().depth == 0; }, 10s));
  EXPECT_EQ(up.stats().rejected_records, 3u);
  EXPECT_TRUE(sub.wait_until(
      [](auto& m) { return received_sequences(m, "bike-poison") == std::vector<std::uint64_t>{4}; },
      5s));
}

// Stop the broker mid-stream while records keep coming; bring it back on the same port.
TEST(UplinkMqtt, OutageLosesNothingAndKeepsOrderWithinEachPriority) {
  MosquittoOptions opts;
  opts.persistence = true;  // the backend's persistent session survives the broker restart
  MosquittoBroker broker(opts);
  broker.start();
  Subscriber sub(broker.uri(), "fleet/v1/#", "backend-outage", std::nullopt, true);
  MemoryOutbox box;
  std::map<std::uint64_t, int> prio;
  auto produce = [&](int count) {
    for (int i = 0; i < count; ++i) {
      const auto t = wall_now().count();
      prio[box.push(5, kind::kTelemetry, t, testing::telemetry_payload(i))] = 5;
      if (i % 4 == 0) prio[box.push(1, kind::kFault, t, testing::fault_payload(i))] = 1;
    }
  };
  auto cfg = plain_config(broker.uri(), "bike-outage");
  cfg.telemetry_batch_max_samples = 20;
  cfg.max_in_flight = 16;
  Uplink up(cfg, box);
  up.start(wall_now());
  ASSERT_TRUE(drive(
      up, [&] { return up.state() == UplinkState::kConnected; }, 10s));
  // Phase 1: stream with the broker up.
  for (int round = 0; round < 20; ++round) {
    produce(25);
    drive(
        up, [] { return false; }, 10ms);
  }
  ASSERT_GT(up.stats().acked_records, 0u);
  // Phase 2: broker down, production continues.
  broker.stop();
  for (int round = 0; round < 30; ++round) {
    produce(25);
    drive(
        up, [] { return false; }, 15ms);
  }
  EXPECT_NE(up.state(), UplinkState::kConnected);
  const auto during = up.stats();
  EXPECT_GE(during.connection_losses, 1u);
  EXPECT_GE(during.connect_failures, 1u);
  EXPECT_GT(during.last_backoff.count(), 0);
  EXPECT_GT(during.outbox_depth, 0u);
  // Phase 3: broker back on the same port; drain.
  broker.start();
  produce(50);
  ASSERT_TRUE(drive(
      up, [&] { return box.stats().depth == 0; }, 30s))
      << "depth " << up.stats().outbox_depth << " in flight " << up.stats().in_flight_messages
      << " state " << to_string(up.state());
  const std::uint64_t n = prio.size();
  ASSERT_TRUE(sub.wait_until([&](auto& m) { return has_all(m, "bike-outage", n); }, 15s))
      << "received " << as_set(received_sequences(sub.messages(), "bike-outage")).size() << " of "
      << n;
  // Order within each priority: first arrivals of each sequence are increasing.
  std::set<std::uint64_t> seen;
  std::map<int, std::uint64_t> last_first_arrival;
  for (const auto seq : received_sequences(sub.messages(), "bike-outage")) {
    if (!seen.insert(seq).second) continue;  // a duplicate (allowed, detectable)
    auto& last = last_first_arrival[prio[seq]];
    EXPECT_GT(seq, last) << "priority " << prio[seq];
    last = seq;
  }
  EXPECT_GE(up.stats().reconnects, 1u);
}

TEST(UplinkMqtt, InFlightIsBoundedAndNothingIsAckedWithoutPuback) {
  MosquittoBroker broker;
  broker.start();
  MemoryOutbox box;
  auto cfg = plain_config(broker.uri(), "bike-window");
  cfg.max_in_flight = 4;
  Uplink up(cfg, box);
  up.start(wall_now());
  ASSERT_TRUE(drive(
      up, [&] { return up.stats().acked_messages >= 1; }, 10s));  // status acked
  broker.pause();  // connection open, nothing acknowledged
  for (int i = 0; i < 200; ++i)
    box.push(1, kind::kFault, wall_now().count(), testing::fault_payload(i));
  drive(
      up, [] { return false; }, 1500ms);
  auto st = up.stats();
  EXPECT_EQ(st.in_flight_messages, 4u);
  EXPECT_LE(st.in_flight_high_water, 4u);
  EXPECT_EQ(st.acked_records, 0u);
  EXPECT_EQ(box.acked_records(), 0u);
  EXPECT_EQ(box.stats().depth, 200u);
  // The broker dies with those publishes unacknowledged: they must stay in the outbox.
  broker.kill();
  ASSERT_TRUE(drive(
      up, [&] { return up.state() != UplinkState::kConnected; }, 10s));
  EXPECT_EQ(box.acked_records(), 0u);
  EXPECT_EQ(box.stats().depth, 200u);
  broker.start();
  Subscriber sub(broker.uri(), "fleet/v1/#", "backend-window");
  ASSERT_TRUE(drive(
      up, [&] { return box.stats().depth == 0; }, 30s))
      << broker.log();
  EXPECT_TRUE(sub.wait_until([&](auto& m) { return has_all(m, "bike-window", 200); }, 10s));
  EXPECT_LE(up.stats().in_flight_high_water, 4u);
}

TEST(UplinkMqtt, BackoffIsObservableAndConnectsWhenTheBrokerAppears) {
  MosquittoBroker broker;  // configured, not started
  MemoryOutbox box;
  box.push(0, kind::kRide, 1, testing::ride_payload("late"));
  auto cfg = plain_config(broker.uri(), "bike-late");
  cfg.reconnect_min = 40ms;
  cfg.reconnect_max = 160ms;
  Uplink up(cfg, box);
  up.start(wall_now());
  ASSERT_TRUE(drive(
      up, [&] { return up.stats().connect_failures >= 4; }, 10s));
  auto st = up.stats();
  EXPECT_EQ(st.state, UplinkState::kWaitingToReconnect);
  EXPECT_GE(st.last_backoff.count(), 80);  // 4th failure: d = 160 ms, wait in [80, 160]
  EXPECT_LE(st.last_backoff.count(), 160);
  EXPECT_GT(st.next_connect_at_us, 0);
  broker.start();
  ASSERT_TRUE(drive(
      up, [&] { return box.stats().depth == 0; }, 10s));
  EXPECT_EQ(up.stats().connects, 1u);
}

// TCP_NODELAY of every socket of this process connected to `port` (no other client of that
// broker lives in this test, so these are the uplink's).
std::vector<int> nodelay_of_sockets_to(std::uint16_t port) {
  std::vector<int> flags;
  for (int fd = 0; fd < 1024; ++fd) {
    sockaddr_in peer{};
    socklen_t len = sizeof peer;
    if (::getpeername(fd, reinterpret_cast<sockaddr*>(&peer), &len) != 0 ||
        peer.sin_family != AF_INET || ntohs(peer.sin_port) != port) {
      continue;
    }
    int flag = -1;
    socklen_t flag_len = sizeof flag;
    ::getsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &flag, &flag_len);
    flags.push_back(flag);
  }
  return flags;
}

// Without TCP_NODELAY a command result waits behind the command's PUBACK for the broker's
// delayed ACK (~40 ms); Paho has no option for it, so the uplink sets it after every connect.
TEST(UplinkMqtt, BrokerSocketGetsTcpNodelayAfterEveryConnect) {
  MosquittoBroker broker;
  broker.start();
  MemoryOutbox box;
  for (const bool enabled : {true, false}) {
    auto cfg = plain_config(broker.uri(), enabled ? "bike-nodelay" : "bike-nagle");
    cfg.tcp_nodelay = enabled;
    Uplink up(cfg, box);
    up.start(wall_now());
    ASSERT_TRUE(drive(
        up, [&] { return up.state() == UplinkState::kConnected; }, 10s));
    EXPECT_EQ(nodelay_of_sockets_to(broker.port()), std::vector<int>{enabled ? 1 : 0});
    if (enabled) {
      // A reconnect opens a new socket: it gets the option too.
      broker.stop();
      broker.start();
      ASSERT_TRUE(drive(
          up, [&] { return up.stats().reconnects >= 1 && up.state() == UplinkState::kConnected; },
          15s));
      EXPECT_EQ(nodelay_of_sockets_to(broker.port()), std::vector<int>{1});
    }
    up.stop(wall_now(), 2s);
  }
}

// ---- commands --------------------------------------------------------------------------------
TEST(UplinkMqtt, BadCommandPayloadsAreDroppedAndTheClientKeepsWorking) {
  MosquittoBroker broker;
  broker.start();
  Subscriber sub(broker.uri(), "fleet/v1/bike-cmd/ride", "backend-cmd");
  MemoryOutbox box;
  auto cfg = plain_config(broker.uri(), "bike-cmd");
  cfg.max_command_bytes = 4096;
  Uplink up(cfg, box);
  std::vector<std::string> handled;
  // Commands are only queued inside poll(); the owner takes them after it returns.
  auto take = [&] {
    for (auto& c : up.take_commands()) handled.push_back(std::move(c));
  };
  up.start(wall_now());
  ASSERT_TRUE(drive(
      up, [&] { return up.stats().acked_messages >= 1; }, 10s));

  v1::Command cmd;
  cmd.set_command_id("c-42");
  cmd.set_vehicle_id("bike-cmd");
  cmd.set_action(v1::COMMAND_ACTION_LOCK);
  cmd.set_whole_vehicle(true);
  v1::SignedCommand signed_cmd;
  signed_cmd.set_command(cmd.SerializeAsString());
  signed_cmd.set_signature("sig");
  signed_cmd.set_key_id("k1");
  const std::string good = signed_cmd.SerializeAsString();

  auto& pub = sub.client();
  const std::string topic = "fleet/v1/bike-cmd/cmd";
  pub.publish(topic, std::string(5000, 'A'), 1, false)->wait();              // oversized
  pub.publish(topic, std::string("\xff\xff\xff\x07", 4), 1, false)->wait();  // not protobuf
  pub.publish(topic, std::string(), 1, false)->wait();                       // empty
  pub.publish(topic, good, 1, false)->wait();
  ASSERT_TRUE(drive(
      up,
      [&] {
        take();
        return handled.size() == 1 && up.stats().commands_dropped == 3;
      },
      10s))
      << handled.size() << " " << up.stats().commands_dropped;
  EXPECT_EQ(handled[0], good);
  // Still publishing after the garbage.
  box.push(0, kind::kRide, wall_now().count(), testing::ride_payload("after"));
  ASSERT_TRUE(drive(
      up, [&] { return box.stats().depth == 0; }, 10s));
  EXPECT_TRUE(sub.wait_until([](auto& m) { return m.size() == 1; }, 5s));
  EXPECT_EQ(up.state(), UplinkState::kConnected);
}

// ---- status and last will --------------------------------------------------------------------

TEST(UplinkMqtt, StopPublishesRetainedOfflineStatus) {
  MosquittoBroker broker;
  broker.start();
  MemoryOutbox box;
  {
    Uplink up(plain_config(broker.uri(), "bike-stop"), box);
    up.start(wall_now());
    ASSERT_TRUE(drive(
        up, [&] { return up.stats().acked_messages >= 1; }, 10s));
    up.stop(wall_now());
    EXPECT_EQ(up.state(), UplinkState::kStopped);
  }
  // A consumer arriving later reads the retained status.
  Subscriber late(broker.uri(), "fleet/v1/bike-stop/status", "backend-late");
  ASSERT_TRUE(late.wait_until([](auto& m) { return !m.empty(); }, 5s));
  EXPECT_TRUE(late.messages().back().retained);
  EXPECT_EQ(last_status(late).state(), v1::ONLINE_STATE_OFFLINE);
  EXPECT_EQ(last_status(late).connection(), v1::CONNECTION_STATE_DISCONNECTED);
}

// Issue 26: the retained status is a value the owner hands over; the uplink builds none and
// calls out for none. It asks for one after the connect (status_wanted), publishes exactly what
// it was handed stamped with its connection (state, connection, connected_at_us), publishes
// nothing when nothing new was handed, and stop() publishes the latest one as OFFLINE.
TEST(UplinkMqtt, PublishesTheStatusItIsHandedStampedWithItsConnection) {
  MosquittoBroker broker;
  broker.start();
  MemoryOutbox box;
  Subscriber sub(broker.uri(), "fleet/v1/bike-bus/status", "backend-bus");
  Uplink up(plain_config(broker.uri(), "bike-bus"), box);
  EXPECT_FALSE(up.status_wanted()) << "not connected: nothing to publish it on";
  up.start(wall_now());
  const auto until = std::chrono::steady_clock::now() + 10s;
  while (up.state() != UplinkState::kConnected && std::chrono::steady_clock::now() < until) {
    up.poll(wall_now());
    up.wait_for_events(5ms);
  }
  ASSERT_EQ(up.state(), UplinkState::kConnected) << broker.log();
  EXPECT_TRUE(up.status_wanted()) << "a new connection asks its owner for a fresh status";
  for (int i = 0; i < 5; ++i) up.poll(wall_now());
  EXPECT_EQ(up.stats().published_messages, 0u) << "no status of its own making";

  v1::Status handed;
  handed.set_firmware_version("owner-9");
  handed.set_bus_state(v1::BUS_STATE_ACTIVE);
  handed.set_outbox_depth(7);
  handed.mutable_storage()->set_failing(true);
  handed.set_attention_needed(true);
  handed.add_attention("store writes failing: disk full (SQLITE_FULL) (3 failed writes)");
  handed.set_state(v1::ONLINE_STATE_OFFLINE);  // the connection's to say: overwritten
  up.set_status(handed);
  EXPECT_FALSE(up.status_wanted());
  EXPECT_TRUE(up.next_poll_due(wall_now()) <= wall_now()) << "a handed status makes a poll due";
  ASSERT_TRUE(drive(
      up, [&] { return up.stats().acked_messages >= 1; }, 10s));
  ASSERT_TRUE(sub.wait_until([](auto& m) { return !m.empty(); }, 5s));
  const v1::Status got = last_status(sub);
  EXPECT_EQ(got.state(), v1::ONLINE_STATE_ONLINE);
  EXPECT_EQ(got.connection(), v1::CONNECTION_STATE_CONNECTED);
  EXPECT_GT(got.connected_at_us(), 0);
  v1::Status rest = got;  // everything else is what the owner handed
  rest.clear_state();
  rest.clear_connection();
  rest.clear_connected_at_us();
  handed.clear_state();
  EXPECT_EQ(rest.SerializeAsString(), handed.SerializeAsString());

  // Nothing new handed: nothing published.
  const auto published = up.stats().published_messages;
  for (int i = 0; i < 5; ++i) up.poll(wall_now());
  EXPECT_EQ(up.stats().published_messages, published);
  // A new one (the bus fell silent) goes out at the next poll.
  handed.set_bus_state(v1::BUS_STATE_SILENT);
  up.set_status(handed);
  ASSERT_TRUE(drive(
      up, [&] { return up.stats().acked_messages >= 2; }, 10s));
  ASSERT_TRUE(sub.wait_until([](auto& m) { return m.size() >= 2; }, 5s));
  EXPECT_EQ(last_status(sub).bus_state(), v1::BUS_STATE_SILENT);

  up.stop(wall_now());
  Subscriber late(broker.uri(), "fleet/v1/bike-bus/status", "backend-late");
  ASSERT_TRUE(late.wait_until([](auto& m) { return !m.empty(); }, 5s));
  EXPECT_TRUE(late.messages().back().retained);
  const v1::Status offline = last_status(late);
  EXPECT_EQ(offline.state(), v1::ONLINE_STATE_OFFLINE);
  EXPECT_EQ(offline.connection(), v1::CONNECTION_STATE_DISCONNECTED);
  EXPECT_EQ(offline.attention_size(), 1) << "the latest handed status, as offline";
  EXPECT_EQ(offline.bus_state(), v1::BUS_STATE_SILENT);
}

constexpr const char* kChildEnv = "FLEETGW_UPLINK_TEST_CHILD_URI";

TEST(UplinkMqtt, LastWillSetsOfflineWhenTheProcessDies) {
  MosquittoBroker broker;
  broker.start();
  Subscriber sub(broker.uri(), "fleet/v1/bike-will/status", "backend-will");
  // The client runs in a child process (this binary in child mode) so it can really die.
  const std::string env_kv = std::string(kChildEnv) + "=" + broker.uri();
  std::vector<char*> envp;
  for (char** e = environ; *e != nullptr; ++e) envp.push_back(*e);
  envp.push_back(const_cast<char*>(env_kv.c_str()));
  envp.push_back(nullptr);
  std::string self = "/proc/self/exe";
  char* argv[] = {self.data(), nullptr};
  pid_t child = -1;
  ASSERT_EQ(posix_spawn(&child, "/proc/self/exe", nullptr, nullptr, argv, envp.data()), 0);
  const bool online = sub.wait_until(
      [](auto& m) {
        for (const auto& r : m) {
          v1::Envelope env;
          if (env.ParseFromString(r.payload) && env.status().state() == v1::ONLINE_STATE_ONLINE)
            return true;
        }
        return false;
      },
      10s);
  ::kill(child, SIGKILL);  // no DISCONNECT: the broker must publish the will
  int status = 0;
  ::waitpid(child, &status, 0);
  ASSERT_TRUE(online) << broker.log();
  ASSERT_TRUE(sub.wait_until(
      [](auto& m) {
        v1::Envelope env;
        return !m.empty() && env.ParseFromString(m.back().payload) &&
               env.status().state() == v1::ONLINE_STATE_OFFLINE;
      },
      10s))
      << broker.log();
  EXPECT_EQ(last_status(sub).connection(), v1::CONNECTION_STATE_LOST);
  EXPECT_EQ(last_status(sub).firmware_version(), "test-1.2.3");
  // Schema v1.1: the will says it is one and carries nothing it could not know at the moment
  // of loss (the child connected with 3 records queued and a decorator flagging attention).
  v1::Envelope will;
  ASSERT_TRUE(will.ParseFromString(sub.messages().back().payload));
  EXPECT_TRUE(will.status().last_will());
  EXPECT_EQ(will.created_at_us(), 0) << "the broker's receive time is the time of loss";
  EXPECT_EQ(will.sequence(), 0u);
  EXPECT_EQ(will.store_id(), "") << "the will is not a record";
  EXPECT_EQ(will.status().outbox_depth(), 0u);
  EXPECT_EQ(will.status().oldest_unsent_created_at_us(), 0);
  EXPECT_FALSE(will.status().attention_needed());
  EXPECT_GT(will.status().connected_at_us(), 0);
  // The online status of the same connection is complete and not marked as a will.
  bool online_seen = false;
  for (const auto& m : sub.messages()) {
    v1::Envelope env;
    if (!env.ParseFromString(m.payload) || env.status().state() != v1::ONLINE_STATE_ONLINE) {
      continue;
    }
    online_seen = true;
    EXPECT_FALSE(env.status().last_will());
    EXPECT_TRUE(env.status().attention_needed());
    EXPECT_EQ(env.store_id(), "store-will");
    EXPECT_EQ(env.status().connected_at_us(), will.status().connected_at_us());
  }
  EXPECT_TRUE(online_seen);
}

}  // namespace

// Child mode for the last-will test: connect, then wait to be killed.
int run_will_child(const char* uri) {
  MemoryOutbox box;
  v1::FaultEvent fault;
  fault.set_node("mc");
  for (int i = 0; i < 3; ++i) box.push(1, "fault", wall_now().count(), fault.SerializeAsString());
  UplinkConfig config = plain_config(uri, "bike-will");
  config.store_id = "store-will";
  // MQTT 5 will delay: none unless a test asks for one (test_uplink_mqtt5.cc).
  const char* delay = std::getenv("FLEETGW_UPLINK_TEST_CHILD_WILL_DELAY_S");
  config.will_delay = std::chrono::seconds(delay != nullptr ? std::atoi(delay) : 0);
  Uplink up(config, box);
  up.start(wall_now());
  for (;;) {
    up.poll(wall_now());
    // The owner's status flags attention: the will must not carry it.
    testing::hand_status(up, [](v1::Status& s) { s.set_attention_needed(true); });
    up.wait_for_events(50ms);
  }
}

}  // namespace fleetgw::uplink

int main(int argc, char** argv) {
  if (const char* uri = std::getenv(fleetgw::uplink::kChildEnv)) {
    return fleetgw::uplink::run_will_child(uri);
  }
  ::testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
