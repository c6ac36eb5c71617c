// The ride's track in the SQLite row (schema v6): the checkpoints and the closed ride carry the
// same start, end, GNSS distance and simplified track as the RideRecord payload; a ride resumed
// after a restart keeps the positions from before it; a damaged stored track is dropped, never
// a reason to lose the ride.

#include <gtest/gtest.h>

#include <cmath>

#include "domain_test_util.h"
#include "fleetgw/v1/ride.pb.h"
#include "storage/sqlite.h"
#include "storage/track_text.h"

namespace fleetgw::domain::testing::track_row {
namespace {

constexpr double kLat0 = 52.52;
constexpr double kLon0 = 13.405;
constexpr double kMetrePerDegLat = 111'195.0;

// 1 km legs, north then east, `d` metres along (the bike's own odometer drives it).
gnss::Fix route_at(double d) {
  const int leg = static_cast<int>(d / 1000.0);
  const double rest = d - leg * 1000.0;
  const double north = (leg + 1) / 2 * 1000.0 + (leg % 2 == 0 ? rest : 0.0);
  const double east = leg / 2 * 1000.0 + (leg % 2 == 1 ? rest : 0.0);
  gnss::Fix p;
  p.lat_deg = kLat0 + north / kMetrePerDegLat;
  p.lon_deg = kLon0 + east / (kMetrePerDegLat * std::cos(kLat0 * M_PI / 180));
  return p;
}

// Runs the bundled ride with a fix every second from `from_s` to `to_s` (while riding).
void ride_with_fixes(Harness& h, int from_s, int to_s, double odo0,
                     std::vector<gnss::Fix>& fed) {
  for (int t = from_s; t <= to_s; ++t) {
    h.run_until_offset(t);
    const gnss::Fix p = route_at(h.truth_at(h.at(t)).odo_m - odo0);
    h.gateway()->trackers().on_position(p);
    if (h.gateway()->trackers().rides().riding()) fed.push_back(p);
  }
}

std::vector<storage::TrackPoint> track_of(const storage::RideRow& r) {
  EXPECT_TRUE(r.track.has_value()) << r.ride_id;
  if (!r.track) return {};
  const auto parsed = storage::parse_track_text(*r.track);
  EXPECT_TRUE(parsed.ok()) << parsed.error;
  return parsed.points;
}

v1::RideRecord ride_record(const Collected& out) {
  v1::RideRecord m;
  for (const auto& p : out.rides) {
    if (p.uplink) {
      EXPECT_TRUE(m.ParseFromArray(p.uplink->data(), static_cast<int>(p.uplink->size())));
    }
  }
  return m;
}

TEST(RideTrackRow, ResumedAfterARestartTheRowKeepsTheWholeTrackAsThePayloadDoes) {
  TempDir dir;
  const auto db = dir.file("fleetgw.db");
  Harness h(bundled("ride"), DomainConfig{}, db);
  h.run_until_offset(0.5);  // the first truth sample: the route starts at this odometer
  const double odo0 = h.truth_at(h.at(0.5)).odo_m;
  std::vector<gnss::Fix> fed;
  ride_with_fixes(h, 1, 700, odo0, fed);
  ASSERT_TRUE(h.gateway()->trackers().rides().riding());
  ASSERT_FALSE(fed.empty());
  const std::string id = h.gateway()->trackers().rides().current(h.bus().now())->ride_id;

  // The checkpoints already carry the track: an open row with positions, start = first fix.
  h.stop_gateway();
  {
    storage::Store store(storage::StoreOptions{.path = db.string()});
    const auto open = store.ride(id);
    ASSERT_TRUE(open && open->state == storage::RideState::kOpen);
    ASSERT_TRUE(open->start_lat_deg && open->gnss_distance_m);
    EXPECT_NEAR(*open->start_lat_deg, fed.front().lat_deg, 1e-9);
    EXPECT_GT(*open->gnss_distance_m, 2000.0);
    EXPECT_GE(track_of(*open).size(), 3u) << "two corners by 700 s";
  }
  h.run_until_offset(701);
  h.start_gateway();  // restored from the open row, positions included
  ride_with_fixes(h, 702, 1750, odo0, fed);
  h.send_keyword(0x760, 0x11);
  h.run_until_offset(1760);
  h.stop_gateway();

  storage::Store store(storage::StoreOptions{.path = db.string()});
  const auto r = store.ride(id);
  ASSERT_TRUE(r && r->state == storage::RideState::kClosed);
  ASSERT_TRUE(r->start_lat_deg && r->start_lon_deg && r->end_lat_deg && r->end_lon_deg);
  EXPECT_NEAR(*r->start_lat_deg, fed.front().lat_deg, 1e-9) << "the start from before the restart";
  EXPECT_NEAR(*r->start_lon_deg, fed.front().lon_deg, 1e-9);
  EXPECT_NEAR(*r->end_lat_deg, fed.back().lat_deg, 1e-9);
  EXPECT_NEAR(*r->end_lon_deg, fed.back().lon_deg, 1e-9);
  const double odo_m = h.truth_at(Micros(*r->end_us)).odo_m - h.truth_at(Micros(r->start_us)).odo_m;
  ASSERT_TRUE(r->gnss_distance_m);
  EXPECT_NEAR(*r->gnss_distance_m, odo_m, 0.03 * odo_m) << "the whole ride, not since the restart";

  // The row and the RideRecord say the same.
  const v1::RideRecord m = ride_record(h.out);
  ASSERT_TRUE(m.has_track());
  EXPECT_NEAR(static_cast<double>(m.distance_gnss_m()), *r->gnss_distance_m, 1.0);
  EXPECT_EQ(m.start_position().lat_e7(), std::lround(*r->start_lat_deg * 1e7));
  const auto points = track_of(*r);
  ASSERT_EQ(static_cast<int>(points.size()), m.track().lat_e7_delta_size());
  std::int64_t lat = 0, lon = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    lat += m.track().lat_e7_delta(static_cast<int>(i));
    lon += m.track().lon_e7_delta(static_cast<int>(i));
    EXPECT_EQ(std::llround(points[i].lat_deg * 1e7), lat) << i;
    EXPECT_EQ(std::llround(points[i].lon_deg * 1e7), lon) << i;
  }
  // A staircase of 1 km legs: the corners and the ends, not a vertex per fix.
  EXPECT_GE(points.size(), 6u);
  EXPECT_LT(points.size(), 40u);
}

TEST(RideTrackRow, ADamagedStoredTrackIsDroppedAndTheRideStillCloses) {
  TempDir dir;
  const auto db = dir.file("fleetgw.db");
  Harness h(bundled("ride"), DomainConfig{}, db);
  h.run_until_offset(0.5);  // the first truth sample: the route starts at this odometer
  const double odo0 = h.truth_at(h.at(0.5)).odo_m;
  std::vector<gnss::Fix> fed;
  ride_with_fixes(h, 1, 400, odo0, fed);
  const std::string id = h.gateway()->trackers().rides().current(h.bus().now())->ride_id;
  h.stop_gateway();
  {
    storage::Database raw(db.string());
    raw.exec("UPDATE rides SET track = '[[13.4,52.5],[13.4]]' WHERE state = 'open'");
  }
  h.start_gateway();
  std::vector<gnss::Fix> after;
  ride_with_fixes(h, 401, 1750, odo0, after);
  h.send_keyword(0x760, 0x11);
  h.run_until_offset(1760);
  EXPECT_EQ(h.gateway()->store()->health().failed_writes, 0u) << "the row is never refused";
  h.stop_gateway();

  storage::Store store(storage::StoreOptions{.path = db.string()});
  const auto r = store.ride(id);
  ASSERT_TRUE(r && r->state == storage::RideState::kClosed) << "the ride is not lost";
  ASSERT_TRUE(r->start_lat_deg);
  ASSERT_FALSE(after.empty());
  EXPECT_NEAR(*r->start_lat_deg, after.front().lat_deg, 1e-9) << "positions since the restart";
  EXPECT_TRUE(storage::parse_track_text(*r->track).ok());
}

}  // namespace
}  // namespace fleetgw::domain::testing::track_row
