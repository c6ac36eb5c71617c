// The rows behind MDS (mds_api.h): registered vehicles, and each vehicle's conditions at the
// start of a window and its signals within it, read in one query per source for a whole page
// of vehicles (never one per vehicle).
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "backend/common/pg.h"
#include "backend/web/mds_state.h"
#include "backend/web/registry_options.h"

namespace fleetgw::web {

struct MdsVehicleRow {
  std::string vehicle_id;
  std::string device_id;
  std::string provider_id;
  std::string provider_name;
  std::string vehicle_type;  // GBFS form factor = MDS vehicle_type
  std::string propulsion;
  std::optional<std::int64_t> max_speed_kph;
  std::optional<std::int64_t> battery_mah;
  std::optional<std::int64_t> removed_at_us;
};

struct MdsTimeline {
  MdsConditions start;
  std::vector<MdsSignal> signals;
  MdsPlace latest;  // the vehicle's latest position and SOC (vehicle_state)
  std::optional<std::int64_t> last_report_us;
  bool riding_now = false;  // the latest state says riding
  std::int64_t state_updated_us = 0;
  std::optional<double> heading_deg;  // the latest state's fix (ingest migration 4)
  std::optional<double> horizontal_error_m;
};

// Registered vehicles ordered by vehicle id; device_id: that one only.
std::vector<MdsVehicleRow> mds_registry_page(PgConnection& c,
                                             const std::optional<std::string>& device_id,
                                             std::int64_t offset, int limit, bool* more);

std::map<std::string, MdsTimeline> mds_timelines(PgConnection& c, const StandardsOptions& o,
                                                 const std::vector<std::string>& vehicle_ids,
                                                 std::int64_t from_us, std::int64_t to_us);

// A text[] literal for a query parameter (every element quoted and escaped).
std::string pg_text_array(const std::vector<std::string>& items);

// The MDS trip id of a ride.
std::string mds_trip_id(const std::string& vehicle_id, const std::string& ride_id);

}  // namespace fleetgw::web
