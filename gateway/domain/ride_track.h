// RideTrack: where a ride went -- start and end position, the GNSS distance, and a compact track
// (a polyline simplified with a bounded error). Pure logic on positions; no clock, no I/O.
//
// Contract:
//  * add(p) takes every current fix during the ride, in order. The first is the start, the
//    latest the end. A fix closer than `min_step_m` to the last accepted vertex is not a
//    vertex and adds no distance: GNSS jitter at a standstill does not make a parked bike
//    "travel".
//  * distance_m() sums the accepted steps (great circle): the GNSS distance, reported next to
//    the odometer's as a cross-check.
//  * simplified() is the track within `tolerance_m` of every accepted vertex
//    (Douglas-Peucker on a local equirectangular projection: exact enough over a ride's extent);
//    its first and last points are the start and the end.
//  * Memory is bounded: beyond `max_vertices` accepted vertices the track is simplified in place
//    to at most half of that (with the same tolerance, doubled until it fits when the route is
//    too winding), so a day-long ride never grows without limit; the distance is unaffected
//    (summed as the vertices arrive).
#pragma once

#include <cstddef>
#include <optional>
#include <vector>

#include "gateway/gnss/position.h"

namespace fleetgw::domain {

struct RideTrackOptions {
  double min_step_m = 5.0;
  double tolerance_m = 5.0;
  std::size_t max_vertices = 4096;
};

class RideTrack {
 public:
  explicit RideTrack(RideTrackOptions options = {}) : options_(options) {}

  void add(const gnss::Fix& p);
  // Continues a track checkpointed by a previous run (the ride row after a restart): its start,
  // its latest fix, its GNSS distance and its simplified vertices (at least the start). The
  // next fix's step is measured from the last vertex, so the distance goes on where it stopped.
  void resume(const gnss::Fix& start, const gnss::Fix& end, double distance_m,
              std::vector<gnss::Fix> vertices);
  bool empty() const { return !start_.has_value(); }
  const std::optional<gnss::Fix>& start() const { return start_; }
  const std::optional<gnss::Fix>& end() const { return end_; }
  double distance_m() const { return distance_m_; }
  std::size_t vertices() const { return vertices_.size(); }
  std::vector<gnss::Fix> simplified() const;
  double tolerance_m() const { return options_.tolerance_m; }

 private:
  RideTrackOptions options_;
  std::optional<gnss::Fix> start_;
  std::optional<gnss::Fix> end_;
  std::vector<gnss::Fix> vertices_;
  double distance_m_ = 0;
};

// Douglas-Peucker: the subset of `points` (first and last always kept) such that every dropped
// point lies within `tolerance_m` of the kept polyline.
std::vector<gnss::Fix> simplify_track(const std::vector<gnss::Fix>& points,
                                           double tolerance_m);

}  // namespace fleetgw::domain
