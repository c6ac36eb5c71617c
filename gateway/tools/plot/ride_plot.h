// `fleetgw ride plot`: a ride as one self-contained SVG document (no scripts, no external
// fonts, images or style sheets), built from plain values so it is testable without a store.
//
// Contract:
//  * render_ride_svg(plot) returns the whole document: kSvgWidth x kSvgHeight user units (and
//    pixels), a title (ride id, start as ISO 8601 UTC, distance km, duration) and four panels
//    stacked on one time axis in minutes from the ride start: speed km/h, power W, SOC % and
//    assist level (drawn as steps, labelled with the names in `assist_names`, else 0xNN).
//    Every panel has a left axis line and a bottom axis line (<line class="axis axis-y|axis-x">
//    at x = kAxisLeft and y = the panel's bottom), tick marks with labels, light grid lines;
//    the time labels are under the last panel. A panel without data says "no data".
//  * Each series is one <path class="series series-NAME"> (NAME speed, power, soc, assist),
//    one subpath ("M") per run of samples: a run ends where the quantity is missing or two
//    consecutive samples are more than `gap_s` apart, so gaps stay gaps. A run of one sample is
//    a dot (<circle class="dot dot-NAME">). Long rides are thinned per pixel column keeping
//    each column's first, last, minimum and maximum point, so spikes survive.
//  * Every string that goes into the document (ride id, assist names) is made printable
//    (common::escape_controls: control characters as \n, \x1b..., invalid UTF-8 as U+FFFD)
//    and XML-escaped (& < > " '): the document is well-formed XML whatever the store holds.
//  * Numbers are written with '.' decimals whatever the locale; NaN and infinite values are
//    treated as missing.
//  * gap_threshold_s(samples) = max(5 s, 3 x the median interval between samples): the
//    default gap for telemetry sampled at 1 Hz while riding.
//  * The ride's GNSS track (`track`, two or more valid positions) adds a map panel under the
//    time panels (ride_plot_map.h) and makes the document kMapPanelHeight taller; without one
//    the document keeps its size and a note line under the time axis says "no GNSS track for
//    this ride". The time panels are the same either way.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "storage/track_text.h"

namespace fleetgw::tools {

inline constexpr int kSvgWidth = 900;
inline constexpr int kSvgHeight = 700;
inline constexpr int kAxisLeft = 80;    // x of every panel's left axis
inline constexpr int kAxisRight = 880;  // right end of the time axis

struct PlotSample {
  double t_s = 0;  // seconds since the ride start
  std::optional<double> speed_kmh;
  std::optional<double> power_w;  // voltage x current, discharge positive
  std::optional<double> soc_pct;
  std::optional<int> assist_level;
};

struct RidePlot {
  std::string ride_id;
  std::int64_t start_us = 0;
  double duration_s = 0;  // the time axis spans at least this (and every sample)
  std::optional<double> distance_km;
  bool open = false;                                      // the ride has not ended (yet)
  std::vector<PlotSample> samples;                        // in time order
  std::vector<std::pair<int, std::string>> assist_names;  // level -> name
  double gap_s = 5;
  // Where the ride went (ride_plot_map.h): positions in ride order (RidePlot is plain values;
  // plot_track() makes them from the store's column), the GNSS distance and, for the map's
  // caption, the odometer's distance (empty without odometer readings).
  std::vector<storage::TrackPoint> track;
  std::optional<double> gnss_distance_m;
  std::optional<double> odometer_km;
};

std::string render_ride_svg(const RidePlot& plot);

// `text` printable (escape_controls) and XML-escaped, for element content and attributes.
std::string xml_text(std::string_view text);

double gap_threshold_s(const std::vector<PlotSample>& samples);

}  // namespace fleetgw::tools
