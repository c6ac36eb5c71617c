// The SVG builder of `fleetgw ride plot` (gateway/tools/plot/ride_plot.h) without a store: the
// document is well-formed XML (checked by a small parser of the subset it writes), strings are
// escaped, gaps stay gaps, assist levels are steps with their names, long rides are thinned.
#include "gateway/tools/plot/ride_plot.h"

#include <gtest/gtest.h>

#include <cctype>
#include <cmath>
#include <string>
#include <string_view>
#include <vector>

#include "gateway/common/untrusted_text.h"
#include "tests/config/svg_xml_check.h"

namespace fleetgw::testing::ride_plot_unit {
namespace {

using tools::PlotSample;
using tools::RidePlot;

std::size_t count(std::string_view text, std::string_view what) {
  std::size_t n = 0;
  for (auto at = text.find(what); at != std::string_view::npos; at = text.find(what, at + 1)) {
    ++n;
  }
  return n;
}

// The d attribute of the series path of `name` ("" when there is none).
std::string path_of(const std::string& svg, std::string_view name) {
  const auto at = svg.find("class=\"series series-" + std::string(name) + "\"");
  if (at == std::string::npos) return "";
  const auto d = svg.find(" d=\"", at);
  return svg.substr(d + 4, svg.find('"', d + 4) - d - 4);
}

PlotSample sample(double t, double speed, double power, double soc, int assist) {
  PlotSample s;
  s.t_s = t;
  s.speed_kmh = speed;
  s.power_w = power;
  s.soc_pct = soc;
  s.assist_level = assist;
  return s;
}

RidePlot steady_ride(int seconds) {
  RidePlot p;
  p.ride_id = "20241127T100000.000000Z";
  p.start_us = 1732701600LL * 1'000'000;
  p.duration_s = seconds;
  p.distance_km = 8.1;
  for (int t = 0; t <= seconds; ++t) {
    p.samples.push_back(
        sample(t, 20 + 5 * std::sin(t / 30.0), 250, 90 - t / 200.0, t < 60 ? 1 : 2));
  }
  return p;
}

TEST(RidePlotSvg, IsWellFormedWithTitleAxesAndFourPanels) {
  const std::string svg = tools::render_ride_svg(steady_ride(600));
  EXPECT_EQ(xml_problem(svg), "");
  EXPECT_TRUE(svg.starts_with("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<svg "));
  EXPECT_NE(svg.find("xmlns=\"http://www.w3.org/2000/svg\" width=\"900\" height=\"700\""),
            std::string::npos);
  EXPECT_NE(svg.find(">Ride 20241127T100000.000000Z</text>"), std::string::npos);
  EXPECT_NE(svg.find("2024-11-27T10:00:00Z \u00b7 8.10 km \u00b7 10.0 min"), std::string::npos);
  EXPECT_NE(svg.find(">minutes from ride start</text>"), std::string::npos);
  for (const char* id : {"panel-speed", "panel-power", "panel-soc", "panel-assist"}) {
    EXPECT_NE(svg.find(std::string("id=\"") + id + "\""), std::string::npos) << id;
  }
  EXPECT_EQ(count(svg, "class=\"axis axis-y\" x1=\"80\""), 4u);
  EXPECT_EQ(count(svg, "class=\"axis axis-x\" x1=\"80\""), 4u);
  // Nothing external: no scripts, no links, no style sheets, no images.
  for (const char* bad : {"<script", "href", "<style", "<image", "@import", "url("}) {
    EXPECT_EQ(svg.find(bad), std::string::npos) << bad;
  }
  // Time ticks every minute up to 10 (nice steps), under the last panel only.
  EXPECT_EQ(count(svg, "text-anchor=\"middle\">10</text>"), 1u);
  EXPECT_EQ(count(svg, "no data"), 0u);
}

TEST(RidePlotSvg, HostileRideIdIsEscapedEverywhere) {
  RidePlot p = steady_ride(60);
  p.ride_id = "<script>alert(\"x\")</script> & 'q' \x1b[2J\nnext\xff\xef\xbf\xbe";
  p.assist_names = {{1, "<b>eco&\"'"}};
  const std::string svg = tools::render_ride_svg(p);
  EXPECT_EQ(xml_problem(svg), "");
  EXPECT_EQ(svg.find("<script"), std::string::npos);
  EXPECT_EQ(svg.find("<b>"), std::string::npos);
  const std::string escaped =
      "&lt;script&gt;alert(&quot;x&quot;)&lt;/script&gt; &amp; &apos;q&apos; \\x1b[2J\\nnext"
      "\xef\xbf\xbd\xef\xbf\xbd";
  EXPECT_NE(svg.find("<title>Ride " + escaped + "</title>"), std::string::npos)
      << svg.substr(0, 600);
  EXPECT_NE(svg.find(">Ride " + escaped + "</text>"), std::string::npos);
  EXPECT_NE(svg.find(">&lt;b&gt;eco&amp;&quot;&apos;</text>"), std::string::npos);
}

TEST(RidePlotSvg, XmlTextEscapesTheFiveCharactersAndControls) {
  EXPECT_EQ(tools::xml_text("a&b<c>d\"e'f"), "a&amp;b&lt;c&gt;d&quot;e&apos;f");
  EXPECT_EQ(tools::xml_text("x\ty\x01z"), "x\\ty\\x01z");
  EXPECT_EQ(tools::xml_text("\xff"), "\xef\xbf\xbd");
}

TEST(RidePlotSvg, GapsAndMissingValuesBreakTheLines) {
  RidePlot p;
  p.ride_id = "r";
  p.duration_s = 393;
  for (int t = 0; t <= 100; ++t) p.samples.push_back(sample(t, 10, 100, 80, 1));
  for (int t = 200; t <= 300; ++t) {  // 100 s without samples before
    PlotSample s = sample(t, 12, 120, 79, 2);
    if (t >= 250 && t < 260) s.speed_kmh.reset();  // speed not measured
    p.samples.push_back(s);
  }
  p.samples.push_back(sample(390, 15, 150, 78, 3));  // alone after a gap: a dot
  p.gap_s = tools::gap_threshold_s(p.samples);
  EXPECT_DOUBLE_EQ(p.gap_s, 5.0);
  const std::string svg = tools::render_ride_svg(p);
  EXPECT_EQ(xml_problem(svg), "");
  EXPECT_EQ(count(path_of(svg, "speed"), "M"), 3u) << path_of(svg, "speed");
  EXPECT_EQ(count(path_of(svg, "power"), "M"), 2u);
  EXPECT_EQ(count(path_of(svg, "soc"), "M"), 2u);
  EXPECT_EQ(count(svg, "class=\"dot dot-speed\""), 1u);
  EXPECT_EQ(count(svg, "class=\"dot dot-power\""), 1u);
  // Assist: three runs of steps; the lone last sample holds to the end (3 s, within the gap)...
  EXPECT_EQ(count(path_of(svg, "assist"), "M"), 3u) << path_of(svg, "assist");
  EXPECT_EQ(count(svg, "class=\"dot dot-assist\""), 0u);
  // ... and without the gap threshold everything is one line.
  p.gap_s = 1000;
  const std::string joined = tools::render_ride_svg(p);
  EXPECT_EQ(count(path_of(joined, "power"), "M"), 1u);
  EXPECT_EQ(count(path_of(joined, "speed"), "M"), 2u);  // the missing speeds still break it
}

TEST(RidePlotSvg, AssistIsDrawnAsNamedSteps) {
  RidePlot p = steady_ride(120);
  p.assist_names = {{1, "eco"}, {2, "norm"}};
  const std::string svg = tools::render_ride_svg(p);
  const std::string d = path_of(svg, "assist");
  EXPECT_EQ(count(d, "M"), 1u);
  EXPECT_EQ(count(d, " V"), 1u) << d;  // one change of level: eco to norm
  EXPECT_EQ(count(d, " H"), 2u) << d;
  EXPECT_NE(svg.find(">eco</text>"), std::string::npos);
  EXPECT_NE(svg.find(">norm</text>"), std::string::npos);
  p.assist_names.clear();
  const std::string unnamed = tools::render_ride_svg(p);
  EXPECT_NE(unnamed.find(">0x01</text>"), std::string::npos);
}

TEST(RidePlotSvg, PanelWithoutDataSaysSo) {
  RidePlot p = steady_ride(60);
  for (auto& s : p.samples) s.power_w.reset();
  p.samples[3].soc_pct = std::nan("");  // NaN is missing, not a point
  const std::string svg = tools::render_ride_svg(p);
  EXPECT_EQ(xml_problem(svg), "");
  EXPECT_EQ(count(svg, ">no data</text>"), 1u);
  EXPECT_EQ(path_of(svg, "power"), "");
  EXPECT_EQ(svg.find("nan"), std::string::npos);
  EXPECT_EQ(count(path_of(svg, "soc"), "M"), 2u);
  RidePlot empty;
  empty.ride_id = "empty";
  const std::string none = tools::render_ride_svg(empty);
  EXPECT_EQ(xml_problem(none), "");
  EXPECT_EQ(count(none, ">no data</text>"), 4u);
}

TEST(RidePlotSvg, LongRidesAreThinnedKeepingSpikes) {
  RidePlot p = steady_ride(36'000);  // ten hours at 1 Hz
  p.samples[20'000].speed_kmh = 80;  // one spike
  const std::string svg = tools::render_ride_svg(p);
  EXPECT_EQ(xml_problem(svg), "");
  const std::string d = path_of(svg, "speed");
  EXPECT_LT(count(d, ","), 4u * 801u);  // at most 4 points per pixel column
  EXPECT_LT(svg.size(), 400'000u);
  // The spike is the top of the scale (80 km/h -> y = top + headroom of the first panel).
  EXPECT_NE(d.find(",86.0"), std::string::npos) << "spike lost";
}

TEST(RidePlotSvg, GapThresholdFollowsTheSamplingInterval) {
  std::vector<PlotSample> samples;
  EXPECT_DOUBLE_EQ(tools::gap_threshold_s(samples), 5.0);
  for (int t = 0; t < 10; ++t) samples.push_back(sample(t * 10.0, 1, 1, 1, 1));
  EXPECT_DOUBLE_EQ(tools::gap_threshold_s(samples), 30.0);
}

}  // namespace
}  // namespace fleetgw::testing::ride_plot_unit
