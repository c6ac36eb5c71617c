// The map panel of `fleetgw ride plot` (gateway/tools/plot/ride_plot_map.h) without a store: a
// known track drawn north up, east right, at one scale on both axes that the scale bar agrees with;
// start and end markers and the caption; no panel but a note without a track; a stored track
// that is damaged, hostile or huge gives no panel and a warning naming the ride, never a crash.
#include "gateway/tools/plot/ride_plot_map.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include "gateway/tools/plot/ride_plot.h"
#include "storage/track_text.h"
#include "tests/config/svg_xml_check.h"

namespace fleetgw::testing::ride_plot_map_unit {
namespace {

using storage::TrackPoint;
using tools::RidePlot;

struct Xy {
  double x = 0;
  double y = 0;
};

std::size_t occurrences(std::string_view text, std::string_view what) {
  std::size_t n = 0;
  for (auto at = text.find(what); at != std::string_view::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

// The value of attribute `name` of the first element with class `cls` ("" when none).
std::string attribute(const std::string& svg, std::string_view cls, std::string_view name) {
  const auto at = svg.find("class=\"" + std::string(cls) + "\"");
  if (at == std::string::npos) return "";
  const auto end = svg.find('>', at);
  const auto a = svg.find(" " + std::string(name) + "=\"", at);
  if (a == std::string::npos || a > end) return "";
  const auto from = a + name.size() + 3;
  return svg.substr(from, svg.find('"', from) - from);
}

std::vector<Xy> polyline(const std::string& svg) {
  std::vector<Xy> out;
  std::istringstream in(attribute(svg, "track", "points"));
  std::string pair;
  while (in >> pair) {
    const auto comma = pair.find(',');
    out.push_back({std::stod(pair.substr(0, comma)), std::stod(pair.substr(comma + 1))});
  }
  return out;
}

double number(const std::string& svg, std::string_view cls, std::string_view name) {
  const std::string v = attribute(svg, cls, name);
  return v.empty() ? std::nan("") : std::stod(v);
}

RidePlot ride_with(std::vector<TrackPoint> track) {
  RidePlot p;
  p.ride_id = "ride-map";
  p.start_us = 1732701600LL * 1'000'000;
  p.duration_s = 600;
  p.distance_km = 8.1;
  p.odometer_km = 8.1;
  p.gnss_distance_m = 6712;
  for (int t = 0; t <= 600; ++t) {
    tools::PlotSample s;
    s.t_s = t;
    s.speed_kmh = 20;
    s.power_w = 200;
    s.soc_pct = 90 - t / 100.0;
    s.assist_level = 2;
    p.samples.push_back(s);
  }
  p.track = std::move(track);
  return p;
}

// Berlin: east 0.0295 degrees (about 2.0 km), north 0.0135 degrees (about 1.5 km), west back,
// then south to 0.3 km north of the start: a square that does not close.
const std::vector<TrackPoint> kSquare = {
    {52.52, 13.405}, {52.52, 13.4345}, {52.5335, 13.4345}, {52.5335, 13.405}, {52.5227, 13.405}};

TEST(RidePlotMap, SquareTrackIsNorthUpEastRightAtOneScale) {
  const std::string svg = tools::render_ride_svg(ride_with(kSquare));
  ASSERT_EQ(xml_problem(svg), "");
  EXPECT_NE(svg.find("width=\"900\" height=\"" +
                     std::to_string(tools::kSvgHeight + tools::kMapPanelHeight) + "\""),
            std::string::npos);
  EXPECT_NE(svg.find("id=\"panel-map\""), std::string::npos);
  EXPECT_EQ(svg.find("no GNSS track"), std::string::npos);
  const auto pts = polyline(svg);
  ASSERT_EQ(pts.size(), 5u) << attribute(svg, "track", "points");
  // East is right (y unchanged), north is up (SVG y decreases), west back to the start's x.
  EXPECT_GT(pts[1].x, pts[0].x + 100);
  EXPECT_NEAR(pts[1].y, pts[0].y, 0.11);
  EXPECT_LT(pts[2].y, pts[1].y - 100);
  EXPECT_NEAR(pts[2].x, pts[1].x, 0.11);
  EXPECT_NEAR(pts[3].x, pts[0].x, 0.11);
  EXPECT_GT(pts[4].y, pts[3].y);
  EXPECT_LT(pts[4].y, pts[0].y);
  // One scale: the drawn sides have the ground's proportions (east shrinks with cos(latitude)).
  constexpr double kRad = std::numbers::pi / 180;
  const double lat0 = (52.52 + 52.5335) / 2;
  const double east_m = 0.0295 * kRad * 6'371'008.8 * std::cos(lat0 * kRad);
  const double north_m = 0.0135 * kRad * 6'371'008.8;
  const double px_per_m = (pts[1].x - pts[0].x) / east_m;
  EXPECT_NEAR((pts[1].y - pts[2].y) / north_m, px_per_m, px_per_m * 0.002);
  EXPECT_NEAR((pts[0].y - pts[4].y) / (0.0027 * kRad * 6'371'008.8), px_per_m, px_per_m * 0.01);
  // Fitted into the frame: everything inside, the north-south extent fills most of its height.
  const double fx = number(svg, "map-frame", "x"), fy = number(svg, "map-frame", "y");
  const double fw = number(svg, "map-frame", "width"), fh = number(svg, "map-frame", "height");
  for (const auto& p : pts) {
    EXPECT_TRUE(p.x > fx && p.x < fx + fw && p.y > fy && p.y < fy + fh) << p.x << "," << p.y;
  }
  EXPECT_GT(pts[0].y - pts[2].y, 0.8 * fh);
  // The scale bar agrees with the track's scale: 500 m (a quarter of the frame is ~900 m).
  EXPECT_NE(svg.find(">500 m</text>"), std::string::npos);
  const double bar_px = number(svg, "scale-bar", "x2") - number(svg, "scale-bar", "x1");
  EXPECT_NEAR(bar_px / 500, px_per_m, px_per_m * 0.005);
  // Start and end markers on the first and last point, labelled; the caption's distances.
  EXPECT_NEAR(number(svg, "track-start", "cx"), pts.front().x, 0.11);
  EXPECT_NEAR(number(svg, "track-start", "cy"), pts.front().y, 0.11);
  EXPECT_NEAR(number(svg, "track-end", "x") + 5, pts.back().x, 0.11);
  EXPECT_NEAR(number(svg, "track-end", "y") + 5, pts.back().y, 0.11);
  EXPECT_NE(svg.find(">start</text>"), std::string::npos);
  EXPECT_NE(svg.find(">end</text>"), std::string::npos);
  EXPECT_NE(svg.find(">GNSS 6.7 km, odometer 8.1 km</text>"), std::string::npos);
  EXPECT_EQ(attribute(svg, "track", "stroke"), tools::kTrackColour);
}

TEST(RidePlotMap, TimePanelsAreTheSameWithAndWithoutATrack) {
  const std::string with = tools::render_ride_svg(ride_with(kSquare));
  const std::string without = tools::render_ride_svg(ride_with({}));
  const auto panels = [](const std::string& svg) {
    const auto from = svg.find("<text class=\"title\"");
    return svg.substr(from, svg.find("minutes from ride start</text>") - from);
  };
  EXPECT_EQ(panels(with), panels(without));
  EXPECT_EQ(occurrences(with, "class=\"axis axis-y\""), 4u);
}

TEST(RidePlotMap, NoTrackMeansNoPanelAndANote) {
  for (const auto& track : std::vector<std::vector<TrackPoint>>{
           {},
           {{52.52, 13.405}},                                                    // never moved 5 m
           {{std::nan(""), 13.4}, {95, 13.4}, {52.5, 181}, {52.52, 13.405}}}) {  // one valid
    const std::string svg = tools::render_ride_svg(ride_with(track));
    EXPECT_EQ(xml_problem(svg), "");
    EXPECT_NE(svg.find("height=\"" + std::to_string(tools::kSvgHeight) + "\""), std::string::npos);
    EXPECT_EQ(occurrences(svg, ">no GNSS track for this ride</text>"), 1u);
    EXPECT_EQ(svg.find("panel-map"), std::string::npos);
    EXPECT_EQ(svg.find("<polyline"), std::string::npos);
    EXPECT_EQ(svg.find("nan"), std::string::npos);
  }
}

TEST(RidePlotMap, StoredTrackIsReadWithTheStoresParser) {
  std::ostringstream err;
  const auto points = tools::plot_track("r", storage::track_text(kSquare), err);
  EXPECT_EQ(points, kSquare);
  EXPECT_EQ(err.str(), "");
  EXPECT_TRUE(tools::plot_track("r", std::nullopt, err).empty());  // NULL: no fix, no warning
  EXPECT_EQ(err.str(), "");
}

TEST(RidePlotMap, BadStoredTrackIsLeftOutWithAWarningNamingTheRide) {
  const std::string huge(tools::kMaxTrackTextBytes + 1, ' ');
  const std::string deep(1'000'000, '[');
  std::string flat = "[";  // just under the size limit, half a million JSON numbers
  for (int i = 0; i < 500'000; ++i) flat += "0,";
  flat += "0]";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"[[13.4,52.5],[13.5", "track: not valid JSON"},
      {"{\"type\":\"LineString\"}", "track: not a JSON array of [longitude, latitude] positions"},
      {"[[\"13.4\",52.5],[13.5,52.5]]",
       "track: position 0: not an array of two numbers [longitude, latitude]"},
      {"[[13.4,52.5],[200,52.5]]", "track: position 1: longitude 200 is outside -180..180"},
      {"[[13.4,52.5],[13.4,-91]]", "track: position 1: latitude -91 is outside -90..90"},
      {deep, "track: nested deeper than [[longitude, latitude], ...]"},
      {flat, "track: position 0: not an array of two numbers [longitude, latitude]"},
      {huge, "track: 1048577 bytes, more than the 1048576 a plot reads"},
  };
  for (const auto& [text, problem] : cases) {
    std::ostringstream err;
    RidePlot p = ride_with({});
    p.ride_id = "ride <7>\n";
    p.track = tools::plot_track(p.ride_id, text, err);
    EXPECT_TRUE(p.track.empty()) << problem;
    EXPECT_EQ(err.str(),
              "fleetgw ride plot: ride 'ride <7>\\n': " + problem + "; plotted without it\n");
    const std::string svg = tools::render_ride_svg(p);
    EXPECT_EQ(xml_problem(svg), "");
    EXPECT_EQ(svg.find("panel-map"), std::string::npos);
    EXPECT_EQ(occurrences(svg, ">no GNSS track for this ride</text>"), 1u);
  }
}

TEST(RidePlotMap, LongTracksAreCappedKeepingTheEnds) {
  // 60,000 positions zig-zagging 100 m east and back while going north: little to merge.
  std::vector<TrackPoint> track;
  for (int i = 0; i < 60'000; ++i) {
    track.push_back({48.0 + i * 1e-5, 11.5 + (i % 3) * 0.00135});
  }
  const std::string svg = tools::render_ride_svg(ride_with(track));
  EXPECT_EQ(xml_problem(svg), "");
  const auto pts = polyline(svg);
  EXPECT_LE(pts.size(), tools::kMaxMapPoints);
  EXPECT_GT(pts.size(), tools::kMaxMapPoints / 4);
  EXPECT_LT(svg.size(), 600'000u);
  // The first and the last position are drawn: the start at the bottom, the end at the top.
  EXPECT_NEAR(number(svg, "track-start", "cy"), pts.front().y, 0.11);
  EXPECT_NEAR(number(svg, "track-end", "y") + 5, pts.back().y, 0.11);
  EXPECT_GT(pts.front().y, pts.back().y + 300);
}

TEST(RidePlotMap, TrackAcrossTheAntimeridianStaysInOnePiece) {
  const std::string svg = tools::render_ride_svg(
      ride_with({{-17.0, 179.9995}, {-17.0, -179.9995}, {-17.0005, -179.999}}));
  EXPECT_EQ(xml_problem(svg), "");
  const auto pts = polyline(svg);
  ASSERT_EQ(pts.size(), 3u);
  EXPECT_GT(pts[1].x, pts[0].x);  // east across 180 degrees, not 40,000 km west
  EXPECT_GT(pts[2].y, pts[1].y);  // then south
  EXPECT_NE(svg.find(" m</text>"), std::string::npos) << "a scale bar in metres";
}

TEST(RidePlotMap, CaptionSaysUnknownForMissingOrImplausibleDistances) {
  RidePlot p = ride_with(kSquare);
  p.gnss_distance_m = std::nan("");
  p.odometer_km.reset();
  EXPECT_NE(tools::render_ride_svg(p).find(">GNSS unknown, odometer unknown</text>"),
            std::string::npos);
  p.gnss_distance_m = 1e300;
  p.odometer_km = -3;
  EXPECT_NE(tools::render_ride_svg(p).find(">GNSS unknown, odometer unknown</text>"),
            std::string::npos);
  p.gnss_distance_m = 420;
  p.odometer_km = 0.5;
  EXPECT_NE(tools::render_ride_svg(p).find(">GNSS 0.4 km, odometer 0.5 km</text>"),
            std::string::npos);
}

TEST(RidePlotMap, StandingStillIsDrawnAtAMinimumExtent) {
  // Two positions 1 m apart (GNSS jitter): a short line, not a line across the whole frame.
  const std::string svg = tools::render_ride_svg(ride_with({{52.52, 13.405}, {52.52, 13.40501}}));
  EXPECT_EQ(xml_problem(svg), "");
  const auto pts = polyline(svg);
  ASSERT_EQ(pts.size(), 2u);
  EXPECT_LT(pts[1].x - pts[0].x, 100);
  EXPECT_GT(pts[1].x - pts[0].x, 1);
  EXPECT_NE(svg.find(">10 m</text>"), std::string::npos);
}

}  // namespace
}  // namespace fleetgw::testing::ride_plot_map_unit
