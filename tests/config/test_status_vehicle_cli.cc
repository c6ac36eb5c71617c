// `fleetgw status` from a running `fleetgw run` on the simulator: speed, SOC and the open ride
// (distance, duration) in the JSON document and in the table, while the bike really rides.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "tests/config/cli_test_util.h"
#include "tests/support/temp_dir.h"

namespace fleetgw::testing::status_vehicle_cli {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

TEST(StatusVehicle, SpeedSocAndOpenRideWhileRiding) {
  TempDir dir("fleetgw-status-vehicle");
  const fs::path sock = dir.path() / "status.sock";
  const fs::path scenario = dir.path() / "ride.toml";
  // Parked 20 s with the locks open, then 20 km/h: at speed 20 the ride starts after ~1 s.
  write_text_file(scenario,
                  "[scenario]\nduration_s = 1200\n[bike]\nseed = 5\nsoc_pct = 71\nlocks_locked = "
                  "false\n[[ride]]\nduration_s = 20\nspeed_kmh = 0\n[[ride]]\nduration_s = 1180\n"
                  "speed_kmh = 20\n");
  const fs::path file = dir.path() / "fleetgw.toml";
  write_text_file(file, "[can]\ntransport = \"sim\"\n[sim]\nscenario = \"" + scenario.string() +
                            "\"\nspeed = 20\nlockstep = true\n[storage]\npath = \"" +
                            (dir.path() / "fleetgw.db").string() + "\"\n[status]\nsocket = \"" +
                            sock.string() + "\"\n");
  Child service({FLEETGW_BIN, "run", "--config", file.string(), "--duration", "60"},
                dir.path() / "svc.out", dir.path() / "svc.err");
  json doc;
  // Until the ride has covered some distance: the document is polled, never slept for.
  const bool riding = wait_until(
      [&] {
        const Result r =
            run({FLEETGW_BIN, "status", "--config", file.string(), "--format", "json"}, dir.path());
        doc = json::parse(r.out, nullptr, false);
        if (!doc.is_object()) return false;
        const json& ride = doc["vehicle"]["ride"];
        return ride.is_object() && ride["distance_km"].get<double>() > 0.2;
      },
      std::chrono::seconds(40));
  ASSERT_TRUE(riding) << doc.dump() << '\n' << service.err();
  const json& v = doc["vehicle"];
  EXPECT_NEAR(v["speed_kmh"].get<double>(), 20, 3) << v;
  EXPECT_NEAR(v["soc_pct"].get<double>(), 71, 2) << v;
  EXPECT_EQ(v["riding"], true);
  EXPECT_GT(v["ride"]["duration_s"].get<double>(), 30) << v;
  EXPECT_EQ(v["ride"]["ride_id"].get<std::string>().empty(), false);
  // 20 km/h: the distance follows the duration (within the start and the 0.1 km steps).
  const double expected_km = v["ride"]["moving_s"].get<double>() * 20 / 3600;
  EXPECT_NEAR(v["ride"]["distance_km"].get<double>(), expected_km, 0.25) << v;

  const Result table =
      run({FLEETGW_BIN, "status", "--config", file.string(), "--format", "table"}, dir.path());
  std::string line;
  std::istringstream in(table.out);
  for (std::string l; std::getline(in, l);) {
    if (l.rfind("vehicle ", 0) == 0) line = l;
  }
  EXPECT_NE(line.find(" km/h  SOC 7"), std::string::npos) << table.out;
  EXPECT_NE(line.find("riding: "), std::string::npos) << table.out;
  EXPECT_NE(line.find(" km in "), std::string::npos) << table.out;
  const Result csv =
      run({FLEETGW_BIN, "status", "--config", file.string(), "--format", "csv"}, dir.path());
  EXPECT_NE(csv.out.find("\r\nvehicle.ride.distance_km,"), std::string::npos) << csv.out;
  service.signal(SIGTERM);
  EXPECT_EQ(service.wait(std::chrono::seconds(20)), 0) << service.err();
}

}  // namespace
}  // namespace fleetgw::testing::status_vehicle_cli
