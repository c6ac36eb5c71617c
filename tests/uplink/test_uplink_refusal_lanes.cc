// Per-kind refusal lanes (issue 24, finding 5): a broker ACL that refuses one kind of record
// (MQTT 5, 0x87) must not hold back the others. Before the lanes, a refused alarm (priority 0)
// stopped the whole drain until its retry, and each retry sent the alarm first again: 107
// telemetry records waited behind one refused alarm. Here, against a real mosquitto whose ACL
// denies `alarm` and `zone`: the refused records stay queued and are named in the stats (and so in
// every Status and in `fleetgw status`), telemetry and faults queued after the refusal arrive
// before the refused kinds are even retried, and once the broker restarts with an ACL that allows
// them, the alarms and zone events arrive exactly once, in their order.
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <string>
#include <vector>

#include "fleetgw/v1/envelope.pb.h"
#include "gateway/uplink/memory_outbox.h"
#include "gateway/uplink/uplink.h"
#include "tests/support/mosquitto_fixture.h"
#include "tests/uplink/mqtt5_test_util.h"
#include "tests/uplink/uplink_test_util.h"

namespace fleetgw::uplink {
namespace {

using namespace std::chrono_literals;
using testing::drive;
using testing::fault_payload;
using testing::MosquittoBroker;
using testing::MosquittoOptions;
using testing::plain_config;
using testing::Received5;
using testing::Subscriber5;
using testing::telemetry_payload;
using testing::wall_now;

// Anonymous clients may read everything below fleet/v1 and write the vehicle's topics, except
// the `denied` leaves.
std::string acl_denying(const std::string& vehicle, const std::vector<std::string>& denied) {
  std::string acl = "topic read fleet/v1/#\n";
  for (const auto& t : kTopicTable) {
    if (t.direction != TopicDirection::kPublish) continue;
    if (std::find(denied.begin(), denied.end(), std::string(t.leaf)) != denied.end()) continue;
    acl += "topic write fleet/v1/" + vehicle + "/" + std::string(t.leaf) + "\n";
  }
  return acl;
}

std::string alarm_payload(std::int64_t at_us) {
  v1::Alarm a;
  a.set_kind(v1::ALARM_KIND_UNAUTHORISED_MOVEMENT);
  a.set_transition(v1::ALARM_TRANSITION_RAISED);
  a.set_at_us(at_us);
  return a.SerializeAsString();
}

std::string zone_payload(const std::string& id) {
  v1::ZoneEvent z;
  z.set_zone_id(id);
  z.set_zone_name("Old Town");
  z.set_at_us(wall_now().count());
  return z.SerializeAsString();
}

// Outbox sequence numbers that arrived on `leaf`, in arrival order (telemetry: per sample).
std::vector<std::uint64_t> arrived(const std::vector<Received5>& msgs, const std::string& vehicle,
                                   const std::string& leaf) {
  std::vector<std::uint64_t> out;
  for (const auto& m : msgs) {
    if (m.topic != "fleet/v1/" + vehicle + "/" + leaf) continue;
    v1::Envelope env;
    if (!env.ParseFromString(m.payload)) continue;
    if (env.has_telemetry()) {
      for (const auto& s : env.telemetry().samples()) out.push_back(s.sequence());
    } else {
      out.push_back(env.sequence());
    }
  }
  return out;
}

TEST(UplinkMqttRefusalLanes, ARefusedKindWaitsTheOthersFlowThenItArrivesExactlyOnce) {
  const std::string v = "bike-lanes";
  MosquittoOptions options;
  options.acl = acl_denying(v, {"alarm", "zone"});
  MosquittoBroker broker(options);
  broker.start();
  Subscriber5 sub(broker.uri(), "fleet/v1/" + v + "/#", "backend-lanes");

  MemoryOutbox box;
  const auto now = wall_now().count();
  std::vector<std::uint64_t> alarms, zones;
  for (int i = 0; i < 3; ++i)
    alarms.push_back(box.push(0, "alarm", now + i, alarm_payload(now + i)));
  zones.push_back(box.push(1, "zone", now, zone_payload("old-town")));
  UplinkConfig c = plain_config(broker.uri(), v);
  // The refused kinds' retries wait at least 1.5 s: long enough that "the other kinds arrived
  // before any retry" is a fact about the lanes, not about a fast machine.
  c.reconnect_min = 3s;
  c.reconnect_max = 6s;
  Uplink up(c, box);
  up.start(wall_now());
  ASSERT_TRUE(drive(
      up, [&] { return up.stats().refused_records == 4; }, 10s))
      << broker.log();
  const auto refusals = up.stats().publish_refusals;
  EXPECT_EQ(refusals, 4u);

  // Queued after the refusal: 40 telemetry samples and a fault, behind the refused alarms.
  std::vector<std::uint64_t> telemetry;
  for (std::uint32_t i = 0; i < 40; ++i) {
    telemetry.push_back(box.push(5, "telemetry", wall_now().count(), telemetry_payload(100 + i)));
  }
  const std::uint64_t fault = box.push(1, "fault", wall_now().count(), fault_payload(4));
  // One more alarm: it waits in its lane behind the refused ones (order within a kind).
  alarms.push_back(box.push(0, "alarm", wall_now().count(), alarm_payload(now + 10)));
  ASSERT_TRUE(drive(
      up, [&] { return box.acked_records() == 41; }, 10s))
      << "telemetry and the fault are held back by the refused alarms\n"
      << broker.log();
  // Nothing of the refused kinds was retried meanwhile: the others did not wait for a retry.
  EXPECT_EQ(up.stats().publish_refusals, refusals);
  EXPECT_EQ(box.stats().depth, 5u);
  EXPECT_EQ(up.stats().refused_records, 4u);
  ASSERT_TRUE(
      sub.wait_until([&](const auto& m) { return arrived(m, v, "telemetry").size() == 40; }, 5s));
  EXPECT_EQ(arrived(sub.messages(), v, "telemetry"), telemetry);
  EXPECT_EQ(arrived(sub.messages(), v, "fault"), std::vector<std::uint64_t>{fault});

  // Every refused kind is named, with its reason (this text is the Status's
  // last_publish_refusal and the `publishes REFUSED:` line of `fleetgw status`).
  const std::string why = up.stats().last_publish_refusal;
  EXPECT_NE(why.find("0x87 Not authorized (fleet/v1/" + v + "/alarm)"), std::string::npos) << why;
  EXPECT_NE(why.find("0x87 Not authorized (fleet/v1/" + v + "/zone)"), std::string::npos) << why;
  EXPECT_EQ(up.stats().last_publish_refusal_code, 0x87);
  ASSERT_TRUE(sub.wait_until(
      [&](const auto& m) {
        for (auto it = m.rbegin(); it != m.rend(); ++it) {
          v1::Envelope env;
          if (env.ParseFromString(it->payload) && env.has_status()) {
            return env.status().last_publish_refusal() == why;
          }
        }
        return false;
      },
      5s))
      << "the retained Status names both refused kinds";

  // The operator fixes the ACL and restarts the broker.
  broker.stop();
  std::ofstream(broker.directory() / "acl") << acl_denying(v, {});
  broker.start();
  Subscriber5 after(broker.uri(), "fleet/v1/" + v + "/#", "backend-lanes-after");
  ASSERT_TRUE(drive(
      up, [&] { return box.stats().depth == 0; }, 20s))
      << broker.log();
  // A marker behind them: once it arrived, a duplicate would have too.
  const std::uint64_t marker = box.push(0, "alarm", wall_now().count(), alarm_payload(now + 20));
  ASSERT_TRUE(drive(
      up, [&] { return box.stats().depth == 0; }, 10s));
  ASSERT_TRUE(after.wait_until(
      [&](const auto& m) {
        const auto a = arrived(m, v, "alarm");
        return std::find(a.begin(), a.end(), marker) != a.end();
      },
      5s));
  auto expected = alarms;
  expected.push_back(marker);
  EXPECT_EQ(arrived(after.messages(), v, "alarm"), expected) << "each once, in order";
  EXPECT_EQ(arrived(after.messages(), v, "zone"), zones);
  EXPECT_TRUE(arrived(sub.messages(), v, "alarm").empty());
  EXPECT_EQ(up.stats().last_publish_refusal, "");
  EXPECT_EQ(up.stats().refused_records, 0u);
  up.stop(wall_now());
}

// Within a refused kind the order holds across retries: a refused telemetry lane releases its
// pending batch, so no sample overtakes the refused ones.
TEST(UplinkMqttRefusalLanes, ARefusedTelemetryLaneKeepsItsOrderAndLetsAlarmsThrough) {
  const std::string v = "bike-lanes-tm";
  MosquittoOptions options;
  options.acl = acl_denying(v, {"telemetry"});
  MosquittoBroker broker(options);
  broker.start();
  Subscriber5 sub(broker.uri(), "fleet/v1/" + v + "/#", "backend-lanes-tm");
  MemoryOutbox box;
  std::vector<std::uint64_t> telemetry;
  for (std::uint32_t i = 0; i < 30; ++i) {
    telemetry.push_back(box.push(5, "telemetry", wall_now().count(), telemetry_payload(i)));
  }
  UplinkConfig c = plain_config(broker.uri(), v);
  c.reconnect_min = 200ms;
  c.reconnect_max = 400ms;
  Uplink up(c, box);
  up.start(wall_now());
  ASSERT_TRUE(drive(
      up, [&] { return up.stats().publish_refusals >= 1; }, 10s))
      << broker.log();
  const std::uint64_t alarm = box.push(0, "alarm", wall_now().count(), alarm_payload(1));
  ASSERT_TRUE(drive(
      up, [&] { return box.acked_records() == 1; }, 10s));
  ASSERT_TRUE(sub.wait_until(
      [&](const auto& m) { return arrived(m, v, "alarm") == std::vector<std::uint64_t>{alarm}; },
      5s));
  EXPECT_NE(up.stats().last_publish_refusal.find("/telemetry)"), std::string::npos);

  broker.stop();
  std::ofstream(broker.directory() / "acl") << acl_denying(v, {});
  broker.start();
  Subscriber5 after(broker.uri(), "fleet/v1/" + v + "/#", "backend-lanes-tm-after");
  ASSERT_TRUE(drive(
      up, [&] { return box.stats().depth == 0; }, 20s))
      << broker.log();
  ASSERT_TRUE(after.wait_until(
      [&](const auto& m) { return arrived(m, v, "telemetry").size() >= telemetry.size(); }, 5s));
  EXPECT_EQ(arrived(after.messages(), v, "telemetry"), telemetry);
  up.stop(wall_now());
}

}  // namespace
}  // namespace fleetgw::uplink
