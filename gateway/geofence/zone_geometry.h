// ZonePolygon: one zone's shape (rings under the even-odd rule), prepared for fast
// point-in-polygon and "near the boundary" queries. Pure geometry: no clock, no I/O.
//
// Contract:
//  * build() takes rings of WGS-84 vertices in 1e-7 degrees that were already validated
//    (zone_bundle.h: >= 3 vertices per ring, coordinates in range, a ring spans at most 180
//    degrees of longitude). It throws std::invalid_argument for an empty ring list or a ring of
//    fewer than 3 vertices, so an unvalidated shape cannot slip through.
//  * The rings are projected once onto a local plane (equirectangular about the centre of the
//    zone's bounding box, metres). Inside/outside is exact under that projection (it is a
//    continuous bijection over the zone); distances are within 0.5 % for city-sized zones.
//  * locate(lat, lon, margin) answers kInside / kOutside when the point is on that side AND at
//    least `margin_m` from every edge, kNearBoundary otherwise -- the basis of the engine's
//    hysteresis. A point on an edge is near the boundary for any margin > 0.
//  * Speed: a bounding-box test, then a horizontal band index: each band lists the edges whose
//    latitude range overlaps it, so a query reads only the edges of one band (the crossing
//    count) and of the bands within the margin (the distance check).
//  * Bounded cost, whatever the shape (a zig-zag whose every edge spans the whole height is the
//    worst): the band count (at most 4,096, about one per 4 edges) is chosen BEFORE the index is
//    allocated, by summing the entries each candidate count would need, halving it until the
//    index holds at most max_index_entries(edges, bands) = 16 per edge + 1 per band. Every
//    vector is allocated once at its exact size, so memory_bytes() <= max_bytes(vertices,
//    rings) ~ 77 bytes per vertex (+ 16 kB of band starts at most) for as long as the zone
//    lives. build() costs O(13 x edges + index entries) time; a query reads at most the entries
//    of the bands it touches (<= 2 x (16 x edges + bands) edge tests for the worst shape, the
//    cost of a linear scan; a few dozen for a compact shape).
//  * distance_to_boundary_m() is the plain linear scan over every edge, kept for tests and the
//    benchmark baseline.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <utility>
#include <vector>

namespace fleetgw::geofence {

struct Vertex {
  std::int32_t lat_e7 = 0;
  std::int32_t lon_e7 = 0;
  friend bool operator==(const Vertex&, const Vertex&) = default;
};
using Ring = std::vector<Vertex>;

enum class Where : std::uint8_t { kInside, kOutside, kNearBoundary };

class ZonePolygon {
 public:
  static ZonePolygon build(std::span<const Ring> rings);

  Where locate(double lat_deg, double lon_deg, double margin_m) const;
  // Even-odd point-in-polygon without a margin.
  bool contains(double lat_deg, double lon_deg) const;
  // Distance from the point to the nearest edge, metres (linear scan).
  double distance_to_boundary_m(double lat_deg, double lon_deg) const;

  std::size_t vertex_count() const { return vertices_; }
  std::size_t band_count() const { return bands_; }
  std::size_t index_entries() const { return band_edges_.size(); }
  // Bytes held by the shape (vector capacities included) and the bound it never exceeds.
  std::size_t memory_bytes() const;
  static std::size_t max_bytes(std::size_t vertices, std::size_t rings);
  // The most index entries build() allows for `edges` edges in `bands` bands.
  static std::size_t max_index_entries(std::size_t edges, std::size_t bands);

 private:
  struct Point {
    float x;
    float y;
  };
  struct Local {
    double x;
    double y;
  };
  ZonePolygon() = default;
  Local project(double lat_deg, double lon_deg) const;
  std::size_t band_of(double y) const;
  bool crossings_odd(const Local& p) const;
  bool near_edge(const Local& p, double margin_m) const;
  double edge_distance_sq(std::uint32_t edge, const Local& p) const;
  void set_bands(std::size_t bands);
  std::pair<std::size_t, std::size_t> bands_of_edge(std::uint32_t edge) const;
  // The index entries `bands` bands would need, counted without allocating them.
  std::size_t entries_for(std::size_t bands);
  void index_edges(std::size_t bands);

  // Projection: metres east/north of (lat0, lon0).
  double lat0_deg_ = 0;
  double lon0_deg_ = 0;
  double m_per_deg_lon_ = 0;
  // Bounding box in the local plane.
  double min_x_ = 0, max_x_ = 0, min_y_ = 0, max_y_ = 0;
  double band_height_ = 1;
  std::size_t bands_ = 1;
  // Every ring closed (its first vertex repeated at its end), rings one after another; edge i
  // runs from points_[i] to points_[i + 1] and exists for the indices in edges_.
  std::vector<Point> points_;
  std::vector<std::uint32_t> edges_;
  std::vector<std::uint32_t> band_start_;  // CSR: band b lists band_edges_[start[b]..start[b+1])
  std::vector<std::uint32_t> band_edges_;  // indices into points_ (edge start)
  std::size_t vertices_ = 0;
};

}  // namespace fleetgw::geofence
