// `fleetgw zones sign|check` as functions: GeoJSON drawn on a map into a signed bundle a gateway
// accepts, every malformed input refused with where it is, and a bundle judged against the one
// in force.
#include "gateway/geofence/zone_tool.h"

#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "gateway/command/ed25519.h"
#include "gateway/geofence/zone_geojson.h"
#include "tests/support/temp_dir.h"

namespace fleetgw::geofence {
namespace {

const Micros kIssued = std::chrono::seconds(1'790'000'000);

// Berlin's centre: an operating area, a slow zone with a hole, a no-parking square.
const char* const kCityGeojson = R"({
  "type": "FeatureCollection",
  "features": [
    {"type": "Feature", "properties": {"id": "city", "kind": "operating_area", "name": "Mitte"},
     "geometry": {"type": "Polygon", "coordinates": [
       [[13.35, 52.50], [13.45, 52.50], [13.45, 52.54], [13.35, 52.54], [13.35, 52.50]]]}},
    {"type": "Feature", "id": "old-town",
     "properties": {"kind": "slow", "speed_limit_kmh": 15, "name": "Altstadt \u00e4"},
     "geometry": {"type": "Polygon", "coordinates": [
       [[13.39, 52.51], [13.42, 52.51], [13.42, 52.53], [13.39, 52.53]],
       [[13.40, 52.515], [13.41, 52.515], [13.41, 52.52], [13.40, 52.52]]]}},
    {"type": "Feature", "properties": {"id": "station", "kind": "no_parking"},
     "geometry": {"type": "MultiPolygon", "coordinates": [
       [[[13.36, 52.52], [13.37, 52.52], [13.37, 52.525]]],
       [[[13.43, 52.52], [13.44, 52.52], [13.44, 52.525]]]]}}
  ]})";

const std::string kTriangle = R"([[[13.35,52.50],[13.45,52.50],[13.45,52.54]]])";

std::string refusal(std::string_view text) {
  auto r = bundle_from_geojson(text, 1, kIssued);
  auto* e = std::get_if<std::string>(&r);
  return e ? *e : "accepted";
}

TEST(ZonesGeojson, AMapDrawingBecomesABundle) {
  auto r = bundle_from_geojson(kCityGeojson, 4, kIssued);
  ASSERT_TRUE(std::holds_alternative<v1::ZoneBundle>(r)) << std::get<std::string>(r);
  const auto& b = std::get<v1::ZoneBundle>(r);
  EXPECT_EQ(b.version(), 4u);
  EXPECT_EQ(b.issued_at_us(), kIssued.count());
  ASSERT_EQ(b.zones_size(), 3);
  EXPECT_EQ(b.zones(1).id(), "old-town");  // the Feature's own id
  EXPECT_EQ(b.zones(1).kind(), v1::ZONE_KIND_SLOW);
  EXPECT_EQ(b.zones(1).speed_limit_kmh(), 15u);
  EXPECT_EQ(b.zones(1).name(), "Altstadt \xc3\xa4");
  EXPECT_EQ(b.zones(1).rings_size(), 2);
  EXPECT_EQ(b.zones(2).rings_size(), 2);  // two polygons
  // [lon, lat] in, lat_e7/lon_e7 out.
  EXPECT_EQ(b.zones(0).rings(0).lat_e7(0), 525'000'000);
  EXPECT_EQ(b.zones(0).rings(0).lon_e7(0), 133'500'000);
}

TEST(ZonesGeojson, MalformedInputIsRefusedSayingWhere) {
  EXPECT_EQ(refusal("{"), "not JSON");
  EXPECT_EQ(refusal(R"({"type": "Feature"})"),
            "not a GeoJSON FeatureCollection with a \"features\" array");
  const std::string head = R"({"type":"FeatureCollection","features":[)";
  auto one = [&](const std::string& props, const std::string& coords = kTriangle,
                 const std::string& type = "Polygon") {
    return refusal(head + R"({"type":"Feature","properties":)" + props +
                   R"(,"geometry":{"type":")" + type + R"(","coordinates":)" + coords + "}}]}");
  };
  EXPECT_EQ(one(R"({"id":"a","kind":"slow","speed_limit_kmh":15})"), "accepted");
  EXPECT_EQ(one(R"({"kind":"slow"})"), "feature 0: no string \"id\" in its properties");
  EXPECT_EQ(one(R"({"id":"a","kind":"fast"})"),
            "feature 0 ('a'): \"kind\" must be \"operating_area\", \"slow\", \"no_ride\", "
            "\"no_parking\" or \"no_start\"");
  EXPECT_EQ(one(R"({"id":"a","kind":"slow","speed_limit_kmh":-3})"),
            "feature 0 ('a'): \"speed_limit_kmh\" must be a whole number of km/h in 0..255");
  // A non-finite coordinate: JSON cannot even carry one (1e999 overflows a double).
  EXPECT_EQ(one(R"({"id":"a","kind":"slow","speed_limit_kmh":15})",
                R"([[[13.35,52.50],[13.45,1e999],[13.45,52.54]]])"),
            "not JSON");
  EXPECT_EQ(one(R"({"id":"a","kind":"no_ride"})", R"([[[13.35,52.50],[13.45,-91],[13.4,52.6]]])"),
            "feature 0 ('a'), ring 0: position 1: latitude -91 is not a number in -90..90");
  EXPECT_EQ(one(R"({"id":"a","kind":"no_ride"})", R"([[[13.35,52.50],[190,52.5],[13.4,52.6]]])"),
            "feature 0 ('a'), ring 0: position 1: longitude 190 is not a number in -180..180");
  EXPECT_EQ(one(R"({"id":"a","kind":"no_ride"})", R"([[[13.35,52.50],["x",52.5],[13.4,52.6]]])"),
            "feature 0 ('a'), ring 0: position 1: not [longitude, latitude]");
  EXPECT_EQ(one(R"({"id":"a","kind":"no_ride"})", kTriangle, "LineString"),
            "feature 0 ('a'): geometry must be a Polygon or a MultiPolygon");
  // The gateway's own rules apply too.
  EXPECT_EQ(one(R"({"id":"a","kind":"no_ride"})", R"([[[13.35,52.50],[13.45,52.50]]])"),
            "zone 0 ('a'), ring 0: 2 distinct vertices (at least 3 needed)");
  // Issue 24: two points drawn back and forth, and a "polygon" along one street.
  EXPECT_EQ(one(R"({"id":"a","kind":"no_ride"})",
                R"([[[13.35,52.50],[13.45,52.50],[13.35,52.50],[13.45,52.50]]])"),
            "zone 0 ('a'), ring 0: 2 distinct vertices (at least 3 needed)");
  EXPECT_EQ(one(R"({"id":"a","kind":"no_ride"})",
                R"([[[13.35,52.50],[13.40,52.50],[13.45,52.50],[13.35,52.50]]])"),
            "zone 0 ('a'), ring 0: all 3 vertices lie on one line (within 0.1 m: the ring "
            "encloses no area)");
  EXPECT_EQ(one(R"({"id":"a","kind":"slow"})"),
            "zone 0 ('a'): a slow zone needs speed_limit_kmh in 1..255, not 0");
}

class ZonesTool : public ::testing::Test {
 protected:
  fleetgw::testing::TempDir dir{"zones-tool"};
  command::Ed25519PrivateKey key = command::Ed25519PrivateKey::generate();
  std::map<std::string, std::string> trusted{{"ops", key.public_key().base64()}};

  void SetUp() override {
    key.write_pem(dir / "ops.pem");
    std::ofstream(dir / "city.geojson") << kCityGeojson;
  }
  int sign(std::uint64_t version, const std::string& out_name, std::string* err_text = nullptr,
           const std::string& vehicle = "") {
    std::ostringstream out, err;
    const int rc = run_zones_sign(
        {dir / "city.geojson", dir / "ops.pem", "", version, kIssued, dir / out_name, vehicle}, out,
        err);
    if (err_text) *err_text = out.str() + err.str();
    return rc;
  }
  int check(const std::string& name, std::optional<std::string> in_force, std::string& out_text,
            const std::string& vehicle = "") {
    std::ostringstream out, err;
    std::optional<std::filesystem::path> in;
    if (in_force) in = dir / *in_force;
    const int rc = run_zones_check({dir / name, trusted, in, vehicle}, out, err);
    out_text = out.str() + err.str();
    return rc;
  }
};

TEST_F(ZonesTool, SignedByTheToolAcceptedByTheCheckAsByAGateway) {
  ASSERT_EQ(sign(5, "v5.pb"), 0);
  ASSERT_EQ(sign(4, "v4.pb"), 0);
  std::string text;
  EXPECT_EQ(check("v5.pb", std::nullopt, text), 0) << text;
  EXPECT_NE(text.find("accepted: version 5 in force: 3 zones"), std::string::npos) << text;
  EXPECT_NE(text.find("old-town  slow  8 vertices  15 km/h  \"Altstadt"), std::string::npos)
      << text;
  // Against the gateway's stored bundle: older refused, the same one already in force.
  EXPECT_EQ(check("v4.pb", "v5.pb", text), 1);
  EXPECT_NE(text.find("refused (not_newer): version 4 is older than version 5 in force"),
            std::string::npos)
      << text;
  EXPECT_EQ(check("v5.pb", "v5.pb", text), 0);
  EXPECT_NE(text.find("already_in_force"), std::string::npos) << text;
  // Another fleet's keys: refused.
  trusted = {{"ops", command::Ed25519PrivateKey::generate().public_key().base64()}};
  EXPECT_EQ(check("v5.pb", std::nullopt, text), 1);
  EXPECT_NE(text.find("signature_invalid"), std::string::npos) << text;
}

// Issue 24: `zones sign --vehicle` binds a bundle to one vehicle; `zones check --vehicle`
// judges it as that vehicle's gateway would.
TEST_F(ZonesTool, ABundleSignedForOneVehicleIsRefusedByAnother) {
  std::string text;
  ASSERT_EQ(sign(6, "bike-7.pb", &text, "bike-7"), 0) << text;
  EXPECT_NE(text.find("version 6, 3 zones, 18 vertices, for vehicle 'bike-7', signed by 'ops'"),
            std::string::npos)
      << text;
  EXPECT_EQ(check("bike-7.pb", std::nullopt, text, "bike-7"), 0) << text;
  EXPECT_NE(text.find("accepted: version 6 in force: 3 zones, 18 vertices, for vehicle 'bike-7'"),
            std::string::npos)
      << text;
  EXPECT_EQ(check("bike-7.pb", std::nullopt, text, "bike-8"), 1) << text;
  EXPECT_NE(text.find("refused (wrong_vehicle): signed for vehicle 'bike-7'"), std::string::npos)
      << text;
  // No vehicle given: accepted, saying whose it is.
  EXPECT_EQ(check("bike-7.pb", std::nullopt, text), 0) << text;
  EXPECT_NE(text.find("for vehicle 'bike-7'"), std::string::npos) << text;
  EXPECT_EQ(sign(6, "bad.pb", &text, "bike 7"), 1);
  EXPECT_NE(text.find("--vehicle 'bike 7' must be 1..64 characters"), std::string::npos) << text;
  EXPECT_FALSE(std::filesystem::exists(dir / "bad.pb"));
}

TEST_F(ZonesTool, SignRefusesWithoutWritingAnything) {
  std::string err;
  EXPECT_EQ(sign(0, "v0.pb", &err), 1);
  EXPECT_NE(err.find("--version"), std::string::npos) << err;
  std::ofstream(dir / "city.geojson", std::ios::trunc) << R"({"type":"FeatureCollection",
    "features":[{"type":"Feature","properties":{"id":"x","kind":"slow","speed_limit_kmh":900},
    "geometry":{"type":"Polygon","coordinates":[[[0,0],[1,0],[1,1]]]}}]})";
  EXPECT_EQ(sign(1, "bad.pb", &err), 1);
  EXPECT_NE(err.find("city.geojson: feature 0 ('x')"), std::string::npos) << err;
  EXPECT_FALSE(std::filesystem::exists(dir / "bad.pb"));
  std::ostringstream out, e2;
  EXPECT_EQ(
      run_zones_sign({dir / "missing.geojson", dir / "ops.pem", "", 1, kIssued, dir / "m.pb", ""},
                     out, e2),
      1);
  EXPECT_NE(e2.str().find("missing.geojson"), std::string::npos) << e2.str();
}

}  // namespace
}  // namespace fleetgw::geofence
