// Node behaviour against a scripted gateway: read requests, writes, locks, start-up handshake,
// shutdown.

#include <gtest/gtest.h>

#include "gateway/sim/bike.h"
#include "sim_test_util.h"

namespace fleetgw::sim {
namespace {

using motinova::Mode;
using testing::attach;
using testing::bundled;
using testing::Message;
using testing::Probe;
using testing::ScriptedGateway;
using testing::seconds;

struct Harness {
  explicit Harness(Scenario s) : scenario(std::move(s)), bus(scenario), gateway(bus) {
    attach(bus, probe);
  }
  Micros t(double s) const { return scenario.start + seconds(s); }
  Scenario scenario;
  VirtualBus bus;
  Probe probe;
  ScriptedGateway gateway;
};

Scenario parked() {
  return bundled("parked");
}

RideSegment cruise(double seconds, double kmh) {
  RideSegment seg;
  seg.duration_s = seconds;
  seg.speed_kmh = kmh;
  return seg;
}

// Lock states broadcast by one lock between two times, consecutive duplicates removed.
std::vector<std::pair<Micros, int64_t>> lock_states(const Probe& p, uint16_t id, Micros from,
                                                    Micros to) {
  std::vector<std::pair<Micros, int64_t>> out;
  for (const Message* m : p.on(id, 0x10)) {
    if (m->ts < from || m->ts > to) continue;
    const int64_t s = *p.decode(*m).raw("state");
    if (out.empty() || out.back().second != s) out.emplace_back(m->ts, s);
  }
  return out;
}

struct ReadCase {
  uint16_t request_id;
  uint8_t request_function;
  uint16_t answer_id;
  uint8_t answer_function;
  const char* answer_name;
};

class ReadRequest : public ::testing::TestWithParam<ReadCase> {};

TEST_P(ReadRequest, AnsweredWithinOneSecond) {
  const ReadCase c = GetParam();
  Harness h(parked());
  const Micros asked = h.t(12.345);
  h.gateway.at(asked, ScriptedGateway::read(c.request_id, c.request_function));
  h.bus.run_until(h.t(14));
  // The reply comes a few ms after the request (a periodic copy cannot fake it: it is the first
  // one after the request and within 50 ms).
  const Message* answer = h.probe.first(c.answer_id, c.answer_function, asked, asked + seconds(1));
  ASSERT_NE(answer, nullptr);
  EXPECT_EQ(answer->name, c.answer_name);
  EXPECT_TRUE(answer->catalogued);
  EXPECT_LT(answer->ts - asked, Micros(50'000));
}

INSTANTIATE_TEST_SUITE_P(Sim, ReadRequest,
                         ::testing::Values(ReadCase{0x761, 0x33, 0x713, 0x54, "mc_settings"},
                                           ReadCase{0x761, 0x35, 0x710, 0x15, "mc_odometer"},
                                           ReadCase{0x761, 0x39, 0x713, 0x55, "mc_params2"},
                                           ReadCase{0x761, 0x43, 0x713, 0x56, "mc_assist_tuning"},
                                           ReadCase{0x731, 0x41, 0x713, 0x55, "mc_params2"},
                                           ReadCase{0x762, 0x50, 0x720, 0x10, "bms_status"},
                                           ReadCase{0x762, 0x51, 0x720, 0x11, "bms_cells"},
                                           ReadCase{0x762, 0x51, 0x720, 0x15, "device_info"},
                                           ReadCase{0x762, 0x52, 0x720, 0x12, "bms_faults"},
                                           ReadCase{0x762, 0x53, 0x720, 0x14, "bms_nameplate"},
                                           ReadCase{0x762, 0x54, 0x720, 0x18, "bms_temps"},
                                           ReadCase{0x762, 0x54, 0x725, 0x50, "pack_stats"},
                                           ReadCase{0x752, 0x33, 0x725, 0x50, "pack_stats"},
                                           ReadCase{0x763, 0x70, 0x730, 0x11, "device_info"},
                                           ReadCase{0x767, 0x80, 0x770, 0x12, "device_info"},
                                           ReadCase{0x767, 0x81, 0x770, 0x10, "lock_status"},
                                           ReadCase{0x76A, 0xB0, 0x7A0, 0x12, "device_info"},
                                           ReadCase{0x76B, 0xC1, 0x7B0, 0x10, "lock_status"}));

TEST(Sim, PackStatsOnlyOnRequest) {
  Harness h(parked());
  h.bus.run_until(h.t(30));
  EXPECT_TRUE(h.probe.on(0x725, 0x50).empty());
  EXPECT_TRUE(h.probe.on(0x713, 0x54).empty());
}

TEST(Sim, LockModelInfoCarriesPerLockSerial) {
  Harness h(parked());
  h.gateway.at(h.t(5), ScriptedGateway::read(0x769, 0xA0));
  h.bus.run_until(h.t(6));
  const Message* info = h.probe.first(0x790, 0x12, h.t(5));
  ASSERT_NE(info, nullptr);
  const auto d = h.probe.decode(*info);
  EXPECT_EQ(d.text("model"), "MNV-LK2");
  EXPECT_EQ(d.text("serial"), "LK2405-3");
  EXPECT_EQ(d.text("fw"), "V1.2.0_20231005");
}

TEST(Sim, StartupHandshake) {
  Harness h(parked());
  h.bus.run_until(h.t(1));
  const Message* hs_bms = h.probe.first(0x712, 0x30, h.t(-1));
  const Message* hs_obc = h.probe.first(0x713, 0x50, h.t(-1));
  ASSERT_NE(hs_bms, nullptr);
  ASSERT_NE(hs_obc, nullptr);
  EXPECT_EQ(hs_bms->frame.mode, Mode::kRead);  // the MC's HANDSHAKE is a read with data
  EXPECT_EQ(hs_bms->name, "handshake");
  const Message* bms_ready = h.probe.first(0x721, 0x30, hs_bms->ts);
  const Message* obc_ready = h.probe.first(0x731, 0x31, hs_obc->ts);
  ASSERT_NE(bms_ready, nullptr);
  ASSERT_NE(obc_ready, nullptr);
  EXPECT_EQ(bms_ready->name, "ready");
  EXPECT_LT(bms_ready->ts - hs_bms->ts, Micros(50'000));
  EXPECT_LT(obc_ready->ts - hs_obc->ts, Micros(50'000));
  const BikeState st = h.bus.bike().state();
  EXPECT_TRUE(st.bms_handshake_ok);
  EXPECT_TRUE(st.obc_handshake_ok);
  EXPECT_EQ(st.mc_faults, 0u);
  // Exactly one handshake each: no retries when answered.
  EXPECT_EQ(h.probe.on(0x712, 0x30).size(), 1u);
}

TEST(Sim, MissingBmsAnswerRaisesBmsCheckFault) {
  Scenario s = parked();
  s.events.push_back(
      {.at = Micros(0), .action = Action::kSilenceNode, .node = motinova::Node::kBms});
  Harness h(s);
  h.bus.run_until(h.t(3));
  EXPECT_GE(h.probe.on(0x712, 0x30).size(), 3u);  // retried
  EXPECT_TRUE(h.probe.on(0x721, 0x30).empty());
  const auto faults = h.probe.on(0x710, 0x11);
  ASSERT_FALSE(faults.empty());
  EXPECT_EQ(*h.probe.decode(*faults.back()).raw("raw"), 0x0400);  // BMS check fault
  // The OBC answered: only the BMS check failed.
  EXPECT_TRUE(h.bus.bike().state().obc_handshake_ok);
  EXPECT_FALSE(h.bus.bike().state().bms_handshake_ok);
}

TEST(Sim, IotShutdownGetsReadyFromMcAndObcThenPowerGoes) {
  Harness h(parked());
  h.gateway.at(h.t(10), ScriptedGateway::write(0x760, 0x10, "SHUTDOWN", Mode::kReport));
  h.bus.run_until(h.t(20));
  const Message* mc_ready = h.probe.first(0x710, 0x13, h.t(10), h.t(11));
  const Message* obc_ready = h.probe.first(0x730, 0x14, h.t(10), h.t(11));
  ASSERT_NE(mc_ready, nullptr);
  ASSERT_NE(obc_ready, nullptr);
  EXPECT_EQ(mc_ready->name, "ready");
  // The IOT cuts ACC ~1 s later: the bus goes quiet.
  std::size_t after_off = 0;
  for (const Message& m : h.probe.messages) after_off += m.ts > h.t(11.5) ? 1 : 0;
  EXPECT_EQ(after_off, 0u);
  EXPECT_FALSE(h.bus.bike().state().powered);
  // ACC on again: the MC boots and handshakes.
  h.bus.bike().set_acc(true, h.t(20));
  h.bus.run_until(h.t(22));
  EXPECT_NE(h.probe.first(0x712, 0x30, h.t(20)), nullptr);
  EXPECT_NE(h.probe.first(0x721, 0x30, h.t(20)), nullptr);
}

TEST(Sim, ObcPowerKeyShutdown) {
  Scenario s = parked();
  s.events.push_back({.at = seconds(30), .action = Action::kPowerOff});
  Harness h(s);
  h.bus.run_until(h.t(40));
  const Message* shutdown = h.probe.first(0x730, 0x10, h.t(29));
  ASSERT_NE(shutdown, nullptr);
  EXPECT_EQ(shutdown->name, "shutdown");
  const Message* mc_ready = h.probe.first(0x710, 0x13, shutdown->ts, shutdown->ts + seconds(1));
  ASSERT_NE(mc_ready, nullptr);
  EXPECT_EQ(h.probe.first(0x730, 0x14, h.t(29)), nullptr);  // the initiator does not answer itself
  EXPECT_FALSE(h.bus.bike().state().powered);
}

TEST(Sim, BmsAutoOff) {
  Scenario s = parked();
  s.events.push_back({.at = seconds(30), .action = Action::kBmsAutoOff});
  Harness h(s);
  h.bus.run_until(h.t(40));
  const Message* shutdown = h.probe.first(0x720, 0x13, h.t(29));
  ASSERT_NE(shutdown, nullptr);
  EXPECT_NE(h.probe.first(0x710, 0x13, shutdown->ts, shutdown->ts + seconds(1)), nullptr);
  EXPECT_NE(h.probe.first(0x730, 0x14, shutdown->ts, shutdown->ts + seconds(1)), nullptr);
  EXPECT_FALSE(h.bus.bike().state().powered);
}

TEST(Sim, IotShutdownOfObcOnly) {
  Harness h(parked());
  h.gateway.at(h.t(10), ScriptedGateway::write(0x763, 0x70, "SHUTDOWN"));
  h.bus.run_until(h.t(20));
  EXPECT_NE(h.probe.first(0x730, 0x14, h.t(10), h.t(11)), nullptr);
  EXPECT_EQ(h.probe.first(0x730, 0x15, h.t(12)), nullptr);  // OBC gone
  EXPECT_NE(h.probe.first(0x710, 0x10, h.t(12)), nullptr);  // MC still there
}

TEST(Sim, UnlockGoesThroughUnlockingWithDelay) {
  Harness h(parked());
  h.gateway.at(h.t(5), ScriptedGateway::write(0x767, 0x83, "UNLOCK"));
  h.gateway.at(h.t(10), ScriptedGateway::write(0x767, 0x82, "LOCK"));
  h.bus.run_until(h.t(12));
  const auto states = lock_states(h.probe, 0x770, h.t(0), h.t(12));
  ASSERT_EQ(states.size(), 5u) << "expected locked, unlocking, unlocked, locking, locked";
  EXPECT_EQ(states[0].second, 2);
  EXPECT_EQ(states[1].second, 3);
  EXPECT_EQ(states[2].second, 1);
  EXPECT_EQ(states[3].second, 4);
  EXPECT_EQ(states[4].second, 2);
  EXPECT_LT(states[1].first - h.t(5), Micros(50'000));  // starts moving at once
  const Micros travel = states[2].first - states[1].first;
  EXPECT_GE(travel, Micros(300'000));
  EXPECT_LE(travel, Micros(800'000));
  EXPECT_EQ(h.bus.bike().state().lock_states[0], LockState::kLocked);
  // The other locks did not move.
  EXPECT_EQ(h.bus.bike().state().lock_states[1], LockState::kLocked);
}

TEST(Sim, Lock4ReportsMotorRpmWhileMoving) {
  Harness h(parked());
  h.gateway.at(h.t(5), ScriptedGateway::write(0x76A, 0xB3, "UNLOCK"));
  h.bus.run_until(h.t(7));
  bool saw_rpm = false;
  for (const Message* m : h.probe.on(0x7A0, 0x10)) {
    const auto d = h.probe.decode(*m);
    if (*d.raw("state") == 3) {
      EXPECT_GT(*d.number("motor_rpm"), 0);
      EXPECT_GT(*d.number("current_a"), 0.1);
      saw_rpm = true;
    } else {
      EXPECT_EQ(*d.number("motor_rpm"), 0);
    }
  }
  EXPECT_TRUE(saw_rpm);
}

TEST(Sim, JammedLockReportsUnlockFailed) {
  Harness h(bundled("faults"));
  h.bus.run_until(h.t(12));
  const auto states = lock_states(h.probe, 0x770, h.t(0), h.t(12));
  ASSERT_EQ(states.size(), 3u);
  EXPECT_EQ(states[1].second, 3);  // unlocking
  EXPECT_EQ(states[2].second, 5);  // unlock failed
  EXPECT_GE(states[2].first - states[1].first, Micros(1'900'000));
  const auto faults = h.probe.on(0x770, 0x11);
  ASSERT_FALSE(faults.empty());
  EXPECT_EQ(*h.probe.decode(*faults.back()).raw("raw"), 0x0040);
  // Faulty: fault word every 200 ms.
  const auto n = std::count_if(faults.begin(), faults.end(), [&](const Message* m) {
    return m->ts > h.t(9) && m->ts <= h.t(11);
  });
  EXPECT_GE(n, 9);
}

TEST(Sim, SilentLockNeverAnswers) {
  Scenario s = bundled("faults");
  Harness h(s);
  h.gateway.at(h.t(20), ScriptedGateway::read(0x769, 0xA1));
  h.gateway.at(h.t(21), ScriptedGateway::write(0x769, 0xA3, "UNLOCK"));
  h.gateway.at(h.t(22), ScriptedGateway::read(0x769, 0xA0));
  h.bus.run_until(h.t(60));
  for (const Message& m : h.probe.messages) {
    EXPECT_NE(motinova::source_of(m.frame.can_id), motinova::Node::kLock3) << m.name;
  }
  EXPECT_FALSE(h.probe.on(0x7A0, 0x10).empty());  // the others talk
}

TEST(Sim, McFaultRaisedAndClearedOnTime) {
  Harness h(bundled("faults"));
  h.bus.run_until(h.t(340));
  const auto faults = h.probe.on(0x710, 0x11);
  const Message* raised = nullptr;
  const Message* cleared = nullptr;
  for (const Message* m : faults) {
    const int64_t w = *h.probe.decode(*m).raw("raw");
    if (!raised && w == 0x10) raised = m;
    if (raised && !cleared && w == 0) cleared = m;
  }
  ASSERT_NE(raised, nullptr);
  ASSERT_NE(cleared, nullptr);
  EXPECT_NEAR(static_cast<double>((raised->ts - h.t(240)).count()), 0, 10'000);  // at once
  EXPECT_NEAR(static_cast<double>((cleared->ts - h.t(330)).count()), 0, 10'000);
  // Over-heat stops the assist.
  for (const Message* m : h.probe.on(0x710, 0x10)) {
    if (m->ts > h.t(241) && m->ts < h.t(329)) {
      EXPECT_EQ(*h.probe.decode(*m).number("power_w"), 0);
    }
  }
}

TEST(Sim, WritesTakeEffect) {
  Scenario s = parked();
  s.vehicle_locked = false;
  s.ride = {cruise(120, 24)};
  Harness h(s);
  // Speed limit -13 (spec T13), read back, assist SPORT + light, then CLEAR.
  h.gateway.at(h.t(30), ScriptedGateway::write(0x761, 0x34, {0x00, 0x02, 0, 0, 0xF3, 0, 0, 0}));
  h.gateway.at(h.t(31), ScriptedGateway::read(0x761, 0x33));
  h.gateway.at(h.t(32), ScriptedGateway::write(0x761, 0x30, {0x03, 0xF1}));
  h.gateway.at(h.t(60), ScriptedGateway::write(0x761, 0x36, "CLEAR"));
  h.bus.run_until(h.t(62));

  const Message* settings = h.probe.first(0x713, 0x54, h.t(31));
  ASSERT_NE(settings, nullptr);
  EXPECT_EQ(*h.probe.decode(*settings).raw("speed_limit_offset_kmh"), -13);
  EXPECT_EQ(*h.probe.decode(*settings).raw("speed_limit_kmh"), 25);
  EXPECT_TRUE(h.probe.on(0x713, 0x53).empty());  // IOT writes are not ACKed (U26)

  double before = 0;
  for (const Message* m : h.probe.on(0x710, 0x10)) {
    const auto d = h.probe.decode(*m);
    if (m->ts > h.t(20) && m->ts < h.t(30)) before = std::max(before, *d.number("speed_kmh"));
    if (m->ts > h.t(45) && m->ts < h.t(60)) {
      EXPECT_LE(*d.number("speed_kmh"), 12.0 + 1e-9);
      EXPECT_EQ(*d.raw("assist"), 3);
      EXPECT_TRUE(*d.number("headlight"));
    }
    if (m->ts > h.t(60.5)) {
      EXPECT_LT(*d.number("trip_km"), 0.1);
    }
  }
  EXPECT_GT(before, 20);
}

// Scenario `mc_ignores_writes` (issue 13): the remote commands' `failed` path. Reads are still
// answered, so the gateway sees the unchanged state.
TEST(Sim, McThatIgnoresWritesStillAnswersReads) {
  Scenario s = parse_scenario("[bike]\nmc_ignores_writes = true\n", "ignore.toml");
  ASSERT_TRUE(s.mc_ignores_writes);
  s.vehicle_locked = false;
  Harness h(s);
  h.gateway.at(h.t(5), ScriptedGateway::write(0x761, 0x34, {0x00, 0x02, 0, 0, 0xF3, 0, 0, 0}));
  h.gateway.at(h.t(6), ScriptedGateway::read(0x761, 0x33));
  h.gateway.at(h.t(7), ScriptedGateway::write(0x761, 0x30, {0x03, 0xF1}));
  h.bus.run_until(h.t(9));
  const Message* settings = h.probe.first(0x713, 0x54, h.t(6));
  ASSERT_NE(settings, nullptr);
  EXPECT_EQ(*h.probe.decode(*settings).raw("speed_limit_offset_kmh"), 0);
  const Message* status = h.probe.first(0x710, 0x10, h.t(8));
  ASSERT_NE(status, nullptr);
  EXPECT_NE(*h.probe.decode(*status).raw("assist"), 3);
  EXPECT_FALSE(*h.probe.decode(*status).number("headlight"));
  EXPECT_EQ(h.bus.bike().state().speed_limit_offset_kmh, 0);
}

TEST(Sim, ObcWritesAreAcked) {
  Harness h(parked());
  h.gateway.at(h.t(5), ScriptedGateway::write(0x731, 0x36, "CLEAR"));
  h.bus.run_until(h.t(6));
  const Message* ack = h.probe.first(0x713, 0x53, h.t(5));
  ASSERT_NE(ack, nullptr);
  EXPECT_EQ(ack->name, "ack");
}

TEST(Sim, VehicleLockStopsAssist) {
  Scenario s = parked();
  s.vehicle_locked = false;
  s.ride = {cruise(100, 20)};
  Harness h(s);
  h.gateway.at(h.t(30), ScriptedGateway::write(0x760, 0x11, "LOCK", Mode::kReport));
  h.gateway.at(h.t(60), ScriptedGateway::write(0x760, 0x12, "UNLOCK", Mode::kReport));
  h.bus.run_until(h.t(90));
  double assisted_before = 0, assisted_locked = 0, assisted_after = 0;
  for (const Message* m : h.probe.on(0x710, 0x10)) {
    const double p = *h.probe.decode(*m).number("power_w");
    if (m->ts > h.t(15) && m->ts < h.t(30)) assisted_before = std::max(assisted_before, p);
    if (m->ts > h.t(30.2) && m->ts < h.t(60)) assisted_locked = std::max(assisted_locked, p);
    if (m->ts > h.t(61) && m->ts < h.t(90)) assisted_after = std::max(assisted_after, p);
  }
  EXPECT_GT(assisted_before, 20);
  EXPECT_EQ(assisted_locked, 0);
  EXPECT_GT(assisted_after, 20);
}

TEST(Sim, FaultWordPeriodsFollowTheRule) {
  Harness h(parked());
  h.bus.run_until(h.t(20));
  // All OK: ~1 s period.
  const auto obc = h.probe.on(0x730, 0x15);
  ASSERT_GE(obc.size(), 18u);
  EXPECT_LE(obc.size(), 22u);
}

TEST(Sim, GatewayFramesWithLittleEndianCrcAreUnderstood) {
  Harness h(parked());
  const motinova::AppFrame unlock = ScriptedGateway::write(0x767, 0x83, "UNLOCK");
  VirtualBus::Participant p;
  h.bus.add(std::move(p));
  for (const auto& can : motinova::segment(unlock, motinova::CrcOrder::kLittle)) {
    h.bus.send(can);
  }
  h.bus.run_until(h.t(3));
  EXPECT_EQ(h.bus.bike().state().lock_states[0], LockState::kUnlocked);
}

TEST(VirtualBusTest, SpinningParticipantIsAnError) {
  VirtualBus bus(parked());
  VirtualBus::Participant p;
  p.name = "stuck";
  p.tick = [](Micros) {};
  p.next_event = [] { return Micros(0); };  // always overdue, never advances
  bus.add(std::move(p));
  EXPECT_THROW(bus.run_for(seconds(1)), std::logic_error);
}

TEST(VirtualBusTest, ParticipantsSeeEachOther) {
  VirtualBus bus(parked());
  int a_seen = 0;
  int b_seen_from_a = 0;
  VirtualBus::ParticipantId a = 0;
  VirtualBus::Participant pa;
  pa.on_frame = [&](const motinova::CanFrame&, Micros) { ++a_seen; };
  a = bus.add(std::move(pa));
  VirtualBus::Participant pb;
  pb.on_frame = [&](const motinova::CanFrame& f, Micros) {
    b_seen_from_a += f.id == 0x7F1 ? 1 : 0;
  };
  bus.add(std::move(pb));
  motinova::CanFrame f;
  f.id = 0x7F1;
  f.len = 1;
  bus.send(f, a);
  bus.run_for(seconds(1));
  EXPECT_EQ(b_seen_from_a, 1);
  EXPECT_GT(a_seen, 0);
  EXPECT_EQ(bus.now(), bus.start() + seconds(1));
}

}  // namespace
}  // namespace fleetgw::sim
