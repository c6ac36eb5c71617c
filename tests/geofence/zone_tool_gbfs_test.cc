// `fleetgw zones sign|export` with GBFS (issue 27), as functions: the city's geofencing_zones.json
// as published signed into a bundle the gateway accepts and exported back member for member;
// a rule the bike cannot enforce refused with its JSON path and nothing written; what has no
// effect reported; a forged file not exported when the keys are given.
#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "gateway/command/ed25519.h"
#include "gateway/geofence/zone_tool.h"
#include "tests/support/files.h"
#include "tests/support/temp_dir.h"

namespace fleetgw::geofence {
namespace {

const Micros kGbfsIssued = std::chrono::seconds(1'790'000'000);

using ::fleetgw::testing::read_text_file;
class ZonesToolGbfs : public ::testing::Test {
 protected:
  ::fleetgw::testing::TempDir dir;
  command::Ed25519PrivateKey key = command::Ed25519PrivateKey::generate();
  std::filesystem::path city =
      std::string(FLEETGW_SOURCE_DIR) + "/tests/geofence/data/ljubljana_geofencing_zones.json";

  void SetUp() override { key.write_pem(dir / "ops.pem"); }
  std::map<std::string, std::string> trusted() const {
    return {{"ops", key.public_key().base64()}};
  }
  int sign(const std::filesystem::path& in, const std::string& out, std::string& err) {
    std::ostringstream o, e;
    const int code = run_zones_sign({in, dir / "ops.pem", "", 7, kGbfsIssued, dir / out, ""}, o, e);
    err = o.str() + e.str();
    return code;
  }
};

TEST_F(ZonesToolGbfs, TheCitysFileIsSignedAsPublishedAndExportedBack) {
  std::string text;
  ASSERT_EQ(sign(city, "city.pb", text), 0) << text;
  EXPECT_NE(text.find("zones sign: version 7, 8 zones, "), std::string::npos) << text;
  EXPECT_EQ(text.find("note:"), std::string::npos) << text;  // nothing without effect in it
  std::ostringstream out, err;
  ASSERT_EQ(run_zones_export({dir / "city.pb", trusted(), "", "", 60}, out, err), 0) << err.str();
  auto back = nlohmann::json::parse(out.str());
  auto original = nlohmann::json::parse(read_text_file(city));
  EXPECT_EQ(back["last_updated"], "2026-09-21T14:13:20Z");  // the bundle's issued_at
  back.erase("last_updated");
  original.erase("last_updated");
  EXPECT_EQ(back, original) << back.dump(1);
  // Into a file, atomically; without keys it says the signature was not checked.
  std::ostringstream o2, e2;
  ASSERT_EQ(run_zones_export({dir / "city.pb", {}, "", dir / "out.json", 0}, o2, e2), 0);
  EXPECT_NE(e2.str().find("signature not checked"), std::string::npos) << e2.str();
  EXPECT_EQ(nlohmann::json::parse(read_text_file(dir / "out.json"))["data"], original["data"]);
  // Another fleet's keys: a gateway would refuse it, so it is not exported.
  std::ostringstream o3, e3;
  EXPECT_EQ(
      run_zones_export({dir / "city.pb",
                        {{"ops", command::Ed25519PrivateKey::generate().public_key().base64()}},
                        "",
                        "",
                        0},
                       o3, e3),
      1);
  EXPECT_NE(e3.str().find("a gateway would refuse it: refused (signature_invalid)"),
            std::string::npos)
      << e3.str();
  EXPECT_TRUE(o3.str().empty());
}

TEST_F(ZonesToolGbfs, ARuleTheBikeCannotEnforceIsRefusedNamingItAndNothingIsWritten) {
  auto doc = nlohmann::json::parse(read_text_file(city));
  doc["data"]["geofencing_zones"]["features"][6]["properties"]["rules"][0]["station_parking"] =
      true;
  doc["data"]["geofencing_zones"]["features"][2]["properties"]["colour"] = "blue";
  std::ofstream(dir / "stations.json") << doc.dump();
  std::string text;
  EXPECT_EQ(sign(dir / "stations.json", "stations.pb", text), 1);
  EXPECT_NE(text.find("stations.json: GBFS data.geofencing_zones.features[6].properties.rules[0]."
                      "station_parking: true is not enforced by the bike"),
            std::string::npos)
      << text;
  EXPECT_FALSE(std::filesystem::exists(dir / "stations.pb"));
  // Without the station rule: signed, the unknown property reported with its place.
  doc["data"]["geofencing_zones"]["features"][6]["properties"]["rules"][0].erase("station_parking");
  std::ofstream(dir / "colour.json", std::ios::trunc) << doc.dump();
  ASSERT_EQ(sign(dir / "colour.json", "colour.pb", text), 0) << text;
  EXPECT_NE(text.find("zones sign: note: data.geofencing_zones.features[2].properties.colour: "
                      "unknown property, ignored (no effect on the bike)"),
            std::string::npos)
      << text;
  // The gateway's own rules apply too: a ring on one line names the zone.
  doc["data"]["geofencing_zones"]["features"][5]["geometry"]["coordinates"] =
      nlohmann::json::parse("[[[[14.5,46.0],[14.51,46.0],[14.52,46.0],[14.5,46.0]]]]");
  std::ofstream(dir / "line.json", std::ios::trunc) << doc.dump();
  EXPECT_EQ(sign(dir / "line.json", "line.pb", text), 1);
  EXPECT_NE(text.find("zone 5 ('gbfs-5'), ring 0: all 3 vertices lie on one line"),
            std::string::npos)
      << text;
  EXPECT_FALSE(std::filesystem::exists(dir / "line.pb"));
}

}  // namespace
}  // namespace fleetgw::geofence
