// The IoT node's behaviour (spec Appendix A, §3.7-3.8) checked end to end: the real GatewayCore
// (configured from TOML text through config::parse_config, so the defaults are the shipped ones)
// runs in lockstep with the simulated bike on the VirtualBus, and every assertion is made on what
// actually went over the bus or on the node's registry.
#include <gtest/gtest.h>

#include <algorithm>
#include <optional>

#include "runtime_test_util.h"

namespace fleetgw::runtime::testing {
namespace {

using motinova::Node;

constexpr uint16_t kIotId = 0x760;

// Observer recording the registry's transitions.
struct Transitions final : node::RegistryObserver {
  struct Entry {
    Node node;
    bool online;
    Micros at;
  };
  struct FaultChange {
    Node node;
    node::FaultWordState before, after;
    Micros at;
  };
  void on_node_online(Node n, Micros now) override { log.push_back({n, true, now}); }
  void on_node_offline(Node n, Micros, Micros now) override { log.push_back({n, false, now}); }
  void on_fault_word(Node n, const node::FaultWordState& before, const node::FaultWordState& after,
                     Micros now) override {
    faults.push_back({n, before, after, now});
  }
  std::vector<Entry> of(Node n) const {
    std::vector<Entry> out;
    for (const auto& e : log) {
      if (e.node == n) out.push_back(e);
    }
    return out;
  }
  std::vector<Entry> log;
  std::vector<FaultChange> faults;
};

Node source_node(uint16_t can_id) {
  return static_cast<Node>((can_id >> 4) & 0xF);
}

// Last valid application frame from `node` at or before `until`.
std::optional<Micros> last_heard(const BusProbe& probe, Node node, Micros until) {
  std::optional<Micros> t;
  for (const auto& m : probe.messages) {
    if (m.ts > until) break;
    if (source_node(m.frame.can_id) == node) t = m.ts;
  }
  return t;
}

std::optional<Micros> first_heard_after(const BusProbe& probe, Node node, Micros after) {
  for (const auto& m : probe.messages) {
    if (m.ts > after && source_node(m.frame.can_id) == node) return m.ts;
  }
  return std::nullopt;
}

std::vector<const BusMessage*> sent_on(const SimHarness& h, uint16_t id, uint8_t function) {
  std::vector<const BusMessage*> out;
  for (const auto& m : h.sent) {
    if (m.frame.can_id == id && m.frame.function == function) out.push_back(&m);
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// Model info at start-up

TEST(NodeOnSim, ModelInfoOfEveryNodeIsInTheRegistryAfterStartUp) {
  const sim::Scenario scenario = bundled("ride");
  SimHarness h(scenario, make_config());
  h.start();
  h.run_until(h.at(6));  // MC model info is broadcast every 5 s (it has no read in V4.6.2)

  const auto& reg = h.core.node().registry();
  const auto expect = [&](Node n, const sim::DeviceStrings& d, const std::string& serial) {
    const auto& s = reg.node(n);
    ASSERT_TRUE(s.model.has_value()) << motinova::node_name(n);
    EXPECT_EQ(s.model->model, d.model) << motinova::node_name(n);
    EXPECT_EQ(s.model->serial, serial) << motinova::node_name(n);
    EXPECT_EQ(s.model->hw, d.hw) << motinova::node_name(n);
    EXPECT_EQ(s.model->fw, d.fw) << motinova::node_name(n);
  };
  expect(Node::kMc, scenario.mc, scenario.mc.serial);
  expect(Node::kBms, scenario.bms, scenario.bms.serial);
  expect(Node::kObc, scenario.obc, scenario.obc.serial);
  for (int k = 0; k < 5; ++k) {
    expect(static_cast<Node>(7 + k), scenario.lock,
           scenario.lock.serial + "-" + std::to_string(k + 1));
  }

  // Where a read exists it is sent at start-up (not left to chance broadcasts): OBC 0x763/0x70,
  // BMS 0x762/0x51, every lock 0x767+k/F. Lock model info is only ever sent in answer to that
  // read, so its presence above proves the reads reached the bike and were matched.
  const Micros start = h.t0();
  const auto read_at_start = [&](uint16_t id, uint8_t fn) {
    const auto reads = sent_on(h, id, fn);
    ASSERT_FALSE(reads.empty()) << std::hex << id << "/" << int(fn);
    EXPECT_EQ(reads.front()->frame.mode, motinova::Mode::kRead);
    EXPECT_LE(reads.front()->ts - start, ms(100)) << std::hex << id << "/" << int(fn);
  };
  read_at_start(0x763, 0x70);
  read_at_start(0x762, 0x51);
  for (int k = 0; k < 5; ++k) {
    read_at_start(static_cast<uint16_t>(0x767 + k), static_cast<uint8_t>(0x80 + 0x10 * k));
  }
  // The lock answers arrive within the spec's 1 s answer window.
  for (int k = 0; k < 5; ++k) {
    const auto* info = h.probe.first(static_cast<uint16_t>(0x770 + 0x10 * k), 0x12, start);
    ASSERT_NE(info, nullptr) << "lock " << k + 1;
    EXPECT_LT(info->ts - start, sec(1)) << "lock " << k + 1;
  }
}

// ---------------------------------------------------------------------------------------------
// READY on another node's SHUTDOWN (§3.8.2)

void expect_ready_after_shutdown(const std::string& action, uint16_t shutdown_id,
                                 uint8_t shutdown_fn) {
  const std::string toml =
      "[scenario]\nname = \"shutdown\"\nduration_s = 20\n"
      "[[ride]]\nduration_s = 15\nspeed_kmh = 15\n"
      "[[event]]\nat_s = 8\naction = \"" +
      action + "\"\n";
  SimHarness h(sim::parse_scenario(toml, "shutdown.toml"), make_config());
  h.start();
  h.run_until(h.at(12));

  const auto shutdowns = h.probe.on(shutdown_id, shutdown_fn);
  ASSERT_EQ(shutdowns.size(), 1u) << action;
  const Micros t = shutdowns.front()->ts;
  EXPECT_GE(t, h.at(8));

  const auto readies = h.probe.on(kIotId, 0x14);
  ASSERT_FALSE(readies.empty()) << "no READY 0x760/0x1405 on the bus after " << action;
  // Nothing before the SHUTDOWN, the first one within 200 ms of it.
  EXPECT_GE(readies.front()->ts, t);
  EXPECT_LE(readies.front()->ts - t, ms(200));
  EXPECT_EQ(std::string(readies.front()->frame.data.begin(), readies.front()->frame.data.end()),
            "READY");
  EXPECT_EQ(readies.front()->frame.mode, motinova::Mode::kReport);
  // Events are repeated (U12) but not forever: the configured 3 copies.
  EXPECT_EQ(readies.size(), 3u);
}

TEST(NodeOnSim, ReadyAnsweredWithin200msOfObcShutdown) {
  expect_ready_after_shutdown("power_off", 0x730, 0x10);
}

TEST(NodeOnSim, ReadyAnsweredWithin200msOfBmsShutdown) {
  expect_ready_after_shutdown("bms_auto_off", 0x720, 0x13);
}

TEST(NodeOnSim, NoReadyWithoutAShutdown) {
  SimHarness h(bundled("parked"), make_config());
  h.start();
  h.run_until(h.at(30));
  EXPECT_TRUE(h.probe.on(kIotId, 0x14).empty());
  EXPECT_FALSE(h.probe.messages.empty());
}

// ---------------------------------------------------------------------------------------------
// Offline / online and stale fault words (bus-trouble: the OBC is silent from 120 s for 30 s)

TEST(NodeOnSim, SilentNodeMarkedOfflineAfterConfiguredTimeoutAndOnlineWhenBack) {
  const int timeout_ms = 2500;  // not the default, so the test proves the config is applied
  SimHarness h(bundled("bus-trouble"),
               make_config("[node]\noffline_timeout_ms = " + std::to_string(timeout_ms) + "\n"));
  Transitions tr;
  h.core.node().registry().add_observer(tr);
  h.start();
  h.run_until(h.at(160));
  h.core.node().registry().remove_observer(tr);

  const auto obc_last = last_heard(h.probe, Node::kObc, h.at(120.5));
  const auto obc_back = first_heard_after(h.probe, Node::kObc, h.at(120.5));
  ASSERT_TRUE(obc_last && obc_back);
  ASSERT_GE(*obc_back, h.at(150)) << "the scenario silences the OBC until 150 s";

  const auto obc = tr.of(Node::kObc);
  std::vector<Transitions::Entry> in_window;
  for (const auto& e : obc) {
    if (e.at > h.at(100)) in_window.push_back(e);
  }
  ASSERT_EQ(in_window.size(), 2u) << "exactly one offline and one online transition";
  EXPECT_FALSE(in_window[0].online);
  EXPECT_GE(in_window[0].at - *obc_last, ms(timeout_ms));
  EXPECT_LE(in_window[0].at - *obc_last, ms(timeout_ms) + GatewayCore::kTickInterval);
  EXPECT_TRUE(in_window[1].online);
  EXPECT_EQ(in_window[1].at, *obc_back) << "online again on its first frame";

  // Nodes that kept talking never went offline (no spurious transitions from the OBC's gap).
  for (Node n : {Node::kMc, Node::kBms}) {
    for (const auto& e : tr.of(n)) EXPECT_TRUE(e.online) << motinova::node_name(n);
  }
  // When it came back its model info was read again (it could be a swapped unit).
  bool reread = false;
  for (const auto* m : sent_on(h, 0x763, 0x70)) reread |= m->ts >= *obc_back;
  EXPECT_TRUE(reread);
}

TEST(NodeOnSim, StaleFaultWordIsUnknownNotOk) {
  SimHarness h(bundled("bus-trouble"), make_config());
  Transitions tr;
  h.core.node().registry().add_observer(tr);
  h.start();
  h.run_until(h.at(120.5));
  const auto& reg = h.core.node().registry();

  std::optional<Micros> last_word;
  for (const auto* m : h.probe.on(0x730, 0x15)) last_word = m->ts;
  ASSERT_TRUE(last_word);
  ASSERT_GT(*last_word, h.at(118));
  EXPECT_EQ(reg.fault_word(Node::kObc, h.bus.now()).state, node::FaultState::kOk);

  // Still OK just before the configured 2 s, unknown (never OK) after it.
  h.run_until(*last_word + ms(1900));
  EXPECT_EQ(reg.fault_word(Node::kObc, h.bus.now()).state, node::FaultState::kOk);
  h.run_until(*last_word + ms(2100));
  const auto stale = reg.fault_word(Node::kObc, h.bus.now());
  EXPECT_EQ(stale.state, node::FaultState::kUnknown);
  ASSERT_TRUE(stale.raw.has_value()) << "the last raw word is kept for context";
  EXPECT_EQ(*stale.raw, 0u);

  // Observers were told, at the tick after the 2 s passed.
  const auto it = std::find_if(tr.faults.begin(), tr.faults.end(), [](const auto& c) {
    return c.node == Node::kObc && c.after.state == node::FaultState::kUnknown;
  });
  ASSERT_NE(it, tr.faults.end());
  EXPECT_EQ(it->before.state, node::FaultState::kOk);
  EXPECT_GE(it->at - *last_word, ms(2000));
  EXPECT_LE(it->at - *last_word, ms(2000) + GatewayCore::kTickInterval);

  // The live OBC word comes back as OK once the node talks again.
  h.run_until(h.at(155));
  EXPECT_EQ(reg.fault_word(Node::kObc, h.bus.now()).state, node::FaultState::kOk);
  h.core.node().registry().remove_observer(tr);
}

TEST(NodeOnSim, NeverHeardFaultWordIsUnknownAndRealFaultsAreFaulty) {
  // faults.toml: lock 3 is dead from the start, lock 1 is jammed (stall bit after the failed
  // unlock at 5 s), lock 2 is healthy.
  SimHarness h(bundled("faults"), make_config());
  h.start();
  h.run_until(h.at(15));
  const auto& reg = h.core.node().registry();
  const Micros now = h.bus.now();
  EXPECT_EQ(reg.fault_word(Node::kLock3, now).state, node::FaultState::kUnknown);
  EXPECT_FALSE(reg.node(Node::kLock3).present);
  EXPECT_EQ(reg.fault_word(Node::kLock1, now).state, node::FaultState::kFaulty);
  EXPECT_EQ(reg.fault_word(Node::kLock2, now).state, node::FaultState::kOk);
  EXPECT_EQ(reg.fault_word(Node::kMc, now).state, node::FaultState::kOk);
}

// ---------------------------------------------------------------------------------------------
// Polling: retries every 200 ms, gives up after 1 s (§3.7), against the silent lock 3

TEST(NodeOnSim, PollingRetriesEvery200msAndTimesOutAfter1sAgainstSilentLock) {
  SimHarness h(bundled("faults"), make_config());
  std::vector<node::PollResult> results;
  h.core.node().set_poll_result_callback([&](const node::PollResult& r) { results.push_back(r); });
  h.start();
  h.run_until(h.at(12));

  constexpr uint16_t kLock3 = 0x769;  // node 9: F = 0xA0
  std::vector<const BusMessage*> reqs;
  for (const auto& m : h.sent) {
    if (m.frame.can_id == kLock3) reqs.push_back(&m);
  }
  ASSERT_GE(reqs.size(), 10u);

  // Model info read (0xA000): sent at start-up, then every 200 ms: 5 transmissions in 1 s.
  std::vector<Micros> model_reads;
  for (const auto* m : reqs) {
    if (m->frame.function == 0xA0 && m->ts < h.at(4)) model_reads.push_back(m->ts);
  }
  ASSERT_EQ(model_reads.size(), 5u);
  EXPECT_EQ(model_reads.front(), h.t0());
  for (std::size_t i = 1; i < model_reads.size(); ++i) {
    const Micros gap = model_reads[i] - model_reads[i - 1];
    EXPECT_GE(gap, ms(200)) << "retry " << i;
    EXPECT_LT(gap, ms(200) + GatewayCore::kTickInterval) << "retry " << i;
  }

  // Given up after 1 s: reported as timed out with 5 transmissions...
  const auto model_result = std::find_if(
      results.begin(), results.end(), [](const auto& r) { return r.entry->name == "lock3_model"; });
  ASSERT_NE(model_result, results.end());
  EXPECT_EQ(model_result->request.outcome, node::RequestOutcome::kTimedOut);
  EXPECT_EQ(model_result->request.transmissions, 5);
  EXPECT_GE(model_result->request.latency, ms(1000));
  EXPECT_LT(model_result->request.latency, ms(1000) + GatewayCore::kTickInterval);

  // ... and the next request on that ID (the status read) only starts after that, so the ID
  // never carries two requests at once; it follows the same 200 ms / 1 s rule.
  std::vector<Micros> status_reads;
  for (const auto* m : reqs) {
    if (m->frame.function == 0xA1 && m->ts < h.at(4)) status_reads.push_back(m->ts);
  }
  ASSERT_EQ(status_reads.size(), 5u);
  EXPECT_GE(status_reads.front(), model_reads.front() + ms(1000));
  for (std::size_t i = 1; i < status_reads.size(); ++i) {
    EXPECT_GE(status_reads[i] - status_reads[i - 1], ms(200));
    EXPECT_LT(status_reads[i] - status_reads[i - 1], ms(200) + GatewayCore::kTickInterval);
  }
  // After the timeouts the absent node is left alone for the back-off (5 s), not hammered.
  for (const auto* m : reqs) {
    if (m->ts > status_reads.back() + ms(1)) {
      EXPECT_GE(m->ts - status_reads.back(), sec(4));
    }
  }

  // A live lock answers the first transmission: no retries for it.
  const auto lock1 = std::find_if(results.begin(), results.end(),
                                  [](const auto& r) { return r.entry->name == "lock1_model"; });
  ASSERT_NE(lock1, results.end());
  EXPECT_EQ(lock1->request.outcome, node::RequestOutcome::kAnswered);
  EXPECT_EQ(lock1->request.transmissions, 1);
  EXPECT_EQ(sent_on(h, 0x767, 0x80).size(), 1u);
}

// ---------------------------------------------------------------------------------------------
// Never two segmented messages interleaved on one CAN ID (Appendix A item 5)

TEST(NodeOnSim, InterleavingCheckerDetectsInterleavedSegments) {
  // The checker itself must be able to fail: two long messages on one ID, segments alternated.
  const auto a = motinova::segment(
      motinova::make_frame(0x761, motinova::Mode::kWrite, 0x44, std::vector<uint8_t>(32, 0x11)));
  const auto b = motinova::segment(
      motinova::make_frame(0x761, motinova::Mode::kWrite, 0x44, std::vector<uint8_t>(32, 0x22)));
  std::vector<BusFrame> log;
  for (std::size_t i = 0; i < a.size(); ++i) {
    log.push_back({Micros(i), a[i], true});
    log.push_back({Micros(i), b[i], true});
  }
  EXPECT_FALSE(interleaving_violations(log, true).empty());
  log.clear();
  for (const auto& f : a) log.push_back({Micros(0), f, true});
  for (const auto& f : b) log.push_back({Micros(0), f, true});
  EXPECT_TRUE(interleaving_violations(log, true).empty());
}

TEST(NodeOnSim, NoTwoSegmentedMessagesInterleavedOnOneId) {
  // A busy session: start-up polls, the silent lock's retries, lock actuations (writes and
  // status reads on the same IDs as the polls), vehicle LOCK/UNLOCK, a fault on the gateway and
  // its own shutdown at the end.
  SimHarness h(bundled("faults"), make_config());
  h.start();
  std::vector<node::LockResult> locks;
  auto& node = h.core.node();
  h.run_until(h.at(20));
  EXPECT_EQ(node.actuate_lock(1, node::LockTarget::kUnlocked, h.bus.now(),
                              [&](const node::LockResult& r) { locks.push_back(r); }),
            node::LockStart::kStarted);
  EXPECT_EQ(node.actuate_lock(2, node::LockTarget::kUnlocked, h.bus.now(),
                              [&](const node::LockResult& r) { locks.push_back(r); }),
            node::LockStart::kStarted);  // the silent one: repeats then times out
  h.run_until(h.at(30));
  EXPECT_EQ(node.actuate_lock(1, node::LockTarget::kLocked, h.bus.now(),
                              [&](const node::LockResult& r) { locks.push_back(r); }),
            node::LockStart::kStarted);
  node.vehicle_lock(h.bus.now());
  h.run_until(h.at(30.1));
  node.vehicle_unlock(h.bus.now());
  node.set_own_fault(0x0004, true, h.bus.now());
  h.run_until(h.at(60));
  EXPECT_TRUE(node.start_shutdown(h.bus.now(), [](const node::ShutdownOutcome&) {}));
  h.run_until(h.at(65));

  ASSERT_EQ(locks.size(), 3u);
  EXPECT_GT(h.sent.size(), 200u);

  // 1. The whole bus, every ID: segments of one message are contiguous.
  const auto violations = interleaving_violations(h.bus_log, false);
  EXPECT_TRUE(violations.empty()) << violations.size() << " violations, first: "
                                  << (violations.empty() ? "" : violations.front());
  // 2. An independent reassembler over the whole bus reports no error at all (no restarts, no
  //    CRC failures, no gaps): this scenario has no injected corruption.
  EXPECT_TRUE(h.probe.errors.empty())
      << h.probe.errors.size() << " errors, first "
      << (h.probe.errors.empty()
              ? ""
              : std::string(motinova::reassembly_error_name(h.probe.errors.front().kind)));
  // 3. The gateway's own transmissions alone, strictly reassembled, give back exactly the
  //    messages it sent, in order.
  struct Strict final : motinova::FrameSink {
    std::vector<motinova::AppFrame> frames;
    int errors = 0;
    void on_frame(const motinova::AppFrame& f, Micros) override { frames.push_back(f); }
    void on_error(const motinova::ReassemblyErrorEvent&) override { ++errors; }
  } strict;
  motinova::Reassembler rx;
  for (const auto& f : h.gateway_frames) rx.push(f.frame, f.ts, strict);
  EXPECT_EQ(strict.errors, 0);
  ASSERT_EQ(strict.frames.size(), h.sent.size());
  for (std::size_t i = 0; i < strict.frames.size(); ++i) {
    EXPECT_EQ(strict.frames[i], h.sent[i].frame) << i;
  }
  EXPECT_TRUE(interleaving_violations(h.gateway_frames, true).empty());
}

// ---------------------------------------------------------------------------------------------
// Own broadcasts: model info every model_info_period, fault word 1 s while OK, 200 ms while not

TEST(NodeOnSim, OwnModelInfoAndFaultWordBroadcastPeriods) {
  const auto cfg = make_config(
      "[node]\nmodel = \"IOT-TEST\"\nserial = \"SN-RT-42\"\nmodel_info_period_ms = 7000\n");
  SimHarness h(bundled("parked"), cfg);
  h.start();
  auto& node = h.core.node();
  h.run_until(h.at(12.01));
  node.set_own_fault(0x0004, true, h.bus.now());  // GPS
  const Micros raised = h.bus.now();
  // Off the 200 ms grid of the faulty word (12.01 + n * 0.2 s): the node's deadlines are exact,
  // so a clear at 15.01 would share its instant with a periodic faulty word.
  h.run_until(h.at(15.11));
  node.set_own_fault(0x0004, false, h.bus.now());
  const Micros cleared = h.bus.now();
  h.run_until(h.at(30));

  // Model info: at start-up, then every 7 s (the configured period), content from the config.
  const auto infos = h.probe.on(kIotId, 0x13);
  ASSERT_EQ(infos.size(), 5u);  // 0, 7, 14, 21, 28 s
  EXPECT_EQ(infos.front()->ts, h.t0());
  for (std::size_t i = 1; i < infos.size(); ++i) {
    EXPECT_GE(infos[i]->ts - infos[i - 1]->ts, ms(7000));
    EXPECT_LT(infos[i]->ts - infos[i - 1]->ts, ms(7000) + GatewayCore::kTickInterval);
  }
  motinova::DecodedMessage d;
  motinova::decode(infos.front()->frame, motinova::Catalogue::standard(), h.core.options(), d);
  ASSERT_EQ(d.status, motinova::DecodeStatus::kOk);
  EXPECT_EQ(d.text("model"), "IOT-TEST");
  EXPECT_EQ(d.text("serial"), "SN-RT-42");
  EXPECT_EQ(d.text("fw").substr(0, 1), "V");

  // Fault word: normalised value of each broadcast, with its period.
  const auto words = h.probe.on(kIotId, 0x15);
  ASSERT_FALSE(words.empty());
  EXPECT_EQ(words.front()->ts, h.t0());
  const auto value = [&](const BusMessage* m) {
    std::array<uint8_t, 4> w{};
    std::copy_n(m->frame.data.begin(), 4, w.begin());
    return motinova::normalise_fault_word(w, h.core.options().data_order,
                                          h.core.options().other_fault_layout);
  };
  std::size_t faulty = 0;
  for (std::size_t i = 0; i < words.size(); ++i) {
    const Micros t = words[i]->ts;
    const uint32_t v = value(words[i]);
    if (t >= raised && t < cleared) {
      EXPECT_EQ(v, 0x0004u) << "at " << (t - h.t0()).count();
      ++faulty;
    } else {
      EXPECT_EQ(v, 0u) << "at " << (t - h.t0()).count();
    }
    if (i == 0) continue;
    const Micros gap = t - words[i - 1]->ts;
    if (t == raised || t == cleared) continue;  // a change goes out at once
    const Micros period = (t > raised && t <= cleared) ? ms(200) : ms(1000);
    EXPECT_GE(gap, period) << "at " << (t - h.t0()).count();
    EXPECT_LT(gap, period + GatewayCore::kTickInterval) << "at " << (t - h.t0()).count();
  }
  // Sent at once on both changes.
  EXPECT_NE(h.probe.first(kIotId, 0x15, raised - Micros(1)), nullptr);
  EXPECT_EQ(h.probe.first(kIotId, 0x15, raised - Micros(1))->ts, raised);
  EXPECT_EQ(h.probe.first(kIotId, 0x15, cleared - Micros(1))->ts, cleared);
  EXPECT_GE(faulty, 14u);  // 3 s at 200 ms
  EXPECT_LE(faulty, 16u);
}

}  // namespace
}  // namespace fleetgw::runtime::testing
