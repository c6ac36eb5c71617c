// The ride plot and the speed limit's reasons (ride_api.h).
#include "backend/web/ride_api.h"

#include <string>

#include "backend/web/fleet_api.h"

namespace fleetgw::web {
namespace {

using nlohmann::json;

json ride_opt_int(const PgResult& r, int row, int col) {
  const auto v = r.int64_or_null(row, col);
  return v ? json(*v) : json(nullptr);
}

json ride_scaled(const PgResult& r, int row, int col, double divisor) {
  const auto v = r.int64_or_null(row, col);
  return v ? json(static_cast<double>(*v) / divisor) : json(nullptr);
}

// The samples of a ride, every k-th of them so that at most kMaxRideSamples come back (the
// last one always: the plot ends where the ride ends). One pass in PostgreSQL; the time range
// prunes telemetry's day partitions and uses telemetry_by_time.
constexpr std::string_view kRideSamplesSql = R"sql(
WITH s AS (
  SELECT sampled_at_us, speed_dkmh, power_w, soc_pct, lat_e7, lon_e7,
         row_number() OVER (ORDER BY sampled_at_us, sequence) AS rn, count(*) OVER () AS n
  FROM telemetry_samples
  WHERE vehicle_id = $1 AND sampled_at_us BETWEEN $2::bigint AND $3::bigint)
SELECT sampled_at_us, speed_dkmh, power_w, soc_pct, lat_e7, lon_e7, n FROM s
WHERE (rn - 1) % greatest(1, ceil(n / $4::numeric))::bigint = 0 OR rn = n
ORDER BY sampled_at_us
)sql";

}  // namespace

std::optional<json> ride_detail(PgConnection& c, std::string_view vehicle_id,
                                std::string_view ride_id) {
  const PgParam p[] = {std::string(vehicle_id), std::string(ride_id)};
  const PgResult r = c.query(
      "SELECT ride_id, started_at_us, ended_at_us, distance_odo_m, distance_gnss_m, "
      "max_speed_dkmh, avg_speed_dkmh, energy_mwh, soc_start_pct, soc_end_pct, partial, "
      "coalesce(ended_at_us, (extract(epoch FROM clock_timestamp()) * 1e6)::bigint) "
      "FROM rides WHERE vehicle_id = $1 AND ride_id = $2 "
      "ORDER BY created_at_us DESC, sequence DESC LIMIT 1",
      p, "ride");
  if (r.rows() != 1) return std::nullopt;
  json out;
  out["vehicle_id"] = std::string(vehicle_id);
  out["ride"] = {{"ride_id", r.str(0, 0)},
                 {"started_at_us", ride_opt_int(r, 0, 1)},
                 {"ended_at_us", ride_opt_int(r, 0, 2)},
                 {"distance_odo_m", ride_opt_int(r, 0, 3)},
                 {"distance_gnss_m", ride_opt_int(r, 0, 4)},
                 {"max_speed_dkmh", ride_opt_int(r, 0, 5)},
                 {"avg_speed_dkmh", ride_opt_int(r, 0, 6)},
                 {"energy_mwh", ride_opt_int(r, 0, 7)},
                 {"soc_start_pct", ride_opt_int(r, 0, 8)},
                 {"soc_end_pct", ride_opt_int(r, 0, 9)},
                 {"partial", r.boolean(0, 10)}};
  out["fields"] = {"t_us", "speed_kmh", "power_w", "soc_pct", "lat", "lon"};
  out["samples"] = json::array();
  out["samples_in_ride"] = 0;
  const auto from = r.int64_or_null(0, 1);
  if (!from) return out;  // no start time: nothing to plot
  const PgParam q[] = {std::string(vehicle_id), std::to_string(*from),
                       std::to_string(r.int64_or_null(0, 11).value_or(*from)),
                       std::to_string(kMaxRideSamples)};
  const PgResult s = c.query(kRideSamplesSql, q, "ride samples");
  for (int i = 0; i < s.rows(); ++i) {
    out["samples"].push_back({ride_opt_int(s, i, 0), ride_scaled(s, i, 1, 10.0),
                              ride_opt_int(s, i, 2), ride_opt_int(s, i, 3),
                              ride_scaled(s, i, 4, 1e7), ride_scaled(s, i, 5, 1e7)});
  }
  if (s.rows() > 0) out["samples_in_ride"] = s.int64_or_null(0, 6).value_or(0);
  return out;
}

json speed_limit(PgConnection& c, std::string_view vehicle_id, const json& reported) {
  json out;
  out["in_force_kmh"] = nullptr;
  if (reported.is_object() && reported.contains("speed_limit_dkmh") &&
      reported["speed_limit_dkmh"].is_number()) {
    out["in_force_kmh"] = reported["speed_limit_dkmh"].get<double>() / 10.0;
  }
  const PgParam p[] = {std::string(vehicle_id)};
  const PgResult cap = c.query(
      "SELECT operator, params, result_at_us, limit_in_force, command_id FROM console_commands "
      "WHERE vehicle_id = $1 AND action = 'speed_limit' AND result = 'succeeded' "
      "ORDER BY result_at_us DESC NULLS LAST LIMIT 1",
      p, "operator cap");
  out["operator_cap"] = nullptr;
  if (cap.rows() == 1) {
    out["operator_cap"] = {{"operator", cap.str(0, 0)},
                           {"command", cap.str(0, 1)},
                           {"at_us", ride_opt_int(cap, 0, 2)},
                           {"limit_in_force", cap.is_null(0, 3) ? json("") : json(cap.str(0, 3))},
                           {"command_id", cap.str(0, 4)}};
  }
  // The latest event of each zone: a slow zone whose latest is an entry is the bike's now.
  const PgResult z = c.query(
      "SELECT zone_id, zone_name, speed_limit_kmh, coalesce(at_us, created_at_us) FROM ("
      "SELECT DISTINCT ON (zone_id) zone_id, zone_name, kind, transition, speed_limit_kmh, "
      "at_us, created_at_us FROM zone_events WHERE vehicle_id = $1 "
      "ORDER BY zone_id, coalesce(at_us, created_at_us) DESC, sequence DESC) latest "
      "WHERE kind = 'ZONE_KIND_SLOW' AND transition = 'ZONE_TRANSITION_ENTER' ORDER BY zone_id",
      p, "slow zones");
  out["slow_zones"] = json::array();
  for (int i = 0; i < z.rows(); ++i) {
    out["slow_zones"].push_back({{"zone_id", z.str(i, 0)},
                                 {"zone_name", z.str(i, 1)},
                                 {"limit_kmh", ride_opt_int(z, i, 2)},
                                 {"since_us", ride_opt_int(z, i, 3)}});
  }
  return out;
}

}  // namespace fleetgw::web
