#include "gateway/tools/store/db_geojson.h"

#include <nlohmann/json.hpp>

#include "gateway/tools/common/table_format.h"
#include "gateway/tools/common/time_arg.h"
#include "storage/track_text.h"

namespace fleetgw::tools {
namespace {

using nlohmann::json;
using nlohmann::ordered_json;

ordered_json iso_time(const json& row, const char* column) {
  const auto it = row.find(column);
  if (it == row.end() || !it->is_number_integer()) return nullptr;
  return iso_utc(it->get<std::int64_t>());
}

ordered_json position(const storage::TrackPoint& p) {
  return ordered_json::array({p.lon_deg, p.lat_deg});  // RFC 7946 §3.1.1: longitude first
}

// The geometry of one ride: LineString, Point or null (db_geojson.h).
ordered_json geometry(const json& row, std::ostream& err) {
  const auto it = row.find("track");
  if (it == row.end() || it->is_null()) return nullptr;
  std::string problem;
  storage::ParsedTrack parsed;
  if (!it->is_string()) {
    problem = "not text";
  } else if (parsed = storage::parse_track_text(it->get_ref<const std::string&>()); !parsed.ok()) {
    problem = parsed.error;
  }
  if (!problem.empty()) {
    const auto id = row.find("ride_id");
    err << "fleetgw db export: ride '"
        << table_cell(id != row.end() && id->is_string() ? id->get<std::string>() : "?")
        << "': track: " << problem << "; exported with geometry null\n";
    return nullptr;
  }
  if (parsed.points.empty()) return nullptr;
  if (parsed.points.size() == 1) {
    return ordered_json{{"type", "Point"}, {"coordinates", position(parsed.points.front())}};
  }
  ordered_json coordinates = ordered_json::array();
  for (const auto& p : parsed.points) coordinates.push_back(position(p));
  return ordered_json{{"type", "LineString"}, {"coordinates", std::move(coordinates)}};
}

ordered_json feature(const json& row, std::ostream& err) {
  ordered_json properties;
  const auto id = row.find("ride_id");
  properties["ride_id"] = id != row.end() ? ordered_json(*id) : ordered_json();
  properties["start"] = iso_time(row, "start_us");
  properties["end"] = iso_time(row, "end_us");
  for (const auto& [column, value] : row.items()) {
    if (column == "id" || column == "track" || column == "ride_id") continue;
    properties[column] = value;
  }
  ordered_json f;
  f["type"] = "Feature";
  f["id"] = properties["ride_id"];
  f["geometry"] = geometry(row, err);
  f["properties"] = std::move(properties);
  return f;
}

}  // namespace

std::uint64_t export_rides_geojson(storage::Store& store, std::int64_t since_us, std::ostream& out,
                                   std::ostream& err) {
  out << "{\"type\":\"FeatureCollection\",\"features\":[";
  std::uint64_t n = 0;
  const auto rows = store.export_table("rides", since_us, [&](const json& row) {
    out << (n++ == 0 ? "\n" : ",\n")
        << feature(row, err).dump(-1, ' ', false, json::error_handler_t::replace);
  });
  out << "\n]}\n";
  return rows;
}

}  // namespace fleetgw::tools
