// The simulated bike's position: the point at a given distance along the scenario's route, a
// polyline of great-circle legs between its waypoints (docs/simulator.md, "Route").
//
// Contract:
//  * parse_route() reads the [[route]] tables ({lat_deg, lon_deg}); a bad entry throws
//    ScenarioError naming the file, line and key ("route[2].lat_deg: expected a number in
//    -90..90, got 95"); a route needs at least 2 waypoints.
//  * RouteWalker::at(distance_m) is the point `distance_m` metres from the first waypoint along
//    the legs: the first waypoint for distance <= 0, the last one once the route is exhausted.
//    Distances use the same Earth radius as the gateway (gateway/gnss/position.cc), so the
//    gateway's GNSS distance of a walked route matches the distance walked.
#pragma once

#include <string>
#include <vector>

#include <toml++/toml.h>

#include "gateway/sim/scenario.h"

namespace fleetgw::sim {

inline constexpr double kRouteEarthRadiusM = 6'371'008.8;

std::vector<GeoPoint> parse_route(const toml::array& route, const std::string& file);

// Great-circle distance in metres (haversine).
double great_circle_m(const GeoPoint& a, const GeoPoint& b);
// Initial bearing from a to b, degrees clockwise from true north in [0, 360).
double bearing_deg(const GeoPoint& a, const GeoPoint& b);

class RouteWalker {
 public:
  explicit RouteWalker(std::vector<GeoPoint> points);  // needs at least one point

  GeoPoint at(double distance_m) const;
  // Bearing of the leg at `distance_m` (of the last leg beyond the end).
  double course_deg(double distance_m) const;
  double length_m() const { return cumulative_.back(); }

 private:
  std::size_t leg_of(double distance_m) const;  // index of the leg's first waypoint

  std::vector<GeoPoint> points_;
  std::vector<double> cumulative_;  // distance from the start to each waypoint
};

}  // namespace fleetgw::sim
