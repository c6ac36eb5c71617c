#include "gateway/tools/plot/ride_plot_map.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "gateway/tools/common/table_format.h"

namespace fleetgw::tools {
namespace ride_map {
namespace {

// Layout relative to the panel's top, in user units.
constexpr double kLabelDy = 16;
constexpr double kFrameDy = 24;
constexpr double kFrameHeight = 380;
constexpr double kScaleBarDy = kFrameDy + kFrameHeight + 16;
constexpr double kFrameLeft = kAxisLeft;
constexpr double kFrameWidth = kAxisRight - kAxisLeft;
constexpr double kPadding = 28;  // keeps the markers and their labels inside the frame
// A track whose positions are all within a few metres (GNSS jitter) is drawn at this extent
// rather than blown up to the whole frame.
constexpr double kMinExtentM = 20;
constexpr double kEarthRadiusM = 6'371'008.8;  // mean radius (IUGG), as the ride tracker uses
// Distances beyond this are not a ride's (a damaged row): printed as unknown.
constexpr double kMaxPlausibleKm = 1e6;
constexpr std::string_view kTextColour = "#333333";
constexpr std::string_view kFrameColour = "#bbbbbb";

struct Pt {
  double x = 0;
  double y = 0;
};

std::string num(double v, int decimals = 1) {
  if (std::fabs(v) < 1e-9 || !std::isfinite(v)) v = 0;  // never "-0.0" or "nan"
  return fmt::format("{:.{}f}", v, decimals);
}

std::string km_text(std::optional<double> km) {
  if (!km || !std::isfinite(*km) || *km < 0 || *km > kMaxPlausibleKm) return "unknown";
  return num(*km, 1) + " km";
}

// The valid positions, evenly picked down to kMaxMapPoints (first and last kept).
std::vector<storage::TrackPoint> drawable(const std::vector<storage::TrackPoint>& track) {
  std::vector<storage::TrackPoint> valid;
  for (const auto& p : track) {
    if (std::isfinite(p.lat_deg) && std::isfinite(p.lon_deg) && std::fabs(p.lat_deg) <= 90 &&
        std::fabs(p.lon_deg) <= 180) {
      valid.push_back(p);
    }
  }
  if (valid.size() <= kMaxMapPoints) return valid;
  const std::size_t step = (valid.size() - 1 + kMaxMapPoints - 2) / (kMaxMapPoints - 1);
  std::vector<storage::TrackPoint> picked;
  picked.reserve(kMaxMapPoints);
  for (std::size_t i = 0; i < valid.size() - 1; i += step) picked.push_back(valid[i]);
  picked.push_back(valid.back());
  return picked;
}

// Positions -> metres east and north of the bounding box's centre (local equirectangular).
std::vector<Pt> project(std::vector<storage::TrackPoint> track) {
  auto [lon_lo, lon_hi] =
      std::minmax_element(track.begin(), track.end(),
                          [](const auto& a, const auto& b) { return a.lon_deg < b.lon_deg; });
  // Across the antimeridian the short way round is the one with the western longitudes moved
  // by 360 degrees.
  if (lon_hi->lon_deg - lon_lo->lon_deg > 180) {
    for (auto& p : track) {
      if (p.lon_deg < 0) p.lon_deg += 360;
    }
  }
  double lat_min = track.front().lat_deg, lat_max = lat_min;
  double lon_min = track.front().lon_deg, lon_max = lon_min;
  for (const auto& p : track) {
    lat_min = std::min(lat_min, p.lat_deg);
    lat_max = std::max(lat_max, p.lat_deg);
    lon_min = std::min(lon_min, p.lon_deg);
    lon_max = std::max(lon_max, p.lon_deg);
  }
  constexpr double kRad = std::numbers::pi / 180.0;
  const double lat0 = (lat_min + lat_max) / 2, lon0 = (lon_min + lon_max) / 2;
  const double east_per_deg = kEarthRadiusM * kRad * std::cos(lat0 * kRad);
  const double north_per_deg = kEarthRadiusM * kRad;
  std::vector<Pt> out;
  out.reserve(track.size());
  for (const auto& p : track) {
    out.push_back({(p.lon_deg - lon0) * east_per_deg, (p.lat_deg - lat0) * north_per_deg});
  }
  return out;
}

// The largest 1, 2 or 5 x 10^n not above `max_m` (at least 1 m).
double scale_bar_m(double max_m) {
  if (!(max_m >= 1) || !std::isfinite(max_m)) return 1;
  const double mag = std::pow(10.0, std::floor(std::log10(max_m)));
  const double f = max_m / mag;
  return (f >= 5 ? 5 : f >= 2 ? 2 : 1) * mag;
}

std::string scale_label(double m) {
  return m >= 1000 ? fmt::format("{:.0f} km", m / 1000) : fmt::format("{:.0f} m", m);
}

}  // namespace
}  // namespace ride_map

std::vector<storage::TrackPoint> plot_track(std::string_view ride_id,
                                            const std::optional<std::string>& text,
                                            std::ostream& err) {
  if (!text) return {};
  std::string problem;
  if (text->size() > kMaxTrackTextBytes) {
    problem =
        fmt::format("{} bytes, more than the {} a plot reads", text->size(), kMaxTrackTextBytes);
  } else {
    // A track nests two deep ([[lon, lat], ...]); deeper text is refused before it is parsed,
    // so a hostile column of millions of brackets never becomes millions of JSON nodes.
    int depth = 0;
    for (const char c : *text) {
      depth += (c == '[' || c == '{') ? 1 : (c == ']' || c == '}') ? -1 : 0;
      if (depth > 2) {
        problem = "nested deeper than [[longitude, latitude], ...]";
        break;
      }
    }
    if (problem.empty()) {
      auto parsed = storage::parse_track_text(*text);
      if (parsed.ok()) return std::move(parsed.points);
      problem = parsed.error;
    }
  }
  err << "fleetgw ride plot: ride '" << table_cell(ride_id) << "': track: " << problem
      << "; plotted without it\n";
  return {};
}

std::optional<std::string> map_panel_svg(const RidePlot& plot, double top) {
  using namespace ride_map;
  const auto track = drawable(plot.track);
  if (track.size() < 2) return std::nullopt;
  const auto metres = project(track);
  double x_lo = metres.front().x, x_hi = x_lo, y_lo = metres.front().y, y_hi = y_lo;
  for (const auto& p : metres) {
    x_lo = std::min(x_lo, p.x);
    x_hi = std::max(x_hi, p.x);
    y_lo = std::min(y_lo, p.y);
    y_hi = std::max(y_hi, p.y);
  }
  // One scale for both axes, the track centred in the frame.
  const double frame_top = top + kFrameDy;
  const double px_per_m =
      std::min((kFrameWidth - 2 * kPadding) / std::max(x_hi - x_lo, kMinExtentM),
               (kFrameHeight - 2 * kPadding) / std::max(y_hi - y_lo, kMinExtentM));
  const double cx = kFrameLeft + kFrameWidth / 2, cy = frame_top + kFrameHeight / 2;
  const double mx = (x_lo + x_hi) / 2, my = (y_lo + y_hi) / 2;
  const auto to_px = [&](const Pt& m) {
    return Pt{cx + (m.x - mx) * px_per_m, cy - (m.y - my) * px_per_m};  // north up
  };

  std::string out = "<g class=\"panel\" id=\"panel-map\">\n";
  out += fmt::format(
      "<text class=\"panel-label\" x=\"{}\" y=\"{}\" font-size=\"12\" font-weight=\"bold\" "
      "fill=\"{}\">GNSS track</text>\n",
      kAxisLeft + 4, num(top + kLabelDy), kTrackColour);
  std::optional<double> gnss_km;
  if (plot.gnss_distance_m) gnss_km = *plot.gnss_distance_m / 1000;
  out += fmt::format(
      "<text class=\"map-caption\" x=\"{}\" y=\"{}\" font-size=\"12\" text-anchor=\"end\">"
      "GNSS {}, odometer {}</text>\n",
      kAxisRight, num(top + kLabelDy), km_text(gnss_km), km_text(plot.odometer_km));
  out += fmt::format(
      "<rect class=\"map-frame\" x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"#fbfbf8\" "
      "stroke=\"{}\" stroke-width=\"1\"/>\n",
      num(kFrameLeft), num(frame_top), num(kFrameWidth), num(kFrameHeight), kFrameColour);

  // The track, without consecutive points that print the same (they add bytes, not shape).
  std::string points;
  std::string last;
  for (const auto& m : metres) {
    const Pt p = to_px(m);
    std::string xy = num(p.x) + "," + num(p.y);
    if (xy == last) continue;
    if (!points.empty()) points += ' ';
    points += xy;
    last = std::move(xy);
  }
  out += fmt::format(
      "<polyline class=\"track\" fill=\"none\" stroke=\"{}\" stroke-width=\"3\" "
      "stroke-linejoin=\"round\" stroke-linecap=\"round\" points=\"{}\"/>\n",
      kTrackColour, points);

  // Start and end: different shapes, so a loop ride shows both.
  const Pt start = to_px(metres.front()), end = to_px(metres.back());
  out += fmt::format(
      "<circle class=\"track-start\" cx=\"{}\" cy=\"{}\" r=\"6\" fill=\"#2ca02c\" "
      "stroke=\"#ffffff\" stroke-width=\"1.5\"/>\n",
      num(start.x), num(start.y));
  out += fmt::format(
      "<text class=\"track-label\" x=\"{}\" y=\"{}\" font-size=\"12\" fill=\"{}\">start</text>\n",
      num(start.x + 9), num(start.y - 8), kTextColour);
  out += fmt::format(
      "<rect class=\"track-end\" x=\"{}\" y=\"{}\" width=\"10\" height=\"10\" fill=\"#d62728\" "
      "stroke=\"#ffffff\" stroke-width=\"1.5\"/>\n",
      num(end.x - 5), num(end.y - 5));
  out += fmt::format(
      "<text class=\"track-label\" x=\"{}\" y=\"{}\" font-size=\"12\" fill=\"{}\">end</text>\n",
      num(end.x + 9), num(end.y + 17), kTextColour);

  // North arrow in the frame's top right corner.
  const double nx = kFrameLeft + kFrameWidth - 18, ny = frame_top + 10;
  out += fmt::format(
      "<path class=\"north-arrow\" d=\"M{0},{1} L{2},{3} L{0},{4} L{5},{3} Z\" fill=\"{6}\"/>\n",
      num(nx), num(ny), num(nx + 6), num(ny + 22), num(ny + 17), num(nx - 6), kTextColour);
  out += fmt::format("<text x=\"{}\" y=\"{}\" font-size=\"11\" text-anchor=\"middle\">N</text>\n",
                     num(nx), num(ny + 34));

  // Scale bar under the frame: at most a quarter of the frame's width.
  const double bar_m = scale_bar_m(kFrameWidth / 4 / px_per_m);
  const double bar_px = bar_m * px_per_m;
  const double by = top + kScaleBarDy;
  out += fmt::format(
      "<line class=\"scale-bar\" x1=\"{0}\" y1=\"{1}\" x2=\"{2}\" y2=\"{1}\" stroke=\"{3}\" "
      "stroke-width=\"2\"/>\n",
      num(kFrameLeft), num(by), num(kFrameLeft + bar_px), kTextColour);
  for (const double x : {kFrameLeft, kFrameLeft + bar_px}) {
    out += fmt::format(
        "<line x1=\"{0}\" y1=\"{1}\" x2=\"{0}\" y2=\"{2}\" stroke=\"{3}\" stroke-width=\"2\"/>\n",
        num(x), num(by - 5), num(by + 1), kTextColour);
  }
  out += fmt::format("<text class=\"scale-label\" x=\"{}\" y=\"{}\" font-size=\"11\">{}</text>\n",
                     num(kFrameLeft + bar_px + 8), num(by + 4), scale_label(bar_m));
  out += "</g>\n";
  return out;
}

std::string no_track_note(double y) {
  return fmt::format(
      "<text class=\"note no-track\" x=\"{}\" y=\"{}\" font-size=\"11\" fill=\"#888888\">"
      "no GNSS track for this ride</text>\n",
      kAxisLeft, ride_map::num(y));
}

}  // namespace fleetgw::tools
