#include "gateway/domain/ride_track.h"

#include <algorithm>
#include <cmath>

namespace fleetgw::domain {
namespace {

constexpr double kEarthRadiusM = 6'371'008.8;
constexpr double kRad = M_PI / 180.0;

struct Xy {
  double x, y;
};

// Metres east/north of `origin` (equirectangular: fine over a few tens of km).
Xy project(const gnss::Fix& p, const gnss::Fix& origin) {
  return {(p.lon_deg - origin.lon_deg) * kRad * kEarthRadiusM * std::cos(origin.lat_deg * kRad),
          (p.lat_deg - origin.lat_deg) * kRad * kEarthRadiusM};
}

// Distance from p to the segment a-b, metres.
double segment_distance(Xy p, Xy a, Xy b) {
  const double dx = b.x - a.x;
  const double dy = b.y - a.y;
  const double len2 = dx * dx + dy * dy;
  double t = len2 > 0 ? ((p.x - a.x) * dx + (p.y - a.y) * dy) / len2 : 0.0;
  t = std::clamp(t, 0.0, 1.0);
  return std::hypot(p.x - (a.x + t * dx), p.y - (a.y + t * dy));
}

}  // namespace

std::vector<gnss::Fix> simplify_track(const std::vector<gnss::Fix>& points,
                                           double tolerance_m) {
  if (points.size() <= 2) return points;
  std::vector<Xy> xy;
  xy.reserve(points.size());
  for (const auto& p : points) xy.push_back(project(p, points.front()));
  std::vector<bool> keep(points.size(), false);
  keep.front() = keep.back() = true;
  // Iterative: a long ride must not recurse thousands deep.
  std::vector<std::pair<std::size_t, std::size_t>> stack{{0, points.size() - 1}};
  while (!stack.empty()) {
    const auto [first, last] = stack.back();
    stack.pop_back();
    double worst = -1;
    std::size_t at = first;
    for (std::size_t i = first + 1; i < last; ++i) {
      const double d = segment_distance(xy[i], xy[first], xy[last]);
      if (d > worst) {
        worst = d;
        at = i;
      }
    }
    if (worst > tolerance_m) {
      keep[at] = true;
      stack.emplace_back(first, at);
      stack.emplace_back(at, last);
    }
  }
  std::vector<gnss::Fix> out;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (keep[i]) out.push_back(points[i]);
  }
  return out;
}

void RideTrack::add(const gnss::Fix& p) {
  if (!start_) {
    start_ = p;
    end_ = p;
    vertices_.push_back(p);
    return;
  }
  end_ = p;
  const double step = gnss::distance_m(vertices_.back(), p);
  if (step < options_.min_step_m) return;
  distance_m_ += step;
  vertices_.push_back(p);
  // Bounded memory: past max_vertices, simplify in place down to half of it, coarser each time
  // if the route is too winding for the tolerance to halve it (documented: such a track is then
  // simplified beyond tolerance_m). Halving makes the cost amortised: one compaction per
  // max_vertices / 2 new vertices, not one per fix once a winding ride has reached the bound.
  if (vertices_.size() <= options_.max_vertices) return;
  double tolerance = options_.tolerance_m;
  while (vertices_.size() > options_.max_vertices / 2 + 1 && vertices_.size() > 2) {
    vertices_ = simplify_track(vertices_, tolerance);
    tolerance *= 2;
  }
}

void RideTrack::resume(const gnss::Fix& start, const gnss::Fix& end, double distance_m,
                       std::vector<gnss::Fix> vertices) {
  start_ = start;
  end_ = end;
  distance_m_ = distance_m;
  vertices_ = std::move(vertices);
  if (vertices_.empty()) vertices_.push_back(start);
}

std::vector<gnss::Fix> RideTrack::simplified() const {
  std::vector<gnss::Fix> points = vertices_;
  // The end is the latest fix even when it was too close to the last vertex to be one.
  if (end_ && !points.empty() && !(points.back() == *end_)) points.push_back(*end_);
  return simplify_track(points, options_.tolerance_m);
}

}  // namespace fleetgw::domain
