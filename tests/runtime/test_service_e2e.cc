// `fleetgw run` end to end on the in-process simulator: run_service() with an accelerated sim,
// checked through its ServiceReport and through the SQLite database it wrote.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <fstream>

#include "gateway/runtime/service.h"
#include "gateway/sim/bus_log_writer.h"
#include "gateway/sim/sim_bus.h"
#include "runtime_test_util.h"
#include "storage/store.h"

namespace fleetgw::runtime::testing {
namespace {

uint64_t rows(const storage::Stats& s, std::string_view table) {
  for (const auto& [name, n] : s.table_rows) {
    if (name == table) return n;
  }
  ADD_FAILURE() << "no table " << table;
  return 0;
}

std::vector<nlohmann::json> export_rows(storage::Store& store, std::string_view table) {
  std::vector<nlohmann::json> out;
  store.export_table(table, 0, [&](const nlohmann::json& row) { out.push_back(row); });
  return out;
}

std::string service_config(const TempDir& dir, const std::string& scenario, double speed,
                           const std::string& extra = "") {
  std::filesystem::create_directories(dir / "db");  // the service never creates it
  return "[can]\ntransport = \"sim\"\n[sim]\nscenario = \"" + scenario_path(scenario).string() +
         "\"\nspeed = " + std::to_string(speed) + "\nlockstep = true\n[storage]\npath = \"" +
         (dir / "db" / "fleetgw.db").string() + "\"\n" + extra;
}

TEST(ServiceE2E, RideScenarioEndsUpAsRideAndTelemetryInTheStore) {
  TempDir dir;
  // 1900 s of ride at 400x: ~5 s of wall time. A ride ends after 120 s standing still. The
  // gateway's polls are round trips through the simulated bus: on the wall-clock pacing a
  // millisecond of delay on a loaded machine was 0.4 s of bus time here (a sanitizer build on
  // a busy CI machine lost a quarter of the samples at 1500x); lock-step (service_config)
  // slows the ride down instead.
  const auto cfg =
      make_config(service_config(dir, "ride", 400, "[ride]\nstationary_end_s = 120\n"));
  ServiceOptions opts;
  opts.open_sim = sim::open_sim_bus;
  // Bus time, not wall time, bounds the run: a slow (sanitizer) build covers the same ride.
  opts.bus_duration = sec(1900);
  opts.duration = std::chrono::milliseconds(120'000);
  ServiceReport report;
  ASSERT_EQ(run_service(cfg, opts, &report), 0);

  EXPECT_GE(report.virtual_seconds, 1850.0);
  EXPECT_GT(report.messages, 35'000u);  // ~45 000 messages in 1900 s
  EXPECT_GT(report.can_frames, report.messages);
  EXPECT_EQ(report.frame_errors, 0u);
  EXPECT_FALSE(report.last_live_line.empty());

  // The same ride on the VirtualBus gives the distance the store must show.
  sim::VirtualBus bus(bundled("ride"));
  const double odo0 = bus.bike().state().odo_m;
  bus.run_until(bus.start() + sec(1900));
  const double ridden_km = (bus.bike().state().odo_m - odo0) / 1000.0;
  ASSERT_GT(ridden_km, 5.0);

  storage::StoreOptions so;
  so.path = (dir / "db" / "fleetgw.db").string();
  storage::Store store(so);
  const auto stats = store.stats();
  EXPECT_EQ(rows(stats, "rides"), 1u);
  // Telemetry every second while riding (~1685 s of riding).
  EXPECT_GT(rows(stats, "telemetry"), 1200u);
  EXPECT_GT(rows(stats, "pack_snapshots"), 0u);
  const auto rides = export_rows(store, "rides");
  ASSERT_EQ(rides.size(), 1u);
  const auto& ride = rides.front();
  EXPECT_EQ(ride["state"], "closed") << ride.dump();
  EXPECT_NEAR(ride["distance_km"].get<double>(), ridden_km, 0.25) << ride.dump();
  EXPECT_GT(ride["max_speed_kmh"].get<double>(), 20.0);
  EXPECT_LE(ride["max_speed_kmh"].get<double>(), 26.0);
  EXPECT_GT(ride["energy_wh"].get<double>(), 0.0);
  EXPECT_EQ(store.integrity_check(), "ok");
}

TEST(ServiceE2E, ServiceKeepsRunningThroughBusTrouble) {
  TempDir dir;
  const auto cfg = make_config(service_config(dir, "bus-trouble", 500));
  ServiceOptions opts;
  opts.open_sim = sim::open_sim_bus;
  opts.bus_duration = sec(450);
  opts.duration = std::chrono::milliseconds(120'000);
  ServiceReport report;
  ASSERT_EQ(run_service(cfg, opts, &report), 0);
  EXPECT_GE(report.virtual_seconds, 420.0);  // past every corruption/garbage event
  EXPECT_GT(report.frame_errors, 20u);
  EXPECT_GT(report.messages, 8000u);
  // The database is consistent and has the ride's telemetry.
  storage::StoreOptions so;
  so.path = (dir / "db" / "fleetgw.db").string();
  storage::Store store(so);
  EXPECT_GT(rows(store.stats(), "telemetry"), 200u);
  EXPECT_EQ(store.integrity_check(), "ok");
}

}  // namespace
}  // namespace fleetgw::runtime::testing

namespace fleetgw::runtime::testing {
namespace {

// A replay as fast as possible is paced by its transport alone: the pipeline's one timer only
// serves the wall-clock group commit (storage.flush_ms), never a tick per bus interval (the old
// service woke every 50 ms and polled every 200 ms whatever the traffic).
TEST(ServiceE2E, ReplayAsFastAsPossibleIsNotPacedByTimers) {
  TempDir dir;
  const auto log_path = dir / "ride.log";
  {
    std::ofstream log(log_path);
    sim::VirtualBus bus(bundled("ride"));
    bus.add(sim::candump_writer(log));
    bus.run_until(bus.start() + sec(600));
  }
  std::filesystem::create_directories(dir / "db");  // the service never creates it
  const auto cfg =
      make_config("[can]\ntransport = \"replay\"\nreplay_file = \"" + log_path.string() +
                  "\"\n[storage]\npath = \"" + (dir / "db" / "fleetgw.db").string() + "\"\n");
  ServiceOptions opts;
  opts.duration = std::chrono::milliseconds(120'000);
  ServiceReport report;
  ASSERT_EQ(run_service(cfg, opts, &report), 0);
  EXPECT_GE(report.virtual_seconds, 590.0);
  EXPECT_GT(report.can_frames, 50'000u);
  // At most one wake-up per 200 ms of wall time (group commit) plus a couple at start and end;
  // 600 s of bus time at the old 50 ms tick would have been 12,000.
  EXPECT_LE(static_cast<double>(report.counters.timer_wakeups), report.wall_seconds * 5 + 3)
      << report.wall_seconds << " s";
  storage::StoreOptions so;
  so.path = (dir / "db" / "fleetgw.db").string();
  storage::Store store(so);
  EXPECT_GT(rows(store.stats(), "telemetry"), 400u);
}

}  // namespace
}  // namespace fleetgw::runtime::testing
