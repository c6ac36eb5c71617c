#include "gateway/geofence/zone_geometry.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace fleetgw::geofence {
namespace {

constexpr double kEarthRadiusM = 6'371'008.8;  // IUGG mean radius, as gnss::distance_m
constexpr double kRadPerDeg = M_PI / 180.0;
constexpr double kMPerDegLat = kEarthRadiusM * kRadPerDeg;
constexpr double kDegPerE7 = 1e-7;

// Bounds on the band index: about four edges per band for a compact shape, never so many bands
// that an empty band list costs more than the edges themselves.
constexpr std::size_t kMaxBands = 4096;
constexpr std::size_t kEntriesPerVertex = 16;

}  // namespace

ZonePolygon ZonePolygon::build(std::span<const Ring> rings) {
  if (rings.empty()) throw std::invalid_argument("zone polygon: no ring");
  ZonePolygon z;
  // The projection's origin: the centre of the latitude/longitude bounding box.
  std::int64_t lat_lo = std::numeric_limits<std::int64_t>::max(), lat_hi = -lat_lo;
  std::int64_t lon_lo = lat_lo, lon_hi = -lat_lo;
  for (const auto& ring : rings) {
    if (ring.size() < 3) throw std::invalid_argument("zone polygon: ring of fewer than 3 vertices");
    for (const auto& v : ring) {
      lat_lo = std::min<std::int64_t>(lat_lo, v.lat_e7);
      lat_hi = std::max<std::int64_t>(lat_hi, v.lat_e7);
      lon_lo = std::min<std::int64_t>(lon_lo, v.lon_e7);
      lon_hi = std::max<std::int64_t>(lon_hi, v.lon_e7);
    }
  }
  z.lat0_deg_ = static_cast<double>(lat_lo + lat_hi) / 2 * kDegPerE7;
  z.lon0_deg_ = static_cast<double>(lon_lo + lon_hi) / 2 * kDegPerE7;
  z.m_per_deg_lon_ = kMPerDegLat * std::cos(z.lat0_deg_ * kRadPerDeg);

  z.min_x_ = z.min_y_ = std::numeric_limits<double>::max();
  z.max_x_ = z.max_y_ = std::numeric_limits<double>::lowest();
  // Exact sizes first: every vector is allocated once, at its final size (no doubling slack
  // kept for as long as the zone is in force).
  std::size_t points = 0;
  for (const auto& ring : rings) points += ring.size() + 1;
  z.points_.reserve(points);
  z.edges_.reserve(points - rings.size());
  for (const auto& ring : rings) {
    const std::size_t first = z.points_.size();
    for (const auto& v : ring) {
      const Local l = z.project(v.lat_e7 * kDegPerE7, v.lon_e7 * kDegPerE7);
      z.points_.push_back({static_cast<float>(l.x), static_cast<float>(l.y)});
    }
    z.points_.push_back(z.points_[first]);  // closed
    for (std::size_t i = first; i + 1 < z.points_.size(); ++i) {
      z.edges_.push_back(static_cast<std::uint32_t>(i));
    }
    z.vertices_ += ring.size();
  }
  // The box from the stored (rounded) points, so every edge lies within it exactly.
  for (const auto& p : z.points_) {
    z.min_x_ = std::min<double>(z.min_x_, p.x);
    z.max_x_ = std::max<double>(z.max_x_, p.x);
    z.min_y_ = std::min<double>(z.min_y_, p.y);
    z.max_y_ = std::max<double>(z.max_y_, p.y);
  }
  // The band count is chosen BEFORE anything is allocated for the index: the entries a count
  // would need are summed without storing them (O(edges) per candidate, at most 13 candidates),
  // and a winding shape (edges spanning many bands) gets fewer, taller bands until the index
  // fits kEntriesPerVertex per edge. The index is then allocated once, at its exact size.
  std::size_t bands = std::clamp<std::size_t>(z.edges_.size() / 4, 1, kMaxBands);
  while (bands > 1 && z.entries_for(bands) > max_index_entries(z.edges_.size(), bands)) {
    bands /= 2;
  }
  z.index_edges(bands);
  return z;
}

std::size_t ZonePolygon::max_index_entries(std::size_t edges, std::size_t bands) {
  return kEntriesPerVertex * edges + bands;
}

std::size_t ZonePolygon::max_bytes(std::size_t vertices, std::size_t rings) {
  const std::size_t points = vertices + rings;
  const std::size_t bands = std::clamp<std::size_t>(vertices / 4, 1, kMaxBands);
  return sizeof(ZonePolygon) + points * sizeof(Point) + vertices * sizeof(std::uint32_t) +
         (bands + 1) * sizeof(std::uint32_t) +
         max_index_entries(vertices, bands) * sizeof(std::uint32_t);
}

std::size_t ZonePolygon::memory_bytes() const {
  return sizeof(ZonePolygon) + points_.capacity() * sizeof(Point) +
         edges_.capacity() * sizeof(std::uint32_t) +
         band_start_.capacity() * sizeof(std::uint32_t) +
         band_edges_.capacity() * sizeof(std::uint32_t);
}

void ZonePolygon::set_bands(std::size_t bands) {
  bands_ = bands;
  const double height = max_y_ - min_y_;
  band_height_ = height > 0 ? height / static_cast<double>(bands) : 1.0;
}

std::pair<std::size_t, std::size_t> ZonePolygon::bands_of_edge(std::uint32_t e) const {
  const double y0 = points_[e].y, y1 = points_[e + 1].y;
  return {band_of(std::min(y0, y1)), band_of(std::max(y0, y1))};
}

std::size_t ZonePolygon::entries_for(std::size_t bands) {
  set_bands(bands);
  std::size_t entries = 0;
  for (const auto e : edges_) {
    const auto [lo, hi] = bands_of_edge(e);
    entries += hi - lo + 1;
  }
  return entries;
}

void ZonePolygon::index_edges(std::size_t bands) {
  set_bands(bands);
  std::vector<std::uint32_t> counts(bands + 1, 0);
  for (const auto e : edges_) {
    const auto [lo, hi] = bands_of_edge(e);
    for (std::size_t b = lo; b <= hi; ++b) ++counts[b + 1];
  }
  for (std::size_t b = 0; b < bands; ++b) counts[b + 1] += counts[b];
  band_start_ = counts;  // a copy: allocated at its exact size
  band_edges_ = std::vector<std::uint32_t>(counts[bands], 0);
  for (const auto e : edges_) {
    const auto [lo, hi] = bands_of_edge(e);
    for (std::size_t b = lo; b <= hi; ++b) band_edges_[counts[b]++] = e;
  }
}

ZonePolygon::Local ZonePolygon::project(double lat_deg, double lon_deg) const {
  return {(lon_deg - lon0_deg_) * m_per_deg_lon_, (lat_deg - lat0_deg_) * kMPerDegLat};
}

std::size_t ZonePolygon::band_of(double y) const {
  const double f = (y - min_y_) / band_height_;
  if (!(f > 0)) return 0;  // also NaN
  const auto b = static_cast<std::size_t>(std::min(f, static_cast<double>(bands_ - 1)));
  return std::min(b, bands_ - 1);
}

bool ZonePolygon::crossings_odd(const Local& p) const {
  if (p.y < min_y_ || p.y > max_y_ || p.x < min_x_ || p.x > max_x_) return false;
  const std::size_t b = band_of(p.y);
  bool odd = false;
  // Every edge whose latitude range straddles p.y overlaps p's band, so the band is enough.
  for (std::uint32_t i = band_start_[b]; i < band_start_[b + 1]; ++i) {
    const Point a = points_[band_edges_[i]];
    const Point c = points_[band_edges_[i] + 1];
    if ((a.y > p.y) != (c.y > p.y)) {
      const double x =
          a.x + (p.y - a.y) * (static_cast<double>(c.x) - a.x) / (static_cast<double>(c.y) - a.y);
      if (p.x < x) odd = !odd;
    }
  }
  return odd;
}

double ZonePolygon::edge_distance_sq(std::uint32_t edge, const Local& p) const {
  const double ax = points_[edge].x, ay = points_[edge].y;
  const double dx = points_[edge + 1].x - ax, dy = points_[edge + 1].y - ay;
  const double len_sq = dx * dx + dy * dy;
  double t = len_sq > 0 ? ((p.x - ax) * dx + (p.y - ay) * dy) / len_sq : 0.0;
  t = std::clamp(t, 0.0, 1.0);
  const double ex = ax + t * dx - p.x, ey = ay + t * dy - p.y;
  return ex * ex + ey * ey;
}

bool ZonePolygon::near_edge(const Local& p, double margin_m) const {
  if (!(margin_m > 0)) return false;
  if (p.y < min_y_ - margin_m || p.y > max_y_ + margin_m || p.x < min_x_ - margin_m ||
      p.x > max_x_ + margin_m) {
    return false;
  }
  const double limit = margin_m * margin_m;
  // An edge within the margin overlaps [y - margin, y + margin] in latitude, so it is listed in
  // one of these bands.
  const std::size_t lo = band_of(p.y - margin_m), hi = band_of(p.y + margin_m);
  for (std::size_t b = lo; b <= hi; ++b) {
    for (std::uint32_t i = band_start_[b]; i < band_start_[b + 1]; ++i) {
      if (edge_distance_sq(band_edges_[i], p) < limit) return true;
    }
  }
  return false;
}

Where ZonePolygon::locate(double lat_deg, double lon_deg, double margin_m) const {
  const Local p = project(lat_deg, lon_deg);
  if (near_edge(p, margin_m)) return Where::kNearBoundary;
  return crossings_odd(p) ? Where::kInside : Where::kOutside;
}

bool ZonePolygon::contains(double lat_deg, double lon_deg) const {
  return crossings_odd(project(lat_deg, lon_deg));
}

double ZonePolygon::distance_to_boundary_m(double lat_deg, double lon_deg) const {
  const Local p = project(lat_deg, lon_deg);
  double best = std::numeric_limits<double>::infinity();
  for (const auto e : edges_) best = std::min(best, edge_distance_sq(e, p));
  return std::sqrt(best);
}

}  // namespace fleetgw::geofence
