#include "proto/convert/gbfs_zones.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <set>

namespace fleetgw::convert {
namespace {

using nlohmann::json;

constexpr std::size_t kMaxNameBytes = 128;  // Zone.name's bound in the gateway's rules

// The JSON-path spelling of a member or an index, appended to `path`.
std::string member(const std::string& path, std::string_view key) {
  return path + "." + std::string(key);
}
std::string index(const std::string& path, std::size_t i) {
  return path + "[" + std::to_string(i) + "]";
}

// `text` cut to at most `bytes` without splitting a UTF-8 character.
std::string cut_utf8(const std::string& text, std::size_t bytes) {
  if (text.size() <= bytes) return text;
  std::size_t end = bytes;
  while (end > 0 && (static_cast<unsigned char>(text[end]) & 0xC0) == 0x80) --end;
  return text.substr(0, end);
}

bool valid_zone_id(std::string_view id) {
  return !id.empty() && id.size() <= 64 &&
         id.find_first_not_of(
             "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789._-") ==
             std::string_view::npos;
}

std::string generated_id(std::size_t feature) {
  return "gbfs-" + std::to_string(feature);
}

// Days since 1970-01-01 of a proleptic Gregorian date (H. Hinnant's days_from_civil).
std::int64_t days_from_civil(std::int64_t y, unsigned m, unsigned d) {
  y -= m <= 2;
  const std::int64_t era = (y >= 0 ? y : y - 399) / 400;
  const auto yoe = static_cast<unsigned>(y - era * 400);
  const unsigned doy = (153 * (m + (m > 2 ? -3 : 9)) + 2) / 5 + d - 1;
  const unsigned doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
  return era * 146097 + static_cast<std::int64_t>(doe) - 719468;
}

// One rule: GBFS object -> ZoneRule, or why not.
std::optional<std::string> rule_from_gbfs(const json& r, const std::string& path, v1::ZoneRule& out,
                                          std::vector<std::string>& notes) {
  if (!r.is_object()) return path + ": a rule must be an object";
  for (const auto& [key, value] : r.items()) {
    const std::string at = member(path, key);
    if (key == "vehicle_type_ids") {
      if (!value.is_array()) return at + ": must be an array of vehicle type ids";
      for (std::size_t i = 0; i < value.size(); ++i) {
        if (!value[i].is_string() || value[i].get<std::string>().empty() ||
            value[i].get<std::string>().size() > 64) {
          return index(at, i) + ": a vehicle type id must be a string of 1..64 bytes";
        }
        out.add_vehicle_type_ids(value[i].get<std::string>());
      }
    } else if (key == "ride_start_allowed" || key == "ride_end_allowed" ||
               key == "ride_through_allowed") {
      if (!value.is_boolean()) return at + ": must be true or false";
    } else if (key == "maximum_speed_kph") {
      if (!value.is_number_unsigned() || value.get<std::uint64_t>() > 255) {
        return at + ": " + value.dump() + " is not a whole number of km/h in 0..255";
      }
      out.set_maximum_speed_kph(value.get<std::uint32_t>());
    } else if (key == "station_parking") {
      if (!value.is_boolean()) return at + ": must be true or false";
      if (value.get<bool>()) {
        return at +
               ": true is not enforced by the bike (it knows no stations); refusing rather than "
               "dropping the rule";
      }
      notes.push_back(at + ": false requires nothing; not kept");
    } else {
      return at + ": unknown rule property '" + key +
             "'; the bike cannot enforce a rule it does not know (refused, not dropped)";
    }
  }
  for (const char* key : {"ride_start_allowed", "ride_end_allowed", "ride_through_allowed"}) {
    if (!r.contains(key)) return member(path, key) + ": missing (required by GBFS v3.0)";
  }
  out.set_ride_start_allowed(r["ride_start_allowed"].get<bool>());
  out.set_ride_end_allowed(r["ride_end_allowed"].get<bool>());
  out.set_ride_through_allowed(r["ride_through_allowed"].get<bool>());
  return std::nullopt;
}

std::optional<std::string> rules_from_gbfs(const json& rules, const std::string& path,
                                           google::protobuf::RepeatedPtrField<v1::ZoneRule>& out,
                                           std::vector<std::string>& notes) {
  if (!rules.is_array()) return path + ": must be an array of rules";
  for (std::size_t i = 0; i < rules.size(); ++i) {
    if (auto e = rule_from_gbfs(rules[i], index(path, i), *out.Add(), notes)) return e;
  }
  return std::nullopt;
}

std::optional<std::string> ring_from_gbfs(const json& ring, const std::string& path,
                                          v1::ZoneRing& out) {
  if (!ring.is_array()) return path + ": a ring must be an array of positions";
  for (std::size_t i = 0; i < ring.size(); ++i) {
    const json& p = ring[i];
    const std::string at = index(path, i);
    if (!p.is_array() || p.size() < 2 || !p[0].is_number() || !p[1].is_number()) {
      return at + ": not [longitude, latitude]";
    }
    const double lon = p[0].get<double>(), lat = p[1].get<double>();
    if (!std::isfinite(lon) || lon < -180 || lon > 180) {
      return at + ": longitude " + p[0].dump() + " is not a number in -180..180";
    }
    if (!std::isfinite(lat) || lat < -90 || lat > 90) {
      return at + ": latitude " + p[1].dump() + " is not a number in -90..90";
    }
    out.add_lon_e7(static_cast<std::int32_t>(std::lround(lon * 1e7)));
    out.add_lat_e7(static_cast<std::int32_t>(std::lround(lat * 1e7)));
  }
  return std::nullopt;
}

std::optional<std::string> polygon_from_gbfs(const json& rings, const std::string& path,
                                             v1::Zone& zone) {
  if (!rings.is_array() || rings.empty()) return path + ": a polygon must be an array of rings";
  for (std::size_t r = 0; r < rings.size(); ++r) {
    if (auto e = ring_from_gbfs(rings[r], index(path, r), *zone.add_rings())) return e;
  }
  zone.add_polygon_rings(static_cast<std::uint32_t>(rings.size()));
  return std::nullopt;
}

std::optional<std::string> time_from_gbfs(const json& value, const std::string& at,
                                          std::int64_t& out) {
  // No std::optional copy through a conditional here: gcc 12 at -O3 warns (maybe-uninitialized)
  // about its payload, and the product tree builds with -Werror.
  if (!value.is_string()) return at + ": " + value.dump() + " is not an RFC 3339 date-time";
  const std::optional<std::int64_t> parsed = us_from_rfc3339(value.get<std::string>());
  if (!parsed.has_value()) return at + ": " + value.dump() + " is not an RFC 3339 date-time";
  const std::int64_t us = parsed.value();
  if (us <= 0) return at + ": " + value.dump() + " is before 1970";
  out = us;
  return std::nullopt;
}

std::optional<std::string> feature_from_gbfs(const json& f, std::size_t i, const std::string& path,
                                             v1::Zone& zone, std::vector<std::string>& notes) {
  if (!f.is_object() || f.value("type", json()) != "Feature") return path + ": not a Feature";
  const bool own_id =
      f.contains("id") && f["id"].is_string() && valid_zone_id(f["id"].get<std::string>());
  zone.set_id(own_id ? f["id"].get<std::string>() : generated_id(i));
  if (f.contains("id") && !own_id) {
    notes.push_back(member(path, "id") +
                    ": not a zone id (1..64 of [A-Za-z0-9._-]); the zone is '" + zone.id() + "'");
  }
  zone.set_kind(v1::ZONE_KIND_RULES);
  for (const auto& [key, value] : f.items()) {
    if (key != "type" && key != "id" && key != "geometry" && key != "properties") {
      notes.push_back(member(path, key) + ": unknown Feature member, ignored");
    }
  }
  const std::string props_path = member(path, "properties");
  if (!f.contains("properties") || !f["properties"].is_object()) {
    return props_path + ": missing (required by GBFS v3.0)";
  }
  for (const auto& [key, value] : f["properties"].items()) {
    const std::string at = member(props_path, key);
    if (key == "name") {
      if (!value.is_array()) return at + ": must be an array of {text, language} (GBFS v3.0)";
      for (std::size_t n = 0; n < value.size(); ++n) {
        const json& t = value[n];
        if (!t.is_object() || !t.contains("text") || !t["text"].is_string() ||
            !t.contains("language") || !t["language"].is_string()) {
          return index(at, n) + ": must be {\"text\": string, \"language\": string}";
        }
        auto* name = zone.add_names();
        name->set_text(t["text"].get<std::string>());
        name->set_language(t["language"].get<std::string>());
      }
      if (!zone.names().empty()) zone.set_name(cut_utf8(zone.names(0).text(), kMaxNameBytes));
    } else if (key == "start") {
      std::int64_t us = 0;
      if (auto e = time_from_gbfs(value, at, us)) return e;
      zone.set_start_us(us);
    } else if (key == "end") {
      std::int64_t us = 0;
      if (auto e = time_from_gbfs(value, at, us)) return e;
      zone.set_end_us(us);
    } else if (key == "rules") {
      if (auto e = rules_from_gbfs(value, at, *zone.mutable_rules(), notes)) return e;
    } else {
      notes.push_back(at + ": unknown property, ignored (no effect on the bike)");
    }
  }
  if (zone.start_us() != 0 && zone.end_us() != 0 && zone.end_us() <= zone.start_us()) {
    return member(props_path, "end") + ": not after start";
  }
  const std::string geo_path = member(path, "geometry");
  if (!f.contains("geometry") || !f["geometry"].is_object()) {
    return geo_path + ": missing (a MultiPolygon is required)";
  }
  const json& g = f["geometry"];
  const json coords = g.value("coordinates", json());
  const std::string coords_path = member(geo_path, "coordinates");
  if (g.value("type", json()) == "MultiPolygon") {
    if (!coords.is_array() || coords.empty()) {
      return coords_path + ": must be an array of polygons";
    }
    for (std::size_t p = 0; p < coords.size(); ++p) {
      if (auto e = polygon_from_gbfs(coords[p], index(coords_path, p), zone)) return e;
    }
    return std::nullopt;
  }
  if (g.value("type", json()) == "Polygon") {
    notes.push_back(member(geo_path, "type") +
                    ": Polygon where GBFS v3.0 requires a MultiPolygon; read as one, exported "
                    "as a MultiPolygon");
    return polygon_from_gbfs(coords, coords_path, zone);
  }
  return member(geo_path, "type") + ": must be \"MultiPolygon\"";
}

json rule_to_gbfs(const v1::ZoneRule& r) {
  json o = json::object();
  if (!r.vehicle_type_ids().empty()) {
    o["vehicle_type_ids"] =
        std::vector<std::string>(r.vehicle_type_ids().begin(), r.vehicle_type_ids().end());
  }
  o["ride_start_allowed"] = r.ride_start_allowed();
  o["ride_end_allowed"] = r.ride_end_allowed();
  o["ride_through_allowed"] = r.ride_through_allowed();
  if (r.has_maximum_speed_kph()) o["maximum_speed_kph"] = r.maximum_speed_kph();
  return o;
}

json position_to_gbfs(std::int32_t lon_e7, std::int32_t lat_e7) {
  // Divided, not multiplied by 1e-7: the nearest double to the decimal the file had.
  return json::array({static_cast<double>(lon_e7) / 1e7, static_cast<double>(lat_e7) / 1e7});
}

// Twice the ring's signed area in (lon, lat) units of 1e-7 degrees: positive when the vertices
// run counter-clockwise (the closing edge is implied; a repeated first vertex adds nothing).
double ring_signed_area2(const v1::ZoneRing& r) {
  const int n = std::min(r.lat_e7_size(), r.lon_e7_size());
  double sum = 0;
  for (int i = 0; i < n; ++i) {
    const int j = (i + 1) % n;
    sum += static_cast<double>(r.lon_e7(i)) * static_cast<double>(r.lat_e7(j)) -
           static_cast<double>(r.lon_e7(j)) * static_cast<double>(r.lat_e7(i));
  }
  return sum;
}

// Even-odd point-in-ring test (the bike's own reading of overlapping rings).
bool ring_contains(const v1::ZoneRing& r, std::int32_t lon, std::int32_t lat) {
  const int n = std::min(r.lat_e7_size(), r.lon_e7_size());
  bool inside = false;
  for (int i = 0, j = n - 1; i < n; j = i++) {
    const double yi = r.lat_e7(i), yj = r.lat_e7(j), xi = r.lon_e7(i), xj = r.lon_e7(j);
    if ((yi > lat) != (yj > lat) && lon < (xj - xi) * (lat - yi) / (yj - yi) + xi) inside = !inside;
  }
  return inside;
}

// GBFS v3.0 (after RFC 7946 s. 3.1.6) asks for the right-hand rule: exterior rings
// counter-clockwise, holes clockwise. The bike reads rings by even-odd, which ignores their
// direction, so a ring is written in the direction its role asks for (`exterior`), starting at
// the same vertex; a ring already in that direction keeps its order (the document written back
// unchanged). A degenerate ring (no area) is left as it is.
json ring_to_gbfs(const v1::ZoneRing& r, bool exterior) {
  json ring = json::array();
  const int n = std::min(r.lat_e7_size(), r.lon_e7_size());
  // A ring stored closed (its last vertex repeating the first) is walked without the repeat.
  const int m =
      n > 1 && r.lat_e7(0) == r.lat_e7(n - 1) && r.lon_e7(0) == r.lon_e7(n - 1) ? n - 1 : n;
  const double area2 = ring_signed_area2(r);
  const bool reverse = area2 != 0 && (area2 > 0) != exterior;
  for (int k = 0; k < m; ++k) {
    const int i = reverse ? (m - k) % m : k;
    ring.push_back(position_to_gbfs(r.lon_e7(i), r.lat_e7(i)));
  }
  // GBFS (RFC 7946) rings are closed: the last position repeats the first.
  if (m > 0) ring.push_back(ring.front());
  return ring;
}

json multipolygon_to_gbfs(const v1::Zone& z) {
  json polygons = json::array();
  std::vector<std::uint32_t> counts(z.polygon_rings().begin(), z.polygon_rings().end());
  std::uint32_t total = 0;
  for (auto c : counts) total += c;
  // No grouping (or one that does not add up): every ring is an outer ring of its own polygon
  // except what the even-odd rule makes holes, which GeoJSON readers also accept; one polygon
  // keeps the bike's reading exactly.
  const bool grouped = !counts.empty() && total == static_cast<std::uint32_t>(z.rings_size());
  if (!grouped) counts = {static_cast<std::uint32_t>(z.rings_size())};
  int next = 0;
  for (auto c : counts) {
    json polygon = json::array();
    const int first = next;
    for (std::uint32_t k = 0; k < c; ++k) {
      const v1::ZoneRing& ring = z.rings(next++);
      // A grouped polygon's first ring is its exterior, the rest its holes. Ungrouped rings: a
      // ring inside an odd number of the others is a hole to the bike (even-odd).
      bool exterior = k == 0;
      if (!grouped && k > 0 && ring.lat_e7_size() > 0 && ring.lon_e7_size() > 0) {
        int depth = 0;
        for (int o = first; o < first + static_cast<int>(c); ++o) {
          if (o != next - 1 && ring_contains(z.rings(o), ring.lon_e7(0), ring.lat_e7(0))) ++depth;
        }
        exterior = depth % 2 == 0;
      }
      polygon.push_back(ring_to_gbfs(ring, exterior));
    }
    polygons.push_back(std::move(polygon));
  }
  return json{{"type", "MultiPolygon"}, {"coordinates", std::move(polygons)}};
}

// The rule the bike enforces for a zone of an older kind.
v1::ZoneRule rule_of_kind(const v1::Zone& z) {
  v1::ZoneRule r;
  r.set_ride_start_allowed(z.kind() != v1::ZONE_KIND_NO_START);
  r.set_ride_end_allowed(z.kind() != v1::ZONE_KIND_NO_PARKING);
  r.set_ride_through_allowed(z.kind() != v1::ZONE_KIND_NO_RIDE);
  if (z.kind() == v1::ZONE_KIND_SLOW) r.set_maximum_speed_kph(z.speed_limit_kmh());
  return r;
}

// UNION bundles: most restrictive first, so GBFS's first match agrees where one kind overlaps.
int union_rank(const v1::Zone& z) {
  switch (z.kind()) {
    case v1::ZONE_KIND_NO_RIDE:
      return 0;
    case v1::ZONE_KIND_SLOW:
      return 1 + static_cast<int>(z.speed_limit_kmh());
    case v1::ZONE_KIND_NO_PARKING:
      return 300;
    case v1::ZONE_KIND_NO_START:
      return 301;
    case v1::ZONE_KIND_RULES:
      return 302;
    default:
      return 400;  // operating areas: allow everything, last
  }
}

}  // namespace

std::string rfc3339_from_us(std::int64_t us) {
  const std::int64_t secs = us >= 0 ? us / 1'000'000 : (us - 999'999) / 1'000'000;
  const std::int64_t frac = us - secs * 1'000'000;
  std::int64_t days = secs >= 0 ? secs / 86400 : (secs - 86399) / 86400;
  const std::int64_t rem = secs - days * 86400;
  // civil_from_days (H. Hinnant).
  days += 719468;
  const std::int64_t era = (days >= 0 ? days : days - 146096) / 146097;
  const auto doe = static_cast<unsigned>(days - era * 146097);
  const unsigned yoe = (doe - doe / 1460 + doe / 36524 - doe / 146096) / 365;
  const unsigned doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
  const unsigned mp = (5 * doy + 2) / 153;
  const unsigned d = doy - (153 * mp + 2) / 5 + 1;
  const unsigned m = mp < 10 ? mp + 3 : mp - 9;
  const std::int64_t y = static_cast<std::int64_t>(yoe) + era * 400 + (m <= 2);
  char buf[48];
  std::snprintf(buf, sizeof buf, "%04lld-%02u-%02uT%02d:%02d:%02d", static_cast<long long>(y), m, d,
                static_cast<int>(rem / 3600), static_cast<int>(rem / 60 % 60),
                static_cast<int>(rem % 60));
  std::string out = buf;
  if (frac != 0) {
    std::snprintf(buf, sizeof buf, ".%06lld", static_cast<long long>(frac));
    out += buf;
  }
  return out + "Z";
}

std::optional<std::int64_t> us_from_rfc3339(std::string_view t) {
  // YYYY-MM-DDTHH:MM:SS[.fraction](Z|+HH:MM|-HH:MM)
  auto digits = [&](std::size_t at, std::size_t n) -> std::optional<int> {
    if (at + n > t.size()) return std::nullopt;
    int v = 0;
    for (std::size_t i = at; i < at + n; ++i) {
      if (t[i] < '0' || t[i] > '9') return std::nullopt;
      v = v * 10 + (t[i] - '0');
    }
    return v;
  };
  const auto y = digits(0, 4), mo = digits(5, 2), d = digits(8, 2), h = digits(11, 2),
             mi = digits(14, 2), s = digits(17, 2);
  if (!y || !mo || !d || !h || !mi || !s || t[4] != '-' || t[7] != '-' ||
      (t[10] != 'T' && t[10] != 't' && t[10] != ' ') || t[13] != ':' || t[16] != ':') {
    return std::nullopt;
  }
  if (*mo < 1 || *mo > 12 || *d < 1 || *d > 31 || *h > 23 || *mi > 59 || *s > 60) {
    return std::nullopt;
  }
  std::size_t at = 19;
  std::int64_t frac_us = 0;
  if (at < t.size() && t[at] == '.') {
    ++at;
    std::int64_t scale = 100'000;
    const std::size_t start = at;
    while (at < t.size() && t[at] >= '0' && t[at] <= '9') {
      frac_us += (t[at] - '0') * scale;
      scale /= 10;
      ++at;
    }
    if (at == start) return std::nullopt;
  }
  std::int64_t offset_s = 0;
  if (at < t.size() && (t[at] == 'Z' || t[at] == 'z')) {
    ++at;
  } else if (at < t.size() && (t[at] == '+' || t[at] == '-')) {
    const auto oh = digits(at + 1, 2), om = digits(at + 4, 2);
    if (!oh || !om || at + 3 >= t.size() || t[at + 3] != ':' || *oh > 23 || *om > 59) {
      return std::nullopt;
    }
    offset_s = (t[at] == '+' ? 1 : -1) * (*oh * 3600 + *om * 60);
    at += 6;
  } else {
    return std::nullopt;
  }
  if (at != t.size()) return std::nullopt;
  const std::int64_t secs =
      days_from_civil(*y, static_cast<unsigned>(*mo), static_cast<unsigned>(*d)) * 86400 +
      *h * 3600 + *mi * 60 + std::min(*s, 59) - offset_s;
  return secs * 1'000'000 + frac_us;
}

bool is_gbfs_geofencing_zones(std::string_view json_text) {
  const json doc = json::parse(json_text, nullptr, /*allow_exceptions=*/false);
  return doc.is_object() && doc.contains("data") && doc["data"].is_object() &&
         doc["data"].contains("geofencing_zones");
}

std::variant<GbfsZonesImport, std::string> zone_bundle_from_gbfs(std::string_view json_text) {
  const json doc = json::parse(json_text, nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded()) return std::string("not JSON");
  if (!doc.is_object()) return std::string("$: not a GBFS document (a JSON object)");
  GbfsZonesImport out;
  auto& notes = out.notes;
  for (const auto& [key, value] : doc.items()) {
    if (key == "version") {
      if (value != "3.0") {
        return "version: " + value.dump() +
               " is not \"3.0\" (GBFS 2.x rules differ: ride_allowed; convert the feed first)";
      }
    } else if (key != "last_updated" && key != "ttl" && key != "data") {
      notes.push_back(key + ": unknown member, ignored");
    }
  }
  if (!doc.contains("version")) notes.push_back("version: missing; read as GBFS 3.0");
  if (!doc.contains("data") || !doc["data"].is_object()) {
    return std::string("data: missing (a GBFS document has data.geofencing_zones)");
  }
  const json& data = doc["data"];
  for (const auto& [key, value] : data.items()) {
    if (key != "geofencing_zones" && key != "global_rules") {
      notes.push_back("data." + key + ": unknown member, ignored");
    }
  }
  const json& fc = data.value("geofencing_zones", json());
  if (!fc.is_object() || fc.value("type", json()) != "FeatureCollection" ||
      !fc.contains("features") || !fc["features"].is_array()) {
    return std::string(
        "data.geofencing_zones: not a GeoJSON FeatureCollection with a \"features\" array");
  }
  v1::ZoneBundle& bundle = out.bundle;
  bundle.set_precedence(v1::ZONE_PRECEDENCE_FIRST_MATCH);
  const json& features = fc["features"];
  std::set<std::string> ids;
  for (std::size_t i = 0; i < features.size(); ++i) {
    const std::string path = index("data.geofencing_zones.features", i);
    v1::Zone& zone = *bundle.add_zones();
    if (auto e = feature_from_gbfs(features[i], i, path, zone, notes)) return *e;
    if (!ids.insert(zone.id()).second) return member(path, "id") + ": '" + zone.id() + "' repeated";
  }
  if (data.contains("global_rules")) {
    if (auto e = rules_from_gbfs(data["global_rules"], "data.global_rules",
                                 *bundle.mutable_default_rules(), notes)) {
      return *e;
    }
  } else {
    notes.push_back("data.global_rules: missing (required by GBFS v3.0); read as none");
  }
  return out;
}

nlohmann::json gbfs_from_zone_bundle(const v1::ZoneBundle& bundle,
                                     const GbfsExportOptions& options) {
  std::vector<int> order(static_cast<std::size_t>(bundle.zones_size()));
  for (int i = 0; i < bundle.zones_size(); ++i) order[static_cast<std::size_t>(i)] = i;
  const bool first_match = bundle.precedence() == v1::ZONE_PRECEDENCE_FIRST_MATCH;
  if (!first_match) {
    std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
      return union_rank(bundle.zones(a)) < union_rank(bundle.zones(b));
    });
  }
  json features = json::array();
  bool any_area = false;
  for (std::size_t pos = 0; pos < order.size(); ++pos) {
    const v1::Zone& z = bundle.zones(order[pos]);
    any_area = any_area || z.kind() == v1::ZONE_KIND_OPERATING_AREA;
    json props = json::object();
    json names = json::array();
    for (const auto& n : z.names())
      names.push_back({{"text", n.text()}, {"language", n.language()}});
    if (names.empty() && !z.name().empty()) {
      names.push_back({{"text", z.name()}, {"language", "en"}});
    }
    if (!names.empty()) props["name"] = std::move(names);
    if (z.start_us() != 0) props["start"] = rfc3339_from_us(z.start_us());
    if (z.end_us() != 0) props["end"] = rfc3339_from_us(z.end_us());
    json rules = json::array();
    if (z.kind() == v1::ZONE_KIND_RULES) {
      for (const auto& r : z.rules()) rules.push_back(rule_to_gbfs(r));
    } else {
      rules.push_back(rule_to_gbfs(rule_of_kind(z)));
    }
    props["rules"] = std::move(rules);
    json f{{"type", "Feature"}, {"geometry", multipolygon_to_gbfs(z)}, {"properties", props}};
    if (z.id() != generated_id(pos)) f["id"] = z.id();
    features.push_back(std::move(f));
  }
  json global = json::array();
  for (const auto& r : bundle.default_rules()) global.push_back(rule_to_gbfs(r));
  if (!first_match && any_area) {
    v1::ZoneRule outside;
    outside.set_ride_through_allowed(true);  // outside every operating area: an alarm, no fade
    global.push_back(rule_to_gbfs(outside));
  }
  const std::int64_t updated =
      options.last_updated_us != 0 ? options.last_updated_us : bundle.issued_at_us();
  return json{{"last_updated", rfc3339_from_us(updated)},
              {"ttl", options.ttl_s},
              {"version", "3.0"},
              {"data",
               {{"geofencing_zones", {{"type", "FeatureCollection"}, {"features", features}}},
                {"global_rules", global}}}};
}

}  // namespace fleetgw::convert
