// Schema v6, where a ride went (issue 14): a v5 store migrates in place (its rides keep their
// data and get NULL positions), rides round-trip their start/end position, GNSS distance and
// track, bad positions are refused naming the entry and field, and the track's text form
// (storage/track_text.h) is GeoJSON's coordinate syntax and refuses anything else.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "storage/schema.h"
#include "storage/store.h"
#include "storage/track_text.h"
#include "storage_test_util.h"

namespace fleetgw::storage {
namespace {

using testing::TempDir;

RideRow ride_with_track(const std::string& id) {
  RideRow r = testing::ride_named(id, 1'000'000, true);
  r.start_lat_deg = 52.52;
  r.start_lon_deg = 13.405;
  r.end_lat_deg = 52.5209;
  r.end_lon_deg = 13.4071;
  r.gnss_distance_m = 243.5;
  r.track =
      track_text(std::vector<TrackPoint>{{52.52, 13.405}, {52.5209, 13.405}, {52.5209, 13.4071}});
  return r;
}

TEST(RideTrackStore, V5RidesMigrateInPlaceWithNullPositions) {
  TempDir dir;
  const std::string path = dir.file("v5.db");
  {
    Database db(path);
    migrate(db, 5);
    db.exec(
        "INSERT INTO rides (ride_id, state, start_us, end_us, distance_km) "
        "VALUES ('r-v5', 'closed', 5, 10, 6.25)");
  }
  Store store(StoreOptions{.path = path});
  const auto old = store.ride("r-v5");
  ASSERT_TRUE(old.has_value());
  EXPECT_DOUBLE_EQ(old->distance_km, 6.25);
  EXPECT_FALSE(old->start_lat_deg || old->start_lon_deg || old->end_lat_deg || old->end_lon_deg);
  EXPECT_FALSE(old->gnss_distance_m);
  EXPECT_FALSE(old->track);
  Database db(path);
  EXPECT_EQ(schema_version(db), kSchemaVersion);
  EXPECT_TRUE(db.query_int64("SELECT count(*) FROM rides WHERE track IS NULL AND "
                             "start_lat_deg IS NULL AND gnss_distance_m IS NULL") == 1);
}

TEST(RideTrackStore, PositionsRoundTripAndAnUpsertReplacesThem) {
  TempDir dir;
  Store store(StoreOptions{.path = dir.file("s.db")});
  RideRow open = testing::ride_named("r1", 1'000'000, false);
  Batch b;
  b.now_us = 2'000'000;
  b.rides.push_back({open, std::nullopt});
  ASSERT_TRUE(store.write(b).ok());
  EXPECT_FALSE(store.ride("r1")->track) << "no fix yet: NULL";

  RideRow closed = ride_with_track("r1");
  b.rides.clear();
  b.rides.push_back({closed, std::nullopt});
  ASSERT_TRUE(store.write(b).ok());
  const auto back = store.ride("r1");
  ASSERT_TRUE(back.has_value());
  RideRow expected = closed;
  expected.id = back->id;
  EXPECT_EQ(*back, expected);
  EXPECT_EQ(*back->track, "[[13.405,52.52],[13.405,52.5209],[13.4071,52.5209]]");
}

TEST(RideTrackStore, BadPositionsAreRefusedNamingTheField) {
  TempDir dir;
  Store store(StoreOptions{.path = dir.file("s.db")});
  auto refused = [&](const RideRow& r) {
    Batch b;
    b.now_us = 2'000'000;
    b.rides.push_back({r, std::nullopt});
    const auto w = store.write(b);
    return w.ok() ? std::string() : w.status().message;
  };
  RideRow r = ride_with_track("r2");
  r.end_lon_deg.reset();
  EXPECT_NE(
      refused(r).find("Batch.rides[0].end_lat_deg: latitude and longitude must come together"),
      std::string::npos)
      << refused(r);
  r = ride_with_track("r2");
  r.start_lat_deg = 91;
  EXPECT_NE(refused(r).find("rides[0].start_lat_deg: position out of range"), std::string::npos);
  r = ride_with_track("r2");
  r.gnss_distance_m = -1;
  EXPECT_NE(refused(r).find("rides[0].gnss_distance_m"), std::string::npos);
  r = ride_with_track("r2");
  r.track = "[[13.4,52.5],[13.4]]";
  EXPECT_NE(refused(r).find("rides[0].track: position 1: not an array of two numbers"),
            std::string::npos)
      << refused(r);
  EXPECT_FALSE(store.ride("r2").has_value()) << "nothing of a refused batch is stored";
}

TEST(TrackText, GeoJsonCoordinatesAtOneTenMillionthOfADegree) {
  const std::vector<TrackPoint> points = {
      {52.52, 13.405}, {-33.8688197, 151.2092955}, {0.00000004, -0.00000006}, {-90, 180}};
  const std::string text = track_text(points);
  EXPECT_EQ(text, "[[13.405,52.52],[151.2092955,-33.8688197],[-0.0000001,0],[180,-90]]");
  const auto doc = nlohmann::json::parse(text);
  ASSERT_TRUE(doc.is_array());
  EXPECT_DOUBLE_EQ(doc[1][0].get<double>(), 151.2092955) << "longitude first (RFC 7946)";
  const auto parsed = parse_track_text(text);
  ASSERT_TRUE(parsed.ok()) << parsed.error;
  ASSERT_EQ(parsed.points.size(), 4u);
  EXPECT_DOUBLE_EQ(parsed.points[1].lat_deg, -33.8688197);
  EXPECT_DOUBLE_EQ(parsed.points[1].lon_deg, 151.2092955);
  EXPECT_EQ(track_text({}), "[]");
  EXPECT_TRUE(parse_track_text("[]").ok());
}

TEST(TrackText, AnythingElseIsRefusedSayingWhere) {
  const std::pair<const char*, const char*> cases[] = {
      {"", "not valid JSON"},
      {"[[13.4,52.5]", "not valid JSON"},
      {"{\"type\":\"LineString\"}", "not a JSON array"},
      {"[[13.4,52.5],\"x\"]", "position 1: not an array of two numbers"},
      {"[[13.4,52.5,7]]", "position 0: not an array of two numbers"},
      {"[[13.4,null]]", "position 0: not an array of two numbers"},
      {"[[13.4,52.5],[181,52.5]]", "position 1: longitude 181 is outside -180..180"},
      {"[[13.4,-90.5]]", "position 0: latitude -90.5 is outside -90..90"},
  };
  for (const auto& [text, error] : cases) {
    const auto parsed = parse_track_text(text);
    EXPECT_FALSE(parsed.ok()) << text;
    EXPECT_NE(parsed.error.find(error), std::string::npos) << text << ": " << parsed.error;
    EXPECT_TRUE(parsed.points.empty()) << text;
  }
}

}  // namespace
}  // namespace fleetgw::storage
