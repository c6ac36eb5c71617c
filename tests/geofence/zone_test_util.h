// Test helpers for the geofence suites and the benchmark: shapes laid out in metres around a
// fixed centre (Berlin), converted to the bundle's 1e-7 degrees, and fixes at such offsets.
// Header-only; the conversions are the plain equirectangular ones, independent of the code
// under test.
#pragma once

#include <chrono>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "fleetgw/v1/zones.pb.h"
#include "gateway/geofence/zone_geometry.h"
#include "gateway/gnss/position.h"

namespace fleetgw::geofence::testing {

inline constexpr double kLat0 = 52.52;
inline constexpr double kLon0 = 13.405;
inline constexpr double kMPerDeg = 6'371'008.8 * M_PI / 180.0;

inline double lat_at(double north_m) {
  return kLat0 + north_m / kMPerDeg;
}
inline double lon_at(double east_m) {
  return kLon0 + east_m / (kMPerDeg * std::cos(kLat0 * M_PI / 180.0));
}
inline Vertex vertex_at(double east_m, double north_m) {
  return {static_cast<std::int32_t>(std::lround(lat_at(north_m) * 1e7)),
          static_cast<std::int32_t>(std::lround(lon_at(east_m) * 1e7))};
}
inline gnss::Fix fix_at(double east_m, double north_m, std::chrono::microseconds at) {
  gnss::Fix p;
  p.lat_deg = lat_at(north_m);
  p.lon_deg = lon_at(east_m);
  p.fixed_at = at;
  p.received_at = at;
  return p;
}

// An axis-aligned rectangle [x0, x1] x [y0, y1] in metres.
inline Ring rect(double x0, double y0, double x1, double y1) {
  return {vertex_at(x0, y0), vertex_at(x1, y0), vertex_at(x1, y1), vertex_at(x0, y1)};
}

// A wiggly closed ring of `n` vertices around (cx, cy): radius r +- wiggle, like a city's
// boundary drawn along streets.
inline Ring wiggly_ring(std::size_t n, double r, double wiggle, double cx = 0, double cy = 0,
                        std::uint32_t seed = 7) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> jitter(-wiggle, wiggle);
  Ring ring;
  for (std::size_t i = 0; i < n; ++i) {
    const double a = 2 * M_PI * static_cast<double>(i) / static_cast<double>(n);
    const double rr = r + jitter(rng);
    ring.push_back(vertex_at(cx + rr * std::cos(a), cy + rr * std::sin(a)));
  }
  return ring;
}

// A smooth closed ring of `n` vertices around (cx, cy): radius r with two slow waves of
// amplitude `wave` and +-2 m of noise, like a city boundary traced along streets.
inline Ring smooth_ring(std::size_t n, double r, double wave, double cx = 0, double cy = 0,
                        std::uint32_t seed = 7) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> jitter(-2, 2);
  Ring ring;
  for (std::size_t i = 0; i < n; ++i) {
    const double a = 2 * M_PI * static_cast<double>(i) / static_cast<double>(n);
    const double rr = r + wave * std::sin(7 * a) + 0.5 * wave * std::sin(23 * a + 1) + jitter(rng);
    ring.push_back(vertex_at(cx + rr * std::cos(a), cy + rr * std::sin(a)));
  }
  return ring;
}

// The worst shape for a band index (issue 24): `n` vertices zig-zagging between y = 0 and
// y = height every `step` metres eastwards, so every edge spans the whole zone's height, closed
// by a base 10 m below. A 100,000-vertex one is the largest bundle a gateway accepts.
inline Ring zig_zag(std::size_t n, double height, double step = 0.5) {
  Ring ring;
  ring.reserve(n);
  for (std::size_t i = 0; i + 2 < n; ++i) {
    ring.push_back(vertex_at(static_cast<double>(i) * step, (i % 2) ? height : 0));
  }
  ring.push_back(vertex_at(static_cast<double>(n - 3) * step, -10));
  ring.push_back(vertex_at(0, -10));
  return ring;
}

inline v1::ZoneRing to_proto(const Ring& ring) {
  v1::ZoneRing r;
  for (const auto& v : ring) {
    r.add_lat_e7(v.lat_e7);
    r.add_lon_e7(v.lon_e7);
  }
  return r;
}

inline v1::Zone* add_zone(v1::ZoneBundle& bundle, const std::string& id, v1::ZoneKind kind,
                          const std::vector<Ring>& rings, std::uint32_t limit_kmh = 0) {
  auto* z = bundle.add_zones();
  z->set_id(id);
  z->set_name("zone " + id);
  z->set_kind(kind);
  z->set_speed_limit_kmh(limit_kmh);
  for (const auto& r : rings) *z->add_rings() = to_proto(r);
  return z;
}

}  // namespace fleetgw::geofence::testing
