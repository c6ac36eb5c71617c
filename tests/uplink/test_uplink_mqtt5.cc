// MQTT 5 in the uplink (issue 15), against a real mosquitto started by each test: records and
// status carry the content type and schema user property under MQTT 5 and nothing under 3.1.1
// (which keeps working as before); a publish the broker's ACL refuses (0x87) stays in the outbox,
// is retried with back-off, is named in the stats and the retained Status, and is delivered
// exactly once after the broker restarts with a fixed ACL; under 3.1.1 the same ACL silently
// drops the record (the known limitation, pinned here); the last will waits for its delay and
// says how long that was.
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <spdlog/sinks/ringbuffer_sink.h>
#include <spdlog/spdlog.h>
#include <sys/wait.h>

#include <algorithm>
#include <fstream>
#include <string>
#include <vector>

#include "fleetgw/v1/envelope.pb.h"
#include "gateway/uplink/memory_outbox.h"
#include "gateway/uplink/mqtt5.h"
#include "gateway/uplink/uplink.h"
#include "tests/support/mosquitto_fixture.h"
#include "tests/uplink/mqtt5_test_util.h"
#include "tests/uplink/uplink_test_util.h"

extern char** environ;

namespace fleetgw::uplink {
namespace {

using namespace std::chrono_literals;
using testing::drive;
using testing::fault_payload;
using testing::MosquittoBroker;
using testing::MosquittoOptions;
using testing::plain_config;
using testing::Received5;
using testing::ride_payload;
using testing::Subscriber5;
using testing::telemetry_payload;
using testing::wall_now;

std::optional<v1::Envelope> envelope(const Received5& m) {
  v1::Envelope env;
  if (!env.ParseFromString(m.payload)) return std::nullopt;
  return env;
}

// Anonymous clients (the uplink and the test's subscriber) may read everything under fleet/v1
// and write the vehicle's topics -- its ride topic only when `ride_allowed`.
std::string acl_for(const std::string& vehicle, bool ride_allowed) {
  std::string acl = "topic read fleet/v1/#\n";
  for (const char* leaf : {"status", "state", "telemetry", "fault", "info", "alarm"}) {
    acl += "topic write fleet/v1/" + vehicle + "/" + leaf + "\n";
  }
  if (ride_allowed) acl += "topic write fleet/v1/" + vehicle + "/ride\n";
  return acl;
}

std::size_t count_on(const std::vector<Received5>& msgs, const std::string& topic,
                     std::uint64_t seq) {
  return static_cast<std::size_t>(std::count_if(msgs.begin(), msgs.end(), [&](const auto& m) {
    const auto env = envelope(m);
    return m.topic == topic && env && env->sequence() == seq;
  }));
}

// Runs records of three kinds through an uplink speaking `protocol`; returns what arrived.
std::vector<Received5> deliver_with(MqttProtocol protocol, const std::string& vehicle,
                                    std::string* broker_log) {
  MosquittoBroker broker;
  broker.start();
  Subscriber5 sub(broker.uri(), "fleet/v1/" + vehicle + "/#", "backend-" + vehicle);
  MemoryOutbox box;
  const auto now = wall_now().count();
  box.push(2, "fault", now, fault_payload(3));
  box.push(3, "ride", now, ride_payload("ride-" + vehicle));
  for (std::uint32_t i = 0; i < 5; ++i) box.push(5, "telemetry", now, telemetry_payload(100 + i));
  UplinkConfig c = plain_config(broker.uri(), vehicle);
  c.protocol = protocol;
  Uplink up(c, box);
  up.start(wall_now());
  EXPECT_TRUE(drive(
      up, [&] { return box.stats().depth == 0; }, 10s))
      << broker.log();
  EXPECT_TRUE(sub.wait_until(
      [](const auto& m) {
        return std::count_if(m.begin(), m.end(), [](const auto& r) {
                 return r.topic.ends_with("/fault") || r.topic.ends_with("/ride") ||
                        r.topic.ends_with("/telemetry");
               }) >= 3;
      },
      5s));
  up.stop(wall_now());
  *broker_log = broker.log();
  return sub.messages();
}

TEST(UplinkMqtt5, EveryMessageNamesItsContentTypeAndSchemaVersion) {
  std::string log;
  const auto msgs = deliver_with(MqttProtocol::kV5, "bike-p5", &log);
  EXPECT_NE(log.find("as bike-p5 (p5"), std::string::npos) << "connected with MQTT 5:\n" << log;
  ASSERT_GE(msgs.size(), 4u);  // fault, ride, telemetry, status
  bool status_seen = false;
  for (const auto& m : msgs) {
    EXPECT_EQ(m.content_type, kEnvelopeContentType) << m.topic;
    EXPECT_EQ(m.schema, kSchemaVersion) << m.topic;
    ASSERT_TRUE(envelope(m)) << m.topic;
    status_seen |= m.topic.ends_with("/status");
  }
  EXPECT_TRUE(status_seen);
}

TEST(UplinkMqtt5, Mqtt311DeliversAsBeforeWithoutProperties) {
  std::string log;
  const auto msgs = deliver_with(MqttProtocol::kV311, "bike-p311", &log);
  EXPECT_NE(log.find("as bike-p311 (p2"), std::string::npos) << "connected with 3.1.1:\n" << log;
  ASSERT_GE(msgs.size(), 4u);
  for (const auto& m : msgs) {
    EXPECT_EQ(m.content_type, "") << m.topic;
    EXPECT_EQ(m.schema, "") << m.topic;
    ASSERT_TRUE(envelope(m)) << m.topic;
  }
}

TEST(UplinkMqtt5, AclRefusedPublishStaysInTheOutboxThenArrivesExactlyOnceOnceAllowed) {
  const std::string v = "bike-acl5";
  const std::string ride_topic = "fleet/v1/" + v + "/ride";
  MosquittoOptions options;
  options.acl = acl_for(v, false);
  MosquittoBroker broker(options);
  broker.start();
  Subscriber5 sub(broker.uri(), "fleet/v1/" + v + "/#", "backend-acl5");
  auto log = std::make_shared<spdlog::sinks::ringbuffer_sink_mt>(512);
  spdlog::default_logger()->sinks().push_back(log);

  MemoryOutbox box;
  const auto now = wall_now().count();
  box.push(2, "fault", now, fault_payload(1));
  const std::uint64_t ride_seq = box.push(3, "ride", now, ride_payload("ride-acl"));
  box.push(4, "fault", now, fault_payload(2));
  UplinkConfig c = plain_config(broker.uri(), v);
  c.reconnect_min = 200ms;  // also paces the retries of refused publishes
  c.reconnect_max = 800ms;
  Uplink up(c, box);
  up.start(wall_now());
  ASSERT_TRUE(drive(
      up, [&] { return up.stats().publish_refusals >= 1 && box.acked_records() == 2; }, 10s))
      << broker.log();
  const UplinkStats s = up.stats();
  EXPECT_EQ(s.last_publish_refusal, "0x87 Not authorized (" + ride_topic + ")");
  EXPECT_EQ(s.last_publish_refusal_code, 0x87);
  EXPECT_GT(s.last_publish_refusal_us, 0);
  EXPECT_EQ(s.refused_records, 1u);
  EXPECT_EQ(box.stats().depth, 1u) << "the refused ride is not acknowledged as delivered";

  // The retained Status says why.
  ASSERT_TRUE(sub.wait_until(
      [](const auto& m) {
        return std::any_of(m.begin(), m.end(), [](const auto& r) {
          const auto env = envelope(r);
          return env && env->has_status() && env->status().last_publish_refusal_code() == 0x87 &&
                 env->status().last_publish_refusal().starts_with("0x87 Not authorized") &&
                 env->status().publish_refusals() >= 1;
        });
      },
      5s));

  // Retried with back-off, not in a hot loop: two more refusals need at least the second wait
  // (random in [200, 400] ms after the 200 ms minimum doubled once).
  const auto t0 = std::chrono::steady_clock::now();
  const auto n0 = up.stats().publish_refusals;
  ASSERT_TRUE(drive(
      up, [&] { return up.stats().publish_refusals >= n0 + 2; }, 10s));
  EXPECT_GE(std::chrono::steady_clock::now() - t0, 190ms);
  EXPECT_LE(up.stats().publish_refusals, n0 + 3);
  EXPECT_EQ(box.stats().depth, 1u);
  EXPECT_EQ(count_on(sub.messages(), ride_topic, ride_seq), 0u);
  // Logged once for this reason, not once per retry.
  const auto lines = log->last_formatted();
  EXPECT_EQ(std::count_if(lines.begin(), lines.end(),
                          [](const auto& l) {
                            return l.find("the broker refused a publish: 0x87") !=
                                   std::string::npos;
                          }),
            1);
  auto& sinks = spdlog::default_logger()->sinks();
  sinks.erase(std::remove(sinks.begin(), sinks.end(), log), sinks.end());

  // The operator fixes the ACL; the broker restarts with it. The uplink reconnects only when
  // polled, so the new subscriber is in place before anything can be sent again.
  broker.stop();
  std::ofstream(broker.directory() / "acl") << acl_for(v, true);
  broker.start();
  Subscriber5 after(broker.uri(), "fleet/v1/" + v + "/#", "backend-acl5-after");
  ASSERT_TRUE(drive(
      up, [&] { return box.stats().depth == 0; }, 20s))
      << broker.log();
  EXPECT_EQ(up.stats().last_publish_refusal, "");
  EXPECT_EQ(up.stats().refused_records, 0u);
  // A marker behind it: once it arrived, a duplicate of the ride would have too.
  const std::uint64_t marker = box.push(4, "fault", wall_now().count(), fault_payload(9));
  ASSERT_TRUE(drive(
      up,
      [&] {
        return box.stats().depth == 0 &&
               count_on(after.messages(), "fleet/v1/" + v + "/fault", marker) == 1;
      },
      10s))
      << broker.log();
  EXPECT_EQ(count_on(after.messages(), ride_topic, ride_seq), 1u) << "delivered exactly once";
  EXPECT_EQ(count_on(sub.messages(), ride_topic, ride_seq), 0u);
  // The retained status no longer names a refusal, and still counts the past ones.
  ASSERT_TRUE(drive(
      up,
      [&] {
        const auto m = after.messages();
        for (auto it = m.rbegin(); it != m.rend(); ++it) {
          const auto env = envelope(*it);
          if (env && env->has_status()) {
            return env->status().last_publish_refusal().empty() &&
                   env->status().publish_refusals() >= n0 + 2;
          }
        }
        return false;
      },
      5s));
  up.stop(wall_now());
}

// The known limitation of the fallback, pinned so a change of mosquitto's behaviour is noticed:
// an MQTT 3.1.1 broker acknowledges a publish its ACL drops, so the record is deleted unseen.
TEST(UplinkMqtt5, Mqtt311CannotSeeARefusalTheDroppedRecordIsAckedAndLost) {
  const std::string v = "bike-acl311";
  MosquittoOptions options;
  options.acl = acl_for(v, false);
  MosquittoBroker broker(options);
  broker.start();
  Subscriber5 sub(broker.uri(), "fleet/v1/" + v + "/#", "backend-acl311");
  MemoryOutbox box;
  const auto now = wall_now().count();
  const std::uint64_t ride_seq = box.push(3, "ride", now, ride_payload("ride-lost"));
  const std::uint64_t marker = box.push(4, "fault", now, fault_payload(9));
  UplinkConfig c = plain_config(broker.uri(), v);
  c.protocol = MqttProtocol::kV311;
  Uplink up(c, box);
  up.start(wall_now());
  ASSERT_TRUE(drive(
      up,
      [&] {
        return box.stats().depth == 0 &&
               count_on(sub.messages(), "fleet/v1/" + v + "/fault", marker) == 1;
      },
      10s))
      << broker.log();
  EXPECT_EQ(box.acked_records(), 2u) << "the dropped ride was acknowledged like a delivered one";
  EXPECT_EQ(count_on(sub.messages(), "fleet/v1/" + v + "/ride", ride_seq), 0u);
  EXPECT_EQ(up.stats().publish_refusals, 0u);
  EXPECT_EQ(up.stats().last_publish_refusal, "");
  up.stop(wall_now());
}

// The child mode of uplink_tests (test_uplink_mqtt.cc) connects as bike-will and waits to be
// killed; FLEETGW_UPLINK_TEST_CHILD_WILL_DELAY_S sets its will delay.
TEST(UplinkMqtt5, LastWillComesAfterItsDelayAndSaysHowLongItWas) {
  MosquittoBroker broker;
  broker.start();
  Subscriber5 sub(broker.uri(), "fleet/v1/bike-will/status", "backend-will5");
  const std::string uri_kv = "FLEETGW_UPLINK_TEST_CHILD_URI=" + broker.uri();
  const std::string delay_kv = "FLEETGW_UPLINK_TEST_CHILD_WILL_DELAY_S=2";
  std::vector<char*> envp;
  for (char** e = environ; *e != nullptr; ++e) envp.push_back(*e);
  envp.push_back(const_cast<char*>(uri_kv.c_str()));
  envp.push_back(const_cast<char*>(delay_kv.c_str()));
  envp.push_back(nullptr);
  std::string self = "/proc/self/exe";
  char* argv[] = {self.data(), nullptr};
  pid_t child = -1;
  ASSERT_EQ(posix_spawn(&child, "/proc/self/exe", nullptr, nullptr, argv, envp.data()), 0);
  const auto state_is = [](const Received5& r, v1::OnlineState want) {
    const auto env = envelope(r);
    return env && env->has_status() && env->status().state() == want;
  };
  const bool online = sub.wait_until(
      [&](const auto& m) {
        return std::any_of(m.begin(), m.end(),
                           [&](const auto& r) { return state_is(r, v1::ONLINE_STATE_ONLINE); });
      },
      10s);
  ::kill(child, SIGKILL);  // no DISCONNECT: the broker publishes the will, after its delay
  const auto killed_at = std::chrono::steady_clock::now();
  int status = 0;
  ::waitpid(child, &status, 0);
  ASSERT_TRUE(online) << broker.log();
  ASSERT_TRUE(sub.wait_until(
      [&](const auto& m) { return !m.empty() && state_is(m.back(), v1::ONLINE_STATE_OFFLINE); },
      15s))
      << broker.log();
  const Received5 will = sub.messages().back();
  // mosquitto checks will delays once a second: the will comes 2..3 s after the loss.
  EXPECT_GE(will.at - killed_at, 1900ms);
  EXPECT_EQ(will.will_delay_s, "2") << "the will says how long after the loss it was sent";
  EXPECT_EQ(will.schema, kSchemaVersion);
  EXPECT_EQ(will.content_type, kEnvelopeContentType);
  EXPECT_TRUE(envelope(will)->status().last_will());
  EXPECT_EQ(envelope(will)->status().connection(), v1::CONNECTION_STATE_LOST);
}

}  // namespace
}  // namespace fleetgw::uplink
