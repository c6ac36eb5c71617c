// Test support for the registry, GBFS and MDS tests (issue 27): the real fleetgw-serve's
// administration options, registry rows through them, an MDS client, and the ingest rows the
// feeds read (written as the ingest writes them: the web fixture's INSERTs, which every web
// test uses; driving real gateways for a few dozen rows would take minutes, not seconds).
#pragma once

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <cstdint>
#include <string>
#include <vector>

#include "tests/web/web_fixture.h"

namespace fleetgw::testing {

inline constexpr const char* kTestProviderId = "3c95765d-4da6-41c6-b61e-1954472ec6c9";

// fleetgw-serve --pg ... ARGS (an administration run); its stdout+stderr in *output.
inline int serve_admin(ServeStack& stack, const std::vector<std::string>& args,
                       std::string* output = nullptr) {
  std::vector<std::string> argv = {FLEETGW_SERVE_BINARY, "--pg", stack.conninfo(), "--provider-id",
                                   kTestProviderId};
  argv.insert(argv.end(), args.begin(), args.end());
  const auto log = stack.dir() / "registry-admin.log";
  const int rc = run_for_exit_code(argv, log);
  if (output != nullptr) *output = read_text_file(log);
  return rc;
}

// The e-bike type every test registers (a 500 Wh pack, 10 Wh/km: 50 km on a full pack).
inline void register_ebike_type(ServeStack& stack) {
  const auto csv = stack.dir() / "types.csv";
  std::ofstream(csv) << "vehicle_type_id,name,form_factor,propulsion_type,max_speed_kph,"
                        "battery_capacity_wh,battery_capacity_mah,wh_per_km\n"
                        "ebike,City e-bike,bicycle,electric_assist,25,500,13800,10\n";
  std::string out;
  ASSERT_EQ(serve_admin(stack, {"--import-vehicle-types", csv.string()}, &out), 0) << out;
}

inline void register_vehicle(ServeStack& stack, const std::string& id) {
  std::string out;
  ASSERT_EQ(serve_admin(stack, {"--register-vehicle", id, "--vehicle-type", "ebike"}, &out), 0)
      << out;
}

// A ride record as the ingest stores it (positions in degrees, times in µs).
struct RideRow {
  std::string vehicle;
  std::string ride_id;
  std::int64_t sequence = 0;
  std::int64_t start_us = 0;
  std::int64_t end_us = 0;
  double start_lat = 0, start_lon = 0, end_lat = 0, end_lon = 0;
  int soc_start = 90, soc_end = 80;
  std::int64_t distance_m = 2400;
  std::int64_t energy_mwh = 24000;
};

inline void insert_ride(ServeStack& stack, const RideRow& r) {
  const auto e7 = [](double d) { return std::to_string(static_cast<long long>(d * 1e7)); };
  const fleetgw::PgParam p[] = {r.vehicle,
                                std::to_string(r.sequence),
                                std::to_string(r.end_us),
                                r.ride_id,
                                std::to_string(r.start_us),
                                std::to_string(r.distance_m),
                                std::to_string(r.energy_mwh),
                                std::to_string(r.soc_start),
                                std::to_string(r.soc_end),
                                e7(r.start_lat),
                                e7(r.start_lon),
                                e7(r.end_lat),
                                e7(r.end_lon)};
  stack.db().query(
      "INSERT INTO rides (vehicle_id, store_id, sequence, created_at_us, gateway_fw_version, "
      "ride_id, started_at_us, ended_at_us, duration_ms, distance_odo_m, energy_mwh, "
      "soc_start_pct, soc_end_pct, partial, start_lat_e7, start_lon_e7, end_lat_e7, end_lon_e7) "
      "VALUES ($1, 'store-1', $2, $3, '0.1.0', $4, $5, $3, ($3::bigint - $5::bigint) / 1000, $6, "
      "$7, $8, $9, false, $10, $11, $12, $13)",
      p, "ride row");
}

// A telemetry sample with a SOC (the fixture's insert_sample has none).
inline void insert_soc_sample(ServeStack& stack, const std::string& vehicle, std::int64_t seq,
                              std::int64_t at_us, int soc, double lat, double lon) {
  const fleetgw::PgParam p[] = {vehicle,
                                std::to_string(seq),
                                std::to_string(at_us),
                                std::to_string(soc),
                                std::to_string(static_cast<long long>(lat * 1e7)),
                                std::to_string(static_cast<long long>(lon * 1e7))};
  stack.db().query(
      "INSERT INTO telemetry_samples (vehicle_id, store_id, sequence, created_at_us, "
      "sampled_at_us, speed_dkmh, soc_pct, lat_e7, lon_e7) VALUES ($1, 'store-1', $2, $3, $3, 0, "
      "$4, $5, $6)",
      p, "soc sample");
}

inline httplib::Result mds_get(ServeStack& stack, const std::string& path, const std::string& token,
                               const std::string& accept = "application/vnd.mds+json;version=2.0") {
  httplib::Headers h;
  if (!token.empty()) h.emplace("Authorization", "Bearer " + token);
  if (!accept.empty()) h.emplace("Accept", accept);
  return stack.client().Get(path, h);
}

inline bool is_uuid_text(const nlohmann::json& j) {
  if (!j.is_string()) return false;
  const std::string s = j;
  if (s.size() != 36) return false;
  for (std::size_t i = 0; i < s.size(); ++i) {
    const bool dash = i == 8 || i == 13 || i == 18 || i == 23;
    if (dash != (s[i] == '-')) return false;
    if (!dash && !std::isxdigit(static_cast<unsigned char>(s[i]))) return false;
  }
  return true;
}

// The start of the UTC hour before the current one (an hour that has ended), and its name.
inline std::int64_t last_full_hour_us() {
  constexpr std::int64_t kHour = 3'600'000'000;
  return (now_us() / kHour - 1) * kHour;
}

inline std::string hour_param(std::int64_t hour_us) {
  const std::time_t t = static_cast<std::time_t>(hour_us / 1'000'000);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H", &tm);
  return buf;
}

}  // namespace fleetgw::testing
