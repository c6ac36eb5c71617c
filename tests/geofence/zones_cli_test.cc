// `fleetgw zones sign|check` through the shipped binary: a key from `fleetgw keygen`, zones
// drawn as GeoJSON, a signed bundle checked against a configuration's trusted keys, and the
// refusals an operator meets (tampered file, older version, invalid zone) with exit 1.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "tests/support/process.h"
#include "tests/support/temp_dir.h"

namespace fleetgw::geofence {
namespace {

const char* const kZones = R"({"type": "FeatureCollection", "features": [
  {"type": "Feature", "properties": {"id": "city", "kind": "operating_area"},
   "geometry": {"type": "Polygon", "coordinates":
     [[[13.35, 52.50], [13.45, 52.50], [13.45, 52.54], [13.35, 52.54], [13.35, 52.50]]]}},
  {"type": "Feature", "properties": {"id": "old-town", "kind": "slow", "speed_limit_kmh": 15},
   "geometry": {"type": "Polygon", "coordinates":
     [[[13.39, 52.51], [13.42, 52.51], [13.42, 52.53], [13.39, 52.53]]]}}]})";

class ZonesCli : public ::testing::Test {
 protected:
  fleetgw::testing::TempDir dir{"zones-cli"};

  int fleetgw(const std::vector<std::string>& args, std::string& output) {
    std::vector<std::string> argv{FLEETGW_BIN};
    argv.insert(argv.end(), args.begin(), args.end());
    const auto out = dir / "out.txt";
    std::filesystem::remove(out);
    const int rc = fleetgw::testing::run_for_exit_code(argv, out);
    std::ifstream in(out);
    std::ostringstream s;
    s << in.rdbuf();
    output = s.str();
    return rc;
  }
  std::string path(const char* name) { return (dir / name).string(); }
};

TEST_F(ZonesCli, SignedWithAKeygenKeyAndCheckedWithTheConfigsTrustedKeys) {
  std::string out;
  ASSERT_EQ(fleetgw({"keygen", path("ops")}, out), 0) << out;
  // keygen prints the [command.trusted_keys] line: the configuration trusts that key.
  const auto line = out.substr(out.find("ops = \""));
  std::ofstream(dir / "fleetgw.toml") << "[command.trusted_keys]\n"
                                      << line.substr(0, line.find('\n')) << "\n";
  std::ofstream(dir / "zones.geojson") << kZones;

  ASSERT_EQ(fleetgw({"zones", "sign", path("zones.geojson"), "--version", "3", "--key",
                     path("ops.pem"), "--out", path("zones-3.pb")},
                    out),
            0)
      << out;
  EXPECT_NE(out.find("version 3, 2 zones, 8 vertices, signed by 'ops'"), std::string::npos) << out;
  ASSERT_EQ(fleetgw({"zones", "sign", path("zones.geojson"), "--version", "2", "--key",
                     path("ops.pem"), "--out", path("zones-2.pb")},
                    out),
            0)
      << out;

  EXPECT_EQ(fleetgw({"zones", "check", path("zones-3.pb"), "--config", path("fleetgw.toml")}, out),
            0)
      << out;
  EXPECT_NE(out.find("accepted: version 3 in force: 2 zones, 8 vertices"), std::string::npos)
      << out;
  EXPECT_NE(out.find("old-town  slow  4 vertices  15 km/h"), std::string::npos) << out;

  // Against the bundle a gateway has in force: an older one is refused.
  EXPECT_EQ(fleetgw({"zones", "check", path("zones-2.pb"), "--config", path("fleetgw.toml"),
                     "--in-force", path("zones-3.pb")},
                    out),
            1)
      << out;
  EXPECT_NE(out.find("refused (not_newer): version 2 is older than version 3 in force"),
            std::string::npos)
      << out;

  // A byte changed in transit: refused, never enforced.
  std::string bytes;
  {
    std::ifstream in(dir / "zones-3.pb", std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  bytes[bytes.size() / 2] ^= 0x04;
  std::ofstream(dir / "forged.pb", std::ios::binary) << bytes;
  EXPECT_EQ(fleetgw({"zones", "check", path("forged.pb"), "--config", path("fleetgw.toml")}, out),
            1)
      << out;
  EXPECT_NE(out.find("refused ("), std::string::npos) << out;
}

TEST_F(ZonesCli, AnInvalidZoneFileIsRefusedSayingWhereAndNothingIsWritten) {
  std::string out;
  ASSERT_EQ(fleetgw({"keygen", path("ops")}, out), 0) << out;
  std::ofstream(dir / "zones.geojson") << R"({"type": "FeatureCollection", "features": [
    {"type": "Feature", "properties": {"id": "pier", "kind": "no_ride"},
     "geometry": {"type": "Polygon", "coordinates": [[[13.35, 52.50], [200, 52.50], [13.4, 52.6]]]}}]})";
  EXPECT_EQ(fleetgw({"zones", "sign", path("zones.geojson"), "--version", "1", "--key",
                     path("ops.pem"), "--out", path("z.pb")},
                    out),
            1);
  EXPECT_NE(out.find("feature 0 ('pier'), ring 0: position 1: longitude 200 is not a number in "
                     "-180..180"),
            std::string::npos)
      << out;
  EXPECT_FALSE(std::filesystem::exists(dir / "z.pb"));
}

}  // namespace
}  // namespace fleetgw::geofence
