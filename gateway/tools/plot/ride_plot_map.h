// The map panel of `fleetgw ride plot` (ride_plot.h): the ride's GNSS track drawn under the time
// panels, self-contained (no tiles, no network), from plain values so it is testable without a
// store.
//
// Contract:
//  * plot_track(ride_id, text, err) turns the stored `rides.track` column (storage/track_text.h,
//    read with its own parser parse_track_text) into RidePlot::track. No column (NULL): no
//    track, silently. A column that is not a valid track (not JSON, another shape, a coordinate
//    out of range, nested deeper than a track, more than kMaxTrackTextBytes) gives no track and
//    one line on `err`: "fleetgw ride plot: ride 'ID': track: PROBLEM; plotted without it"
//    (ID made printable). It never throws.
//  * map_panel_svg(plot, top) is the panel's SVG elements from y = top down, kMapPanelHeight
//    high, when plot.track has two or more valid positions (finite, latitude -90..90,
//    longitude -180..180; others are skipped); else nullopt. The panel:
//      - <g class="panel" id="panel-map">, a label "GNSS track" and the caption
//        "GNSS 5.9 km, odometer 6.0 km" (<text class="map-caption">; "unknown" for a
//        distance that is missing or not a plausible number);
//      - a frame (<rect class="map-frame">) and the track as one
//        <polyline class="track" points="x,y ...">, in a local equirectangular projection:
//        metres east and north of the track's centre, equal scale on both axes (shapes keep
//        their proportions), north up, east right, fitted into the frame; a track across the
//        antimeridian is kept in one piece;
//      - start and end markers (<circle class="track-start">, <rect class="track-end">) with
//        the labels "start" and "end", a north arrow, and a scale bar (<line class="scale-bar">)
//        of 1, 2 or 5 x 10^n m labelled in m or km;
//      - at most kMaxMapPoints positions (evenly picked, first and last kept), and no two
//        consecutive points that print the same, so the document stays small.
//  * no_track_note(y) is the line a plot without a map gets: "no GNSS track for this ride".
#pragma once

#include <cstddef>
#include <optional>
#include <ostream>
#include <string>
#include <string_view>
#include <vector>

#include "gateway/tools/plot/ride_plot.h"
#include "storage/track_text.h"

namespace fleetgw::tools {

inline constexpr std::size_t kMaxMapPoints = 20'000;
// About 43,000 positions: ten times the ride tracker's bound (4096 vertices, ~100 kB,
// gateway/domain/ride_track.h), small enough that parsing a hostile column costs tens of MB at
// most, even on the bike.
inline constexpr std::size_t kMaxTrackTextBytes = 1u << 20;
inline constexpr int kMapPanelHeight = 430;
inline constexpr std::string_view kTrackColour = "#ff7f0e";

std::vector<storage::TrackPoint> plot_track(std::string_view ride_id,
                                            const std::optional<std::string>& text,
                                            std::ostream& err);

std::optional<std::string> map_panel_svg(const RidePlot& plot, double top);

std::string no_track_note(double y);

}  // namespace fleetgw::tools
