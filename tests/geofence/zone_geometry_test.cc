// ZonePolygon: inside/outside/near the boundary, holes, self-intersecting rings, and the band
// index agreeing with a plain scan of every edge on a 10,000-vertex zone.
#include "gateway/geofence/zone_geometry.h"

#include <gtest/gtest.h>

#include <random>

#include "tests/geofence/zone_test_util.h"

namespace fleetgw::geofence {
namespace {

using namespace testing;

Where where(const ZonePolygon& z, double east_m, double north_m, double margin_m) {
  return z.locate(lat_at(north_m), lon_at(east_m), margin_m);
}

TEST(ZoneGeometry, SquareInsideOutsideAndWithinTheMargin) {
  const std::vector<Ring> rings{rect(-100, -100, 100, 100)};
  const auto z = ZonePolygon::build(rings);
  EXPECT_EQ(where(z, 0, 0, 10), Where::kInside);
  EXPECT_EQ(where(z, 85, 0, 10), Where::kInside);           // 15 m inside
  EXPECT_EQ(where(z, 95, 0, 10), Where::kNearBoundary);     // 5 m inside
  EXPECT_EQ(where(z, 105, 0, 10), Where::kNearBoundary);    // 5 m outside
  EXPECT_EQ(where(z, 115, 0, 10), Where::kOutside);         // 15 m outside
  EXPECT_EQ(where(z, 107, 107, 10), Where::kNearBoundary);  // 9.9 m from the corner
  EXPECT_EQ(where(z, 108, 108, 10), Where::kOutside);       // 11.3 m from the corner
  EXPECT_EQ(where(z, 0, 5000, 10), Where::kOutside);
  EXPECT_EQ(where(z, 95, 0, 0), Where::kInside);  // no margin: a plain point-in-polygon
  EXPECT_NEAR(z.distance_to_boundary_m(lat_at(0), lon_at(40)), 60.0, 0.3);
  EXPECT_EQ(z.vertex_count(), 4u);
}

TEST(ZoneGeometry, AHoleIsOutsideAndAnIslandInItInsideAgain) {
  const std::vector<Ring> rings{rect(-500, -500, 500, 500), rect(-200, -200, 200, 200),
                                rect(-50, -50, 50, 50)};
  const auto z = ZonePolygon::build(rings);
  EXPECT_EQ(where(z, 350, 0, 10), Where::kInside);   // in the outer ring
  EXPECT_EQ(where(z, 120, 0, 10), Where::kOutside);  // in the hole
  EXPECT_EQ(where(z, 0, 0, 10), Where::kInside);     // on the island in the hole
  EXPECT_EQ(where(z, 203, 0, 10), Where::kNearBoundary);
}

TEST(ZoneGeometry, ASelfIntersectingRingFollowsTheEvenOddRule) {
  // A bow tie: two triangles meeting at the origin.
  const std::vector<Ring> rings{
      {vertex_at(-100, -100), vertex_at(100, 100), vertex_at(100, -100), vertex_at(-100, 100)}};
  const auto z = ZonePolygon::build(rings);
  EXPECT_EQ(where(z, -80, 0, 5), Where::kInside);
  EXPECT_EQ(where(z, 80, 0, 5), Where::kInside);
  EXPECT_EQ(where(z, 0, 80, 5), Where::kOutside);
  EXPECT_EQ(where(z, 0, -80, 5), Where::kOutside);
}

TEST(ZoneGeometry, BuildRefusesShapesNobodyValidated) {
  EXPECT_THROW(ZonePolygon::build(std::vector<Ring>{}), std::invalid_argument);
  const std::vector<Ring> two{{vertex_at(0, 0), vertex_at(10, 0)}};
  EXPECT_THROW(ZonePolygon::build(two), std::invalid_argument);
}

// The plain even-odd rule in degrees (the projection is affine per zone, so the parity is the
// same) over every edge: what the band index must agree with.
bool brute_inside(const std::vector<Ring>& rings, double lat, double lon) {
  bool odd = false;
  for (const auto& ring : rings) {
    for (std::size_t i = 0; i < ring.size(); ++i) {
      const auto& a = ring[i];
      const auto& b = ring[(i + 1) % ring.size()];
      const double ay = a.lat_e7 * 1e-7, by = b.lat_e7 * 1e-7;
      const double ax = a.lon_e7 * 1e-7, bx = b.lon_e7 * 1e-7;
      if ((ay > lat) != (by > lat) && lon < ax + (lat - ay) * (bx - ax) / (by - ay)) odd = !odd;
    }
  }
  return odd;
}

TEST(ZoneGeometry, TheIndexAgreesWithAScanOfEveryEdgeOnTenThousandVertices) {
  const std::vector<Ring> rings{wiggly_ring(10'000, 3000, 150),
                                wiggly_ring(500, 800, 60, 500, -300, 11)};
  const auto z = ZonePolygon::build(rings);
  EXPECT_EQ(z.vertex_count(), 10'500u);
  EXPECT_GT(z.band_count(), 100u);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> coord(-3400, 3400);
  int inside = 0, near = 0;
  for (int i = 0; i < 4000; ++i) {
    const double x = coord(rng), y = coord(rng);
    const double lat = lat_at(y), lon = lon_at(x);
    const double d = z.distance_to_boundary_m(lat, lon);
    const Where w = z.locate(lat, lon, 10);
    if (d < 9.9) {
      EXPECT_EQ(w, Where::kNearBoundary) << x << "," << y << " at " << d << " m";
    } else if (d > 10.1) {
      const Where expected = brute_inside(rings, lat, lon) ? Where::kInside : Where::kOutside;
      EXPECT_EQ(w, expected) << x << "," << y << " at " << d << " m";
    }
    inside += w == Where::kInside;
    near += w == Where::kNearBoundary;
  }
  // The sample must exercise every answer, or the comparison proves little.
  EXPECT_GT(inside, 1500);
  EXPECT_GT(near, 15);
}

TEST(ZoneGeometry, TheIndexStaysBoundedForAZigZagSpanningTheWholeHeight) {
  // Every edge spans (nearly) the full height: a naive band index would hold edges x bands.
  Ring ring;
  for (int i = 0; i < 2000; ++i) ring.push_back(vertex_at(i * 2.0, (i % 2) ? 2000 : 0));
  ring.push_back(vertex_at(4000, -100));
  ring.push_back(vertex_at(0, -100));
  const std::vector<Ring> rings{ring};
  const auto z = ZonePolygon::build(rings);
  EXPECT_LE(z.index_entries(), 16 * 2002 + z.band_count());
  EXPECT_EQ(z.locate(lat_at(-50), lon_at(1000), 10), Where::kInside);
  EXPECT_EQ(z.locate(lat_at(1000), lon_at(1000.5), 0.1),
            brute_inside(rings, lat_at(1000), lon_at(1000.5)) ? Where::kInside : Where::kOutside);
}

// The worst shapes for a band index: a zig-zag whose every edge spans the whole height, and a
// comb of short base edges with long thin spikes through every band. The shape's memory --
// capacity included, so an oversized index allocated first and kept as capacity fails -- stays
// within the bound the header documents, and the answers stay those of a scan of every edge.
TEST(ZoneGeometry, WorstShapesStayWithinTheDocumentedMemoryBound) {
  Ring comb;
  for (int i = 0; i < 8000; ++i) comb.push_back(vertex_at(i * 1.0, (i % 40 == 20) ? 5000 : 0));
  comb.push_back(vertex_at(7999, -10));
  comb.push_back(vertex_at(0, -10));
  const std::vector<std::pair<const char*, Ring>> shapes{{"zig-zag", zig_zag(8000, 5000)},
                                                         {"comb", comb}};
  for (const auto& [name, ring] : shapes) {
    const std::vector<Ring> rings{ring};
    const auto z = ZonePolygon::build(rings);
    const std::size_t v = z.vertex_count();
    EXPECT_EQ(v, ring.size()) << name;
    EXPECT_LE(z.index_entries(), ZonePolygon::max_index_entries(v, z.band_count())) << name;
    EXPECT_LE(z.index_entries(), 16 * v + z.band_count()) << name;
    EXPECT_LE(z.memory_bytes(), ZonePolygon::max_bytes(v, 1)) << name;
    // About 77 bytes per vertex, as docs/location.md states.
    EXPECT_LE(z.memory_bytes(), 80 * v + 20'000) << name;
    std::mt19937 rng(9);
    std::uniform_real_distribution<double> x(-50, 8050), y(-100, 5100);
    for (int i = 0; i < 300; ++i) {
      const double lat = lat_at(y(rng)), lon = lon_at(x(rng));
      EXPECT_EQ(z.contains(lat, lon), brute_inside(rings, lat, lon)) << name << " " << i;
    }
  }
}

}  // namespace
}  // namespace fleetgw::geofence
