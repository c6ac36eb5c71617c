#include "gateway/sim/route.h"

#include <algorithm>
#include <cmath>

#include "gateway/sim/toml_number.h"

namespace fleetgw::sim {
namespace {

constexpr double kRad = M_PI / 180.0;

double read_coordinate(const toml::table& t, std::string_view key, double limit,
                       const std::string& path, const std::string& file) {
  const std::string full = path + "." + std::string(key);
  const toml::node* n = t.get(key);
  if (!n) throw ScenarioError(file, t.source().begin.line, full, "missing key");
  return read_number(*n, -limit, limit, file, full);
}

}  // namespace

std::vector<GeoPoint> parse_route(const toml::array& route, const std::string& file) {
  std::vector<GeoPoint> out;
  for (std::size_t i = 0; i < route.size(); ++i) {
    const toml::node& n = *route.get(i);
    const std::string path = "route[" + std::to_string(i) + "]";
    if (!n.is_table()) {
      throw ScenarioError(file, n.source().begin.line, path,
                          "expected a table ([[route]] with lat_deg and lon_deg)");
    }
    const toml::table& t = *n.as_table();
    for (const auto& [k, v] : t) {
      if (k.str() != "lat_deg" && k.str() != "lon_deg") {
        throw ScenarioError(file, v.source().begin.line, path + "." + std::string(k.str()),
                            "unknown key (a waypoint has lat_deg and lon_deg)");
      }
    }
    out.push_back(GeoPoint{read_coordinate(t, "lat_deg", 90, path, file),
                           read_coordinate(t, "lon_deg", 180, path, file)});
  }
  if (out.size() < 2) {
    throw ScenarioError(file, route.source().begin.line, "route",
                        "a route needs at least 2 waypoints, got " + std::to_string(out.size()));
  }
  return out;
}

double great_circle_m(const GeoPoint& a, const GeoPoint& b) {
  const double dlat = (b.lat_deg - a.lat_deg) * kRad;
  const double dlon = (b.lon_deg - a.lon_deg) * kRad;
  const double h = std::sin(dlat / 2) * std::sin(dlat / 2) +
                   std::cos(a.lat_deg * kRad) * std::cos(b.lat_deg * kRad) * std::sin(dlon / 2) *
                       std::sin(dlon / 2);
  return 2 * kRouteEarthRadiusM * std::asin(std::min(1.0, std::sqrt(h)));
}

double bearing_deg(const GeoPoint& a, const GeoPoint& b) {
  const double p1 = a.lat_deg * kRad;
  const double p2 = b.lat_deg * kRad;
  const double dl = (b.lon_deg - a.lon_deg) * kRad;
  const double y = std::sin(dl) * std::cos(p2);
  const double x = std::cos(p1) * std::sin(p2) - std::sin(p1) * std::cos(p2) * std::cos(dl);
  const double deg = std::atan2(y, x) / kRad;
  return deg < 0 ? deg + 360 : deg;
}

RouteWalker::RouteWalker(std::vector<GeoPoint> points) : points_(std::move(points)) {
  if (points_.empty()) throw std::invalid_argument("RouteWalker: empty route");
  cumulative_.push_back(0);
  for (std::size_t i = 1; i < points_.size(); ++i) {
    cumulative_.push_back(cumulative_.back() + great_circle_m(points_[i - 1], points_[i]));
  }
}

std::size_t RouteWalker::leg_of(double distance_m) const {
  if (points_.size() < 2) return 0;
  // First waypoint whose cumulative distance exceeds distance_m ends the leg.
  const auto it = std::upper_bound(cumulative_.begin(), cumulative_.end(), distance_m);
  const auto end = static_cast<std::size_t>(it - cumulative_.begin());
  return std::clamp<std::size_t>(end, 1, points_.size() - 1) - 1;
}

GeoPoint RouteWalker::at(double distance_m) const {
  if (!(distance_m > 0)) return points_.front();
  if (distance_m >= length_m()) return points_.back();
  const std::size_t i = leg_of(distance_m);
  const GeoPoint& a = points_[i];
  const GeoPoint& b = points_[i + 1];
  const double leg = cumulative_[i + 1] - cumulative_[i];
  if (leg <= 0) return b;
  const double f = (distance_m - cumulative_[i]) / leg;
  const double delta = leg / kRouteEarthRadiusM;  // angular length of the leg
  if (delta < 1e-9)
    return GeoPoint{a.lat_deg + f * (b.lat_deg - a.lat_deg),
                    a.lon_deg + f * (b.lon_deg - a.lon_deg)};
  // Spherical interpolation: the point a fraction f of the way along the great circle.
  const double wa = std::sin((1 - f) * delta) / std::sin(delta);
  const double wb = std::sin(f * delta) / std::sin(delta);
  const double p1 = a.lat_deg * kRad, l1 = a.lon_deg * kRad;
  const double p2 = b.lat_deg * kRad, l2 = b.lon_deg * kRad;
  const double x = wa * std::cos(p1) * std::cos(l1) + wb * std::cos(p2) * std::cos(l2);
  const double y = wa * std::cos(p1) * std::sin(l1) + wb * std::cos(p2) * std::sin(l2);
  const double z = wa * std::sin(p1) + wb * std::sin(p2);
  return GeoPoint{std::atan2(z, std::hypot(x, y)) / kRad, std::atan2(y, x) / kRad};
}

double RouteWalker::course_deg(double distance_m) const {
  if (points_.size() < 2) return 0;
  const std::size_t i = distance_m >= length_m() ? points_.size() - 2 : leg_of(distance_m);
  return bearing_deg(points_[i], points_[i + 1]);
}

}  // namespace fleetgw::sim
