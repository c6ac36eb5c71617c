// Ride tracks: the simulated ride scenario with GNSS fixes along a staircase route derived from
// the bike's own odometer (1 Hz, with jitter), and the RideTrack rules on their own.

#include <gtest/gtest.h>

#include <algorithm>

#include <cmath>

#include "domain_test_util.h"
#include "fleetgw/v1/ride.pb.h"
#include "gateway/domain/ride_track.h"

namespace fleetgw::domain::testing {
namespace {

constexpr double kLat0 = 52.52;
constexpr double kLon0 = 13.405;
constexpr double kMetrePerDegLat = 111'195.0;

// A staircase of 500 m legs, north then east, at distance `d` metres along it.
gnss::Fix staircase(double d, int i) {
  const int leg = static_cast<int>(d / 500.0);
  const double rest = d - leg * 500.0;
  const double north = (leg + 1) / 2 * 500.0 + (leg % 2 == 0 ? rest : 0.0);
  const double east = leg / 2 * 500.0 + (leg % 2 == 1 ? rest : 0.0);
  // Deterministic jitter of up to 1.5 m, as a receiver wobbles.
  const double jn = 1.5 * std::sin(i * 1.7);
  const double je = 1.5 * std::cos(i * 2.3);
  gnss::Fix p;
  p.lat_deg = kLat0 + (north + jn) / kMetrePerDegLat;
  p.lon_deg = kLon0 + (east + je) / (kMetrePerDegLat * std::cos(kLat0 * M_PI / 180));
  return p;
}

double distance_to_polyline(const gnss::Fix& p, const std::vector<gnss::Fix>& line) {
  double best = 1e18;
  const double k = kMetrePerDegLat * std::cos(kLat0 * M_PI / 180);
  for (std::size_t i = 0; i + 1 < line.size(); ++i) {
    const double ax = line[i].lon_deg * k, ay = line[i].lat_deg * kMetrePerDegLat;
    const double bx = line[i + 1].lon_deg * k, by = line[i + 1].lat_deg * kMetrePerDegLat;
    const double px = p.lon_deg * k, py = p.lat_deg * kMetrePerDegLat;
    const double dx = bx - ax, dy = by - ay, len2 = dx * dx + dy * dy;
    const double t = len2 > 0 ? std::clamp(((px - ax) * dx + (py - ay) * dy) / len2, 0.0, 1.0) : 0;
    best = std::min(best, std::hypot(px - (ax + t * dx), py - (ay + t * dy)));
  }
  return best;
}

TEST(RideTrack, RideRecordCarriesATrackWhoseLengthAgreesWithTheOdometer) {
  Harness h(bundled("ride"));
  std::vector<gnss::Fix> fed;
  double odo0 = -1;
  for (int t = 1; t <= 1750; ++t) {
    h.run_until_offset(t);
    const Truth truth = h.truth_at(h.at(t));
    if (odo0 < 0) odo0 = truth.odo_m;
    gnss::Fix p = staircase(truth.odo_m - odo0, t);
    h.gateway()->trackers().on_position(p);
    if (h.gateway()->trackers().rides().riding()) fed.push_back(p);
  }
  h.send_keyword(0x760, 0x11);  // the rental ends: one-touch LOCK
  h.run_until_offset(1760);
  const std::vector<storage::RideRow> closed = h.out.closed_rides();  // a copy: keep it alive
  ASSERT_EQ(closed.size(), 1u);
  const storage::RideRow& r = closed.front();
  const double odo_m = h.truth_at(Micros(*r.end_us)).odo_m - h.truth_at(Micros(r.start_us)).odo_m;

  v1::RideRecord m;
  for (const auto& p : h.out.rides) {
    if (p.uplink) {
      ASSERT_TRUE(m.ParseFromArray(p.uplink->data(), static_cast<int>(p.uplink->size())));
    }
  }
  ASSERT_TRUE(m.has_start_position() && m.has_end_position() && m.has_track());
  ASSERT_TRUE(m.has_distance_gnss_m());
  EXPECT_NEAR(static_cast<double>(m.distance_gnss_m()), odo_m, 0.03 * odo_m)
      << "GNSS distance vs the odometer, within 3 %";
  EXPECT_NEAR(m.start_position().lat_e7() / 1e7, fed.front().lat_deg, 1e-6);
  EXPECT_NEAR(m.end_position().lon_e7() / 1e7, fed.back().lon_deg, 1e-6);

  // Decode the delta-coded polyline; every fix of the ride lies near it, and it is compact.
  ASSERT_EQ(m.track().lat_e7_delta_size(), m.track().lon_e7_delta_size());
  std::vector<gnss::Fix> line;
  int64_t lat = 0, lon = 0;
  for (int i = 0; i < m.track().lat_e7_delta_size(); ++i) {
    lat += m.track().lat_e7_delta(i);
    lon += m.track().lon_e7_delta(i);
    gnss::Fix p;
    p.lat_deg = lat / 1e7;
    p.lon_deg = lon / 1e7;
    line.push_back(p);
  }
  EXPECT_EQ(m.track().tolerance_m(), 5u);
  ASSERT_GE(line.size(), 2u);
  EXPECT_LT(line.size(), fed.size() / 4) << "simplified: " << line.size() << " of " << fed.size();
  double worst = 0;
  for (const auto& p : fed) worst = std::max(worst, distance_to_polyline(p, line));
  EXPECT_LE(worst, 10.0) << "tolerance 5 m + the 5 m minimum step";
}

TEST(RideTrack, JitterAtAStandstillIsNoDistance) {
  RideTrack t;
  for (int i = 0; i < 600; ++i) t.add(staircase(0, i));  // ten minutes wobbling on the spot
  EXPECT_DOUBLE_EQ(t.distance_m(), 0.0);
  EXPECT_EQ(t.vertices(), 1u);
  ASSERT_TRUE(t.start() && t.end());
}

TEST(RideTrack, MemoryStaysBoundedOnAnEndlessWindingRide) {
  RideTrack t(RideTrackOptions{.max_vertices = 512});
  std::size_t most = 0;
  std::size_t compactions = 0;
  for (int i = 0; i < 50'000; ++i) {  // 350 km of 500 m legs
    const std::size_t before = t.vertices();
    t.add(staircase(i * 7.0, i));
    most = std::max(most, t.vertices());
    if (t.vertices() < before) ++compactions;
  }
  EXPECT_LE(most, 512u);
  // Compacted to half the bound and then allowed to grow back to it: one compaction per ~256
  // new corners, not one per fix (which cost a whole simplification every second on a bike).
  EXPECT_GE(compactions, 50'000u / 512) << "the bound was never reached";
  EXPECT_LE(compactions, 50'000u / 200) << "compactions";
  EXPECT_NEAR(t.distance_m(), 50'000 * 7.0, 0.03 * 50'000 * 7.0);
}

TEST(RideTrack, DouglasPeuckerKeepsCornersAndDropsStraightRuns) {
  std::vector<gnss::Fix> pts;
  for (int i = 0; i <= 100; ++i) {
    gnss::Fix p;
    p.lat_deg = kLat0 + (i <= 50 ? i : 50) * 10.0 / kMetrePerDegLat;
    p.lon_deg =
        kLon0 + (i <= 50 ? 0 : i - 50) * 10.0 / (kMetrePerDegLat * std::cos(kLat0 * M_PI / 180));
    pts.push_back(p);
  }
  const auto s = simplify_track(pts, 5.0);
  ASSERT_EQ(s.size(), 3u);  // start, the corner, end
  EXPECT_EQ(s[1], pts[50]);
}

}  // namespace
}  // namespace fleetgw::domain::testing
