// `fleetgw db export --table rides --format geojson` against the real binary on a store written
// through the real Store: the output is checked by Python's json module against RFC 7946's
// structure (tests/support/check_geojson.py) and read back with nlohmann: one Feature per ride,
// the track as a LineString in [longitude, latitude] order, geometry null without a track, a
// damaged stored track named on stderr; any other table exits 2 naming the supported ones.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "storage/sqlite.h"
#include "storage/store.h"
#include "storage/track_text.h"
#include "tests/config/cli_test_util.h"
#include "tests/config/store_fixture.h"
#include "tests/support/temp_dir.h"

namespace fleetgw::testing::db_geojson {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr std::int64_t kSec = 1'000'000;
constexpr std::int64_t kT0 = 1732701600LL * kSec;  // 2024-11-27T10:00:00Z

// Four rides: one with a 3-point track, one that never had a fix, one whose fixes never moved
// (a single position), one still open with a track so far; then a fifth whose stored track is
// damaged (written past the Store, which would refuse it).
void make_store(const fs::path& path) {
  {
    storage::Store store(storage::StoreOptions{.path = path.string()});
    storage::Batch b;
    b.now_us = kT0;
    storage::RideRow tracked = closed_ride("ride-tracked", kT0, 1.2);
    tracked.start_lat_deg = 52.52;
    tracked.start_lon_deg = 13.405;
    tracked.end_lat_deg = 52.5209;
    tracked.end_lon_deg = 13.4071;
    tracked.gnss_distance_m = 243.6;
    tracked.track = storage::track_text(
        std::vector<storage::TrackPoint>{{52.52, 13.405}, {52.5209, 13.405}, {52.5209, 13.4071}});
    b.rides.push_back({tracked, std::nullopt});
    b.rides.push_back({closed_ride("ride-nofix", kT0 + 3600 * kSec, 3.0), std::nullopt});
    storage::RideRow still = closed_ride("ride-still", kT0 + 7200 * kSec, 0.1);
    still.start_lat_deg = still.end_lat_deg = -33.8688197;
    still.start_lon_deg = still.end_lon_deg = 151.2092955;
    still.gnss_distance_m = 0;
    still.track = storage::track_text(std::vector<storage::TrackPoint>{{-33.8688197, 151.2092955}});
    b.rides.push_back({still, std::nullopt});
    storage::RideRow open = closed_ride("ride-open", kT0 + 9000 * kSec, 0.4);
    open.state = storage::RideState::kOpen;
    open.end_us.reset();
    open.start_lat_deg = 48.1;
    open.start_lon_deg = 11.5;
    open.end_lat_deg = 48.101;
    open.end_lon_deg = 11.5;
    open.gnss_distance_m = 111.2;
    open.track =
        storage::track_text(std::vector<storage::TrackPoint>{{48.1, 11.5}, {48.101, 11.5}});
    b.rides.push_back({open, std::nullopt});
    b.rides.push_back({closed_ride("ride-damaged", kT0 + 10000 * kSec, 1.0), std::nullopt});
    const auto r = store.write(b);
    ASSERT_TRUE(r.ok()) << r.status().message;
  }
  storage::Database raw(path.string());
  raw.exec("UPDATE rides SET track = '[[13.4,52.5],[200,52.5]]' WHERE ride_id = 'ride-damaged'");
}

class DbGeojson : public ::testing::Test {
 protected:
  void SetUp() override { make_store(db_); }
  Result db(std::vector<std::string> args) {
    args.insert(args.begin(), {FLEETGW_BIN, "db", "export", "--db", db_.string()});
    return run(args, dir_.path());
  }
  // Python's json module and the RFC 7946 structure rules: the summary it prints.
  json python_check(const std::string& text) {
    const fs::path file = dir_.path() / "rides.geojson";
    write_text_file(file, text);
    const Result r =
        run({"python3", std::string(FLEETGW_SOURCE_DIR) + "/tests/support/check_geojson.py",
             file.string()},
            dir_.path());
    EXPECT_EQ(r.code, 0) << r.err << "\n" << text;
    return json::parse(r.out, nullptr, false);
  }

  TempDir dir_{"fleetgw-db-geojson"};
  fs::path db_ = dir_.path() / "fleetgw.db";
};

TEST_F(DbGeojson, RidesAreAFeatureCollectionThatPythonReadsAsRfc7946) {
  const Result r = db({"--table", "rides", "--format", "geojson"});
  ASSERT_EQ(r.code, 0) << r.err;
  const json summary = python_check(r.out);
  ASSERT_TRUE(summary.is_object()) << r.out;
  EXPECT_EQ(summary["features"], 5);
  EXPECT_EQ(summary["geometry_types"], (json{{"LineString", 2}, {"Point", 1}}));
  EXPECT_EQ(summary["null_geometries"], 2);
  EXPECT_EQ(summary["linestring_points"], (json{3, 0, 0, 2, 0}));
  EXPECT_EQ(summary["ids"],
            (json{"ride-tracked", "ride-nofix", "ride-still", "ride-open", "ride-damaged"}));
  // The damaged track: named with its ride and problem, the export goes on.
  EXPECT_NE(r.err.find("ride 'ride-damaged': track: position 1: longitude 200 is outside"),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("5 rows"), std::string::npos) << r.err;

  // Read back: longitude first, the properties are the ride's columns with ISO times.
  const json doc = json::parse(r.out);
  const json& tracked = doc["features"][0];
  EXPECT_EQ(tracked["geometry"]["coordinates"],
            (json{{13.405, 52.52}, {13.405, 52.5209}, {13.4071, 52.5209}}));
  const json& p = tracked["properties"];
  EXPECT_EQ(p["ride_id"], "ride-tracked");
  EXPECT_EQ(p["start"], "2024-11-27T10:00:00Z");
  EXPECT_EQ(p["end"], "2024-11-27T10:28:00Z");
  EXPECT_DOUBLE_EQ(p["distance_km"].get<double>(), 1.2);
  EXPECT_DOUBLE_EQ(p["gnss_distance_m"].get<double>(), 243.6);
  EXPECT_DOUBLE_EQ(p["duration_s"].get<double>(), 28 * 60);
  EXPECT_DOUBLE_EQ(p["start_lon_deg"].get<double>(), 13.405);
  EXPECT_EQ(p["state"], "closed");
  EXPECT_TRUE(p["assist_time_json"].is_object());
  EXPECT_FALSE(p.contains("track")) << "the track is the geometry";
  EXPECT_FALSE(p.contains("id"));
  const json& nofix = doc["features"][1];
  EXPECT_TRUE(nofix["geometry"].is_null());
  EXPECT_TRUE(nofix["properties"]["gnss_distance_m"].is_null());
  EXPECT_TRUE(nofix["properties"]["start_lat_deg"].is_null());
  EXPECT_EQ(doc["features"][2]["geometry"],
            (json{{"type", "Point"}, {"coordinates", {151.2092955, -33.8688197}}}));
  EXPECT_TRUE(doc["features"][3]["properties"]["end"].is_null()) << "still open";
}

TEST_F(DbGeojson, SinceSelectsRidesAndAnEmptyStoreIsAnEmptyCollection) {
  const Result r =
      db({"--table", "rides", "--format", "geojson", "--since", "2024-11-27T11:30:00Z"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(python_check(r.out)["ids"], (json{"ride-still", "ride-open", "ride-damaged"}));
  const Result none = db({"--table", "rides", "--format", "geojson", "--since", "2030-01-01"});
  ASSERT_EQ(none.code, 0) << none.err;
  EXPECT_EQ(python_check(none.out)["features"], 0);
}

TEST_F(DbGeojson, AnyOtherTableIsAUsageErrorNamingTheTablesThatHaveGeometry) {
  for (const char* table : {"faults", "fault_events", "telemetry", "zone_events", "no_such"}) {
    const Result r = db({"--table", table, "--format", "geojson"});
    EXPECT_EQ(r.code, 2) << table << ": " << r.err;
    EXPECT_NE(r.err.find("--format geojson"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(std::string("'") + table + "'"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("supports: rides"), std::string::npos) << r.err;
    EXPECT_TRUE(r.out.empty()) << r.out;
  }
  // The other formats of rides are unchanged: the track is one more column.
  const Result jsonl = db({"--table", "rides"});
  ASSERT_EQ(jsonl.code, 0) << jsonl.err;
  const json first = json::parse(lines_of(jsonl.out).at(0));
  EXPECT_EQ(first["track"], "[[13.405,52.52],[13.405,52.5209],[13.4071,52.5209]]");
  EXPECT_DOUBLE_EQ(first["gnss_distance_m"].get<double>(), 243.6);
}

}  // namespace
}  // namespace fleetgw::testing::db_geojson
