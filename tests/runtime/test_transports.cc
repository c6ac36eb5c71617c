// Transports and bad input: a recorded log replayed through ReplayTransport decodes to exactly
// the stream the in-process simulator produced; the UDP tunnel carries frames both ways between
// `fleetgw sim` (a child process) and the service; bad configs, malformed log lines and garbage
// on the bus are reported precisely while the rest keeps working.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <asio/io_context.hpp>
#include <asio/ip/udp.hpp>
#include <set>
#include <thread>

#include "gateway/can/replay_transport.h"
#include "gateway/runtime/service.h"
#include "gateway/sim/bus_log_writer.h"
#include "runtime_test_util.h"

namespace fleetgw::runtime::testing {
namespace {

struct Collected {
  Micros ts{0};
  uint16_t can_id = 0;
  uint8_t function = 0;
  std::vector<uint8_t> data;
  friend bool operator==(const Collected&, const Collected&) = default;
};

std::ostream& operator<<(std::ostream& os, const Collected& c) {
  return os << c.ts.count() << " 0x" << std::hex << c.can_id << "/0x" << int(c.function) << std::dec
            << " (" << c.data.size() << " bytes)";
}

Collected collect(const motinova::AppFrame& f, Micros ts) {
  return {ts, f.can_id, f.function, std::vector<uint8_t>(f.data.begin(), f.data.end())};
}

struct Collector final : MessageListener {
  void on_message(const motinova::DecodedMessage& m, Micros now) override {
    messages.push_back(collect(*m.frame, now));
  }
  bool saw(uint16_t id, uint8_t fn) const {
    return std::any_of(messages.begin(), messages.end(),
                       [&](const Collected& c) { return c.can_id == id && c.function == fn; });
  }
  std::vector<Collected> messages;
};

// A sender that refuses everything: the replaying core then only decodes (nothing is echoed).
struct RefusingSender final : node::FrameSender {
  bool send(const motinova::AppFrame&) override { return false; }
};

// Replays `in` through ReplayTransport (as fast as possible) into a GatewayCore; returns what the
// core decoded.
std::vector<Collected> replay_into_core(std::unique_ptr<std::istream> in, Micros start,
                                        can::ReplaySummary* summary = nullptr) {
  asio::io_context io;
  can::ReplayTransport replay(io, std::move(in), "test-log", can::ReplayOptions{});
  RefusingSender refuse;
  const auto cfg = make_config();
  GatewayCore core(cfg, refuse);
  Collector collector;
  core.add_listener(collector);
  core.start(start);
  replay.on_end([&](const can::ReplaySummary& s) {
    if (summary) *summary = s;
  });
  replay.start([&](const motinova::CanFrame& f, Micros ts) { core.on_can_frame(f, ts); },
               [](const can::BusHealth&) {});
  io.run();
  EXPECT_TRUE(replay.finished());
  return std::move(collector.messages);
}

// ---------------------------------------------------------------------------------------------
// Replay versus the in-process simulator

TEST(Transports, ReplayOfRecordedSessionDecodesExactlyWhatTheSimProduced) {
  // A whole session, the gateway's own frames included (polls, model info, READY...).
  std::ostringstream log;
  SimHarness h(bundled("demo"), make_config());
  h.bus.add(sim::candump_writer(log));
  h.start();
  h.run_until(h.at(90));

  std::vector<Collected> from_sim;
  for (const auto& m : h.probe.messages) from_sim.push_back(collect(m.frame, m.ts));
  ASSERT_GT(from_sim.size(), 1500u);
  ASSERT_GT(h.sent.size(), 20u);

  can::ReplaySummary summary;
  const auto replayed =
      replay_into_core(std::make_unique<std::istringstream>(log.str()), h.t0(), &summary);
  EXPECT_EQ(summary.malformed_lines, 0u);
  EXPECT_EQ(summary.frames, h.bus_log.size());
  ASSERT_EQ(replayed.size(), from_sim.size());
  std::size_t gateway = 0;
  for (std::size_t i = 0; i < replayed.size(); ++i) {
    ASSERT_EQ(replayed[i], from_sim[i]) << "message " << i;
    gateway += (replayed[i].can_id & 0xFF0) == 0x760;
  }
  EXPECT_EQ(gateway, h.sent.size()) << "the gateway's frames are part of the replayed stream";
}

TEST(Transports, ReplayOfRecordScenarioFileMatchesTheBikeAlone) {
  const sim::Scenario scenario = bundled("faults");
  const Micros duration = sec(300);  // through the MC over-temperature at 240 s
  TempDir dir;
  {
    std::ofstream out(dir / "faults.log");
    EXPECT_GT(sim::record_scenario(scenario, duration, out), 10'000u);
  }
  // The bike alone on the VirtualBus, decoded by a probe.
  sim::VirtualBus bus(scenario);
  BusProbe probe;
  sim::VirtualBus::Participant p;
  p.on_frame = [&](const motinova::CanFrame& f, Micros ts) { probe.push(f, ts); };
  bus.add(std::move(p));
  bus.run_until(bus.start() + duration);

  asio::io_context io;
  can::ReplayTransport replay(io, dir / "faults.log", can::ReplayOptions{});
  RefusingSender refuse;
  const auto cfg = make_config();
  GatewayCore core(cfg, refuse);
  Collector collector;
  core.add_listener(collector);
  core.start(scenario.start);
  replay.start([&](const motinova::CanFrame& f, Micros ts) { core.on_can_frame(f, ts); },
               [](const can::BusHealth&) {});
  io.run();

  ASSERT_EQ(collector.messages.size(), probe.messages.size());
  for (std::size_t i = 0; i < probe.messages.size(); ++i) {
    ASSERT_EQ(collector.messages[i], collect(probe.messages[i].frame, probe.messages[i].ts)) << i;
  }
  // The decoded stream carries what happened: the MC fault word went non-zero at 240 s.
  const auto& reg = core.node().registry();
  EXPECT_EQ(reg.node(motinova::Node::kMc).faults.state, node::FaultState::kFaulty);
  EXPECT_EQ(core.bus_stats().total_errors(), 0u);
}

// ---------------------------------------------------------------------------------------------
// UDP tunnel between two processes

uint16_t free_udp_port() {
  asio::io_context io;
  asio::ip::udp::socket s(io, asio::ip::udp::endpoint(asio::ip::make_address("127.0.0.1"), 0));
  return s.local_endpoint().port();
}

TEST(Transports, UdpTunnelCarriesFramesBetweenSimProcessAndService) {
  TempDir dir;
  const uint16_t sim_port = free_udp_port();
  uint16_t gw_port = free_udp_port();
  while (gw_port == sim_port) gw_port = free_udp_port();

  auto cfg =
      make_config("[can]\ntransport = \"udp\"\nudp_local = \"127.0.0.1:" + std::to_string(gw_port) +
                  "\"\nudp_remote = \"127.0.0.1:" + std::to_string(sim_port) +
                  "\"\n[storage]\npath = \"" + (dir / "gw.db").string() + "\"\n");

  // The simulator as a separate process: 30 s of the ride at 10x. It starts a little after the
  // service so the service's socket is bound when the first frames arrive.
  fleetgw::testing::CapturedChild sim(
      {"/bin/sh", "-c",
       "sleep 0.3; exec " + std::string(FLEETGW_BIN) +
           " sim --bus udp:" + std::to_string(sim_port) + ":" + std::to_string(gw_port) +
           " --scenario " + scenario_path("ride").string() + " --duration 30 --speed 10"},
      dir / "sim.out", dir / "sim.err");

  Collector collector;
  // Everything the checks below need, each (CAN ID, function) pair noted once as it arrives.
  std::set<std::pair<uint16_t, uint8_t>> wanted{
      {0x710, 0x10}, {0x720, 0x10}, {0x730, 0x15}, {0x760, 0x13}};
  for (uint16_t id = 0x770; id <= 0x7B0; id += 0x10) {
    wanted.insert({id, 0x10});
    wanted.insert({id, 0x12});
  }
  std::size_t scanned = 0;
  ServiceOptions opts;
  // Stops once everything arrived, not after a fixed time: a loaded machine (or a sanitizer
  // build) starts the simulator process late. The duration only bounds a failing run.
  opts.duration = std::chrono::seconds(60);
  opts.stop_when = [&] {
    for (; scanned < collector.messages.size(); ++scanned) {
      wanted.erase({collector.messages[scanned].can_id, collector.messages[scanned].function});
    }
    return wanted.empty() && collector.messages.size() > 600;
  };
  opts.on_core = [&](GatewayCore& core) { core.add_listener(collector); };
  ServiceReport report;
  EXPECT_EQ(run_service(cfg, opts, &report), 0);
  EXPECT_EQ(sim.wait(std::chrono::seconds(60)).value_or(-1), 0) << sim.err();

  // Sim -> gateway: broadcasts of the MC, the BMS and the locks were decoded.
  EXPECT_GT(report.messages, 500u);
  EXPECT_EQ(report.frame_errors, 0u);
  EXPECT_TRUE(collector.saw(0x710, 0x10)) << "MC status";
  EXPECT_TRUE(collector.saw(0x720, 0x10)) << "BMS status";
  EXPECT_TRUE(collector.saw(0x730, 0x15)) << "OBC fault word";
  for (uint16_t id = 0x770; id <= 0x7B0; id += 0x10) {
    EXPECT_TRUE(collector.saw(id, 0x10)) << std::hex << id << " lock status";
  }
  // Gateway -> sim: the gateway broadcast its model info and read the locks' model info; locks
  // send 0x1240 only in answer to that read, so its arrival proves our frames reached the sim.
  EXPECT_TRUE(collector.saw(0x760, 0x13)) << "own model info (echo)";
  for (uint16_t id = 0x770; id <= 0x7B0; id += 0x10) {
    EXPECT_TRUE(collector.saw(id, 0x12)) << std::hex << id << " lock model info (answer)";
  }
  // And the sim says how many external CAN frames it heard: at least the 10 segments of the
  // model info plus the read requests.
  const std::string sim_log = sim.err() + sim.out();
  // (No std::regex: g++ 12 reports a false -Wmaybe-uninitialized inside <regex> under ASan.)
  const auto heard_at = sim_log.find(" frames heard");
  ASSERT_NE(heard_at, std::string::npos) << sim_log;
  const auto digits = sim_log.find_last_not_of("0123456789", heard_at - 1) + 1;
  ASSERT_LT(digits, heard_at) << sim_log;
  EXPECT_GE(std::stoul(sim_log.substr(digits, heard_at - digits)), 10u + 7u);
}

// ---------------------------------------------------------------------------------------------
// Bad input

TEST(BadInput, ConfigErrorsNameFileLineAndKey) {
  const std::string text =
      "[vehicle]\n"
      "id = \"bike-7\"\n"
      "[can]\n"
      "transprot = \"sim\"\n"          // line 4: unknown key
      "reassembly_gap_ms = \"100\"\n"  // line 5: wrong type
      "[node]\n"
      "offline_timeout_ms = -5\n";  // line 7: out of range
  try {
    (void)config::parse_config(text, "bad.toml");
    FAIL() << "a config with three errors was accepted";
  } catch (const config::ConfigError& e) {
    ASSERT_EQ(e.problems.size(), 3u) << e.what();
    const auto has = [&](const std::string& where, const std::string& key) {
      return std::any_of(e.problems.begin(), e.problems.end(), [&](const std::string& p) {
        return p.find(where) != std::string::npos && p.find(key) != std::string::npos;
      });
    };
    EXPECT_TRUE(has("bad.toml:4", "can.transprot")) << e.what();
    EXPECT_TRUE(has("bad.toml:5", "can.reassembly_gap_ms")) << e.what();
    EXPECT_TRUE(has("bad.toml:7", "node.offline_timeout_ms")) << e.what();
  }
  // The same through a file: the path is named.
  TempDir dir;
  std::ofstream(dir / "gw.toml") << text;
  try {
    (void)config::load_config(dir / "gw.toml");
    FAIL();
  } catch (const config::ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("gw.toml:4"), std::string::npos) << e.what();
  }
  // And a valid file with the same keys spelled right loads.
  EXPECT_NO_THROW(config::parse_config(
      "[can]\ntransport = \"sim\"\nreassembly_gap_ms = 100\n[node]\noffline_timeout_ms = 5000\n",
      "good.toml"));
}

TEST(BadInput, DecodeReportsMalformedLinesWithNumbersAndDecodesTheRest) {
  TempDir dir;
  std::ostringstream rec;
  sim::record_scenario(bundled("ride"), sec(20), rec);
  auto lines = lines_of(rec.str());
  ASSERT_GT(lines.size(), 1000u);
  {
    std::ofstream clean(dir / "clean.log");
    for (const auto& l : lines) clean << l << '\n';
  }
  // Malformed lines inserted between frames: they must cost their own line and nothing else.
  const std::vector<std::pair<std::size_t, std::string>> bad = {
      {3, "(1717228800.000000) can0 7G0#00"},                     // bad hex in the ID
      {100, "this is not a candump line"},                        // garbage
      {500, "(1717228801.5) can0 710#0011223"},                   // odd number of digits
      {900, "(1717228802.000000) can0 710#001122334455667788"}};  // 9 data bytes
  std::vector<std::string> dirty = lines;
  for (const auto& [line_no, text] : bad) {
    dirty.insert(dirty.begin() + static_cast<std::ptrdiff_t>(line_no - 1), text);
  }
  {
    std::ofstream out(dir / "dirty.log");
    for (const auto& l : dirty) out << l << '\n';
  }
  for (const auto& [line_no, text] : bad) ASSERT_EQ(dirty[line_no - 1], text);

  const auto c = fleetgw::testing::run_captured(
      {FLEETGW_BIN, "decode", (dir / "clean.log").string()}, dir.path());
  ASSERT_EQ(c.code, 0) << c.err;
  const auto d = fleetgw::testing::run_captured(
      {FLEETGW_BIN, "decode", (dir / "dirty.log").string()}, dir.path());
  ASSERT_EQ(d.code, 0) << d.err;

  // The rest is decoded exactly as without the bad lines.
  const auto out_lines = lines_of(d.out);
  EXPECT_EQ(d.out, c.out);
  ASSERT_GT(out_lines.size(), 400u);
  for (const auto& l : out_lines) {
    const auto j = nlohmann::json::parse(l);
    ASSERT_TRUE(j.is_object()) << l;
  }
  // Every bad line is reported with its number; no good line is.
  for (const auto& [line_no, text] : bad) {
    EXPECT_NE(d.err.find("line " + std::to_string(line_no) + ","), std::string::npos)
        << "line " << line_no << " not reported:\n"
        << d.err;
  }
  EXPECT_EQ(
      std::count(d.err.begin(), d.err.end(), '\n') - std::count(c.err.begin(), c.err.end(), '\n'),
      static_cast<long>(bad.size()))
      << d.err;
  EXPECT_NE(d.err.find("4 malformed log lines"), std::string::npos) << d.err;
}

TEST(BadInput, GarbageOnTheBusIsCountedAndValidTrafficStillDecoded) {
  SimHarness h(bundled("bus-trouble"), make_config());
  Collector collector;
  h.core.add_listener(collector);
  h.start();
  h.run_until(h.at(330));  // bit flips, truncations, garbage at 30/60/90/200/260/300 s

  const auto& stats = h.core.bus_stats();
  using E = motinova::ReassemblyError;
  EXPECT_GT(stats.error(E::kBadCrc), 0u) << "bit flips";
  EXPECT_GT(stats.error(E::kBadHeader), 0u) << "garbage frames";
  EXPECT_GT(stats.error(E::kTruncated) + stats.error(E::kGapTimeout) + stats.error(E::kRestarted),
            0u)
      << "truncated messages";
  // The gateway counted exactly what an independent reassembler saw.
  EXPECT_EQ(stats.total_errors(), h.probe.errors.size());
  const auto& bike = h.bus.bike().stats();
  EXPECT_GE(stats.total_errors(), bike.corrupted_bitflip + bike.corrupted_truncated);

  // Every valid message was still decoded: the core saw every message the probe saw (minus the
  // gateway's own frames, which it does not receive from the bus).
  std::size_t valid_from_bike = 0;
  for (const auto& m : h.probe.messages) valid_from_bike += !m.from_gateway;
  EXPECT_EQ(h.core.stats().messages, valid_from_bike);
  // The loss is bounded by what was corrupted: every message the bike sent arrived except the
  // damaged ones.
  EXPECT_GE(valid_from_bike + bike.corrupted_bitflip + bike.corrupted_truncated,
            bike.messages_sent);
  // MC status keeps flowing after the trouble (5 per second from 305 s on) and the node is live.
  std::size_t late_status = 0;
  for (const auto& c : collector.messages) {
    late_status += c.can_id == 0x710 && c.function == 0x10 && c.ts > h.at(305);
  }
  EXPECT_GE(late_status, 120u);
  EXPECT_TRUE(h.core.node().registry().online(motinova::Node::kMc));
  EXPECT_TRUE(h.core.node().registry().online(motinova::Node::kBms));
}

}  // namespace
}  // namespace fleetgw::runtime::testing
