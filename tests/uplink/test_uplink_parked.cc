// The uplink's side of parked mode and of the retained vehicle state (issue 13), against a real
// mosquitto, on a virtual timeline (the uplink reads no clock: every poll() takes `now`):
//  * one parked hour of telemetry (one sample a minute, the domain's parked sampling) leaves in
//    far fewer messages with the parked batch delay than with the riding one, every sample
//    delivered either way;
//  * set_vehicle_state() is published retained with QoS 1 and online = true, a late subscriber
//    gets it from the broker, and stop() replaces it with online = false.
#include <gtest/gtest.h>

#include <chrono>
#include <optional>
#include <string>

#include "fleetgw/v1/envelope.pb.h"
#include "gateway/uplink/memory_outbox.h"
#include "gateway/uplink/uplink.h"
#include "tests/support/mosquitto_fixture.h"
#include "tests/uplink/uplink_test_util.h"

namespace fleetgw::uplink {
namespace {

using fleetgw::testing::MosquittoBroker;
using fleetgw::testing::Subscriber;
using motinova::Micros;
using namespace std::chrono_literals;

// Polls at the virtual time `t` until nothing is in flight (or 2 s of real time passed).
void settle_at(Uplink& up, Micros t) {
  const auto deadline = std::chrono::steady_clock::now() + 2s;
  do {
    up.poll(t);
    if (up.stats().in_flight_messages == 0) return;
    up.wait_for_events(5ms);
  } while (std::chrono::steady_clock::now() < deadline);
}

struct HourFigures {
  std::size_t messages = 0;
  std::size_t samples = 0;
  std::size_t bytes = 0;
};

HourFigures parked_hour(const std::string& uri, std::optional<std::chrono::milliseconds> delay,
                        const std::string& vehicle) {
  Subscriber sub(uri, "fleet/v1/" + vehicle + "/telemetry", vehicle + "-backend");
  MemoryOutbox box;
  UplinkConfig c = fleetgw::testing::plain_config(uri, vehicle);
  c.telemetry_batch_max_delay = 5s;  // [mqtt] batch_max_ms default: the riding rate
  Uplink up(c, box);
  up.set_telemetry_batch_delay(delay);
  const Micros t0 = fleetgw::testing::wall_now();
  up.start(t0);
  EXPECT_TRUE(fleetgw::testing::drive(
      up, [&] { return up.state() == UplinkState::kConnected; }, 10s));
  for (int minute = 0; minute < 60; ++minute) {
    const Micros t = t0 + std::chrono::minutes(minute);
    box.push(5, kind::kTelemetry, t.count(), fleetgw::testing::telemetry_payload(0));
    for (int s = 0; s < 60; s += 10) settle_at(up, t + std::chrono::seconds(s));
  }
  settle_at(up, t0 + std::chrono::minutes(66));  // the last parked batch is due too
  HourFigures f;
  EXPECT_TRUE(sub.wait_until(
      [&](const auto& msgs) {
        std::size_t n = 0;
        for (const auto& m : msgs) {
          v1::Envelope e;
          if (e.ParseFromString(m.payload))
            n += static_cast<std::size_t>(e.telemetry().samples_size());
        }
        return n >= 60;
      },
      10s));
  for (const auto& m : sub.messages()) {
    v1::Envelope e;
    EXPECT_TRUE(e.ParseFromString(m.payload));
    ++f.messages;
    f.samples += static_cast<std::size_t>(e.telemetry().samples_size());
    f.bytes += m.payload.size();
  }
  up.stop(t0 + std::chrono::minutes(67));
  return f;
}

TEST(UplinkParked, AParkedHourOfTelemetryLeavesInFewerMessagesAndNoSampleIsLost) {
  MosquittoBroker broker;
  broker.start();
  const HourFigures riding = parked_hour(broker.uri(), std::nullopt, "parked-riding-rate");
  const HourFigures parked = parked_hour(broker.uri(), 300'000ms, "parked-parked-rate");
  std::printf(
      "one parked hour of telemetry: %zu messages / %zu payload bytes at the riding "
      "batch delay, %zu / %zu at the parked one\n",
      riding.messages, riding.bytes, parked.messages, parked.bytes);
  EXPECT_EQ(riding.samples, 60u);
  EXPECT_EQ(parked.samples, 60u);
  EXPECT_EQ(riding.messages, 60u) << "one batch per sample at 5 s";
  EXPECT_LE(parked.messages, 13u) << "one batch per 5 minutes";
  EXPECT_LT(parked.bytes, riding.bytes);
}

TEST(UplinkParked, VehicleStateIsRetainedOnlineAndStopMakesItOffline) {
  MosquittoBroker broker;
  broker.start();
  MemoryOutbox box;
  const std::string vehicle = "state-unit-1";
  Uplink up(fleetgw::testing::plain_config(broker.uri(), vehicle), box);
  up.start(fleetgw::testing::wall_now());
  ASSERT_TRUE(fleetgw::testing::drive(
      up, [&] { return up.state() == UplinkState::kConnected; }, 10s));
  v1::VehicleState s;
  s.set_soc_pct(57);
  s.set_mode(v1::VEHICLE_MODE_PARKED);
  up.set_vehicle_state(s.SerializeAsString());
  ASSERT_TRUE(fleetgw::testing::drive(
      up, [&] { return up.stats().acked_messages >= 2; }, 10s));  // status + state
  const std::string topic = "fleet/v1/" + vehicle + "/state";
  auto state_of = [&](const std::vector<fleetgw::testing::Received>& msgs,
                      bool online) -> const fleetgw::testing::Received* {
    for (const auto& m : msgs) {
      v1::Envelope e;
      if (m.topic == topic && e.ParseFromString(m.payload) && e.has_state() &&
          e.state().online() == online)
        return &m;
    }
    return nullptr;
  };
  {
    Subscriber late(broker.uri(), topic, "state-late");
    ASSERT_TRUE(late.wait_until([&](const auto& m) { return state_of(m, true) != nullptr; }, 10s));
    const auto msgs = late.messages();
    const auto* m = state_of(msgs, true);
    EXPECT_TRUE(m->retained);
    EXPECT_EQ(m->qos, 1);
    v1::Envelope e;
    ASSERT_TRUE(e.ParseFromString(m->payload));
    EXPECT_EQ(e.state().soc_pct(), 57u);
    EXPECT_EQ(e.vehicle_id(), vehicle);
    EXPECT_EQ(e.sequence(), 0u) << "not an outbox record";
  }
  up.stop(fleetgw::testing::wall_now());
  Subscriber after(broker.uri(), topic, "state-after");
  ASSERT_TRUE(after.wait_until([&](const auto& m) { return !m.empty(); }, 10s));
  const auto msgs = after.messages();
  ASSERT_NE(state_of(msgs, false), nullptr) << "the clean stop said offline";
  EXPECT_EQ(state_of(msgs, true), nullptr);
}

}  // namespace
}  // namespace fleetgw::uplink
