// The telemetry of a time window, typed, for `fleetgw ride plot`
// (gateway/tools/store/ride_command.h).
// Read-only: works on a store opened with read_only.
#include "storage/store_impl.h"

namespace fleetgw::storage {

std::vector<TelemetryRow> Store::telemetry_between(std::int64_t from_us, std::int64_t to_us) {
  // The table has no index on ts_us (eviction and the uplink go by rowid): one scan, filtered
  // by SQLite, only the window converted.
  Statement st = impl_->db.prepare(
      "SELECT id, ts_us, speed_kmh, assist_level, soc_pct, voltage_v, current_a, motor_temp_c, "
      "controller_temp_c, battery_temp_c, wheel_lock_state, battery_lock_state FROM telemetry "
      "WHERE ts_us BETWEEN ?1 AND ?2 ORDER BY ts_us, id");
  st.bind(1, from_us);
  st.bind(2, to_us);
  std::vector<TelemetryRow> out;
  const auto opt_int = [&st](int col) -> std::optional<int> {
    if (const auto v = st.column_opt_int64(col)) return static_cast<int>(*v);
    return std::nullopt;
  };
  while (st.step()) {
    TelemetryRow s;
    s.id = st.column_int64(0);
    s.ts_us = st.column_int64(1);
    s.speed_kmh = st.column_opt_double(2);
    s.assist_level = opt_int(3);
    s.soc_pct = st.column_opt_double(4);
    s.voltage_v = st.column_opt_double(5);
    s.current_a = st.column_opt_double(6);
    s.motor_temp_c = st.column_opt_double(7);
    s.controller_temp_c = st.column_opt_double(8);
    s.battery_temp_c = st.column_opt_double(9);
    s.wheel_lock_state = opt_int(10);
    s.battery_lock_state = opt_int(11);
    out.push_back(s);
  }
  return out;
}

}  // namespace fleetgw::storage
