// The store the `fleetgw ride plot` tests plot, written through the real storage::Store (shared
// by ride_plot_cli_tests and the ride_plot_fixture program of the Chromium rendering test).
//
// Two closed rides:
//  * "ride-normal", 2024-11-27T09:00:00Z, 10 min, a sample every second, no gap (601 samples);
//  * the latest, 2024-11-27T10:00:00Z to 10:28:00Z, 8.1 km, with a hostile id (markup, quotes,
//    an ampersand, ESC, a newline, invalid UTF-8). Samples every second, except: none between
//    10 and 12 min (the gateway was down), speed missing from 20 to 21 min; assist eco, then
//    norm from 5 min, sport from 15 min, eco from 24 min (kLatestSamples samples).
// The latest ride has a GNSS track (kLatestTrack: a square that does not close, 6.7 km of GNSS
// distance against 8.1 km of odometer); ride-normal had no fix (no track).
// Telemetry outside both windows (before, between and after the rides) has a speed of 999 km/h,
// so a plot that takes it in shows it.
#pragma once

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "storage/store.h"
#include "storage/track_text.h"

namespace fleetgw::testing::ride_plot_store {

inline constexpr std::int64_t kSec = 1'000'000;
inline constexpr std::int64_t kLatestStartUs = 1732701600LL * kSec;  // 2024-11-27T10:00:00Z
inline constexpr std::int64_t kNormalStartUs = kLatestStartUs - 3600 * kSec;
inline constexpr int kLatestSeconds = 28 * 60;
inline constexpr int kNormalSeconds = 10 * 60;
// 0..1680 s every second, without 601..719 s.
inline constexpr std::size_t kLatestSamples = kLatestSeconds + 1 - 119;
// Berlin: east 0.0295 degrees (2.0 km), north 0.0135 degrees (1.5 km), west back, then south
// to 0.3 km north of the start.
inline const std::vector<storage::TrackPoint> kLatestTrack = {
    {52.52, 13.405}, {52.52, 13.4345}, {52.5335, 13.4345}, {52.5335, 13.405}, {52.5227, 13.405}};
inline constexpr double kLatestGnssM = 6693;
inline const std::string kHostileRideId = "<script>alert(\"x\")</script> & 'q' \x1b[2J\nnext\xff";

inline storage::RideRow plotted_ride(const std::string& id, std::int64_t start_us, int seconds,
                                  double km) {
  storage::RideRow r;
  r.ride_id = id;
  r.state = storage::RideState::kClosed;
  r.start_us = start_us;
  r.end_us = start_us + seconds * kSec;
  r.duration_s = seconds;
  r.moving_s = seconds * 0.9;
  r.start_odo_km = 100;
  r.end_odo_km = 100 + km;
  r.distance_km = km;
  r.distance_integrated_km = km * 0.98;
  r.max_speed_kmh = 25;
  r.avg_speed_kmh = km / (seconds / 3600.0);
  r.soc_start_pct = 90;
  r.soc_end_pct = 81;
  return r;
}

inline storage::TelemetryRow plotted_sample(std::int64_t start_us, int t) {
  storage::TelemetryRow s;
  s.ts_us = start_us + t * kSec;
  s.speed_kmh = 18 + 7 * std::sin(t / 60.0);
  s.voltage_v = 48 - t / 600.0;
  s.current_a = 6 + 4 * std::sin(t / 45.0);
  s.soc_pct = 90 - 9.0 * t / kLatestSeconds;
  s.assist_level = t < 300 ? 1 : t < 900 ? 2 : t < 1440 ? 3 : 1;
  return s;
}

inline storage::TelemetryRow outside_sample(std::int64_t ts_us) {
  storage::TelemetryRow s;
  s.ts_us = ts_us;
  s.speed_kmh = 999;
  s.assist_level = 4;
  s.soc_pct = 50;
  return s;
}

inline void write_ride_store(const std::filesystem::path& path) {
  storage::StoreOptions o;
  o.path = path.string();
  storage::Store store(o);
  storage::Batch b;
  b.now_us = kLatestStartUs;
  b.rides.push_back(
      {plotted_ride("ride-normal", kNormalStartUs, kNormalSeconds, 3.0), std::nullopt});
  storage::RideRow latest = plotted_ride(kHostileRideId, kLatestStartUs, kLatestSeconds, 8.1);
  latest.start_lat_deg = kLatestTrack.front().lat_deg;
  latest.start_lon_deg = kLatestTrack.front().lon_deg;
  latest.end_lat_deg = kLatestTrack.back().lat_deg;
  latest.end_lon_deg = kLatestTrack.back().lon_deg;
  latest.gnss_distance_m = kLatestGnssM;
  latest.track = storage::track_text(kLatestTrack);
  b.rides.push_back({latest, std::nullopt});
  for (std::int64_t at :
       {kNormalStartUs - 30 * kSec, kNormalStartUs - 1,
        kNormalStartUs + (kNormalSeconds + 1) * kSec, kLatestStartUs - 1,
        kLatestStartUs + kLatestSeconds * kSec + 1, kLatestStartUs + 3600 * kSec}) {
    b.telemetry.push_back({outside_sample(at), std::nullopt});
  }
  for (int t = 0; t <= kNormalSeconds; ++t) {
    b.telemetry.push_back({plotted_sample(kNormalStartUs, t), std::nullopt});
  }
  for (int t = 0; t <= kLatestSeconds; ++t) {
    if (t > 600 && t < 720) continue;  // the gateway was down
    auto s = plotted_sample(kLatestStartUs, t);
    if (t >= 1200 && t < 1260) s.speed_kmh.reset();
    b.telemetry.push_back({s, std::nullopt});
  }
  const auto r = store.write(b);
  if (!r.ok()) throw std::runtime_error("ride plot store: " + r.status().message);
}

}  // namespace fleetgw::testing::ride_plot_store
