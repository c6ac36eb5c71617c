// The vehicle registry's store (registry_store.h).
#include "backend/web/registry_store.h"

#include <sodium.h>

#include <array>
#include <charconv>
#include <map>
#include <stdexcept>

#include "backend/web/secrets.h"
#include "fleetgw/v1/zones.pb.h"

namespace fleetgw::web {
namespace {

using nlohmann::json;

constexpr std::array<std::string_view, 7> kFormFactors = {
    "bicycle", "cargo_bicycle", "car", "moped", "scooter_standing", "scooter_seated", "other"};
constexpr std::array<std::string_view, 8> kPropulsions = {
    "human",  "electric_assist", "electric",          "combustion", "combustion_diesel",
    "hybrid", "plug_in_hybrid",  "hydrogen_fuel_cell"};

template <std::size_t N>
bool one_of(const std::array<std::string_view, N>& set, std::string_view v) {
  for (std::string_view s : set) {
    if (s == v) return true;
  }
  return false;
}

bool is_type_id(std::string_view id) {
  if (id.empty() || id.size() > 64) return false;
  for (const char ch : id) {
    const bool ok = (ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') ||
                    (ch >= '0' && ch <= '9') || ch == '.' || ch == '_' || ch == '-';
    if (!ok) return false;
  }
  return true;
}

std::string uuid_text(std::array<unsigned char, 16> b, int version) {
  b[6] = static_cast<unsigned char>((b[6] & 0x0f) | (version << 4));
  b[8] = static_cast<unsigned char>((b[8] & 0x3f) | 0x80);  // RFC 9562 variant
  static constexpr char kHex[] = "0123456789abcdef";
  std::string out;
  for (std::size_t i = 0; i < b.size(); ++i) {
    if (i == 4 || i == 6 || i == 8 || i == 10) out += '-';
    out += kHex[b[i] >> 4];
    out += kHex[b[i] & 15];
  }
  return out;
}

PgParam opt_param(const std::optional<int>& v) {
  return v ? PgParam(std::to_string(*v)) : std::nullopt;
}

json opt_json_int(const PgResult& r, int row, int col) {
  const auto v = r.int64_or_null(row, col);
  return v ? json(*v) : json(nullptr);
}

// A whole-number field of a CSV line or JSON body, named in the error.
int parse_int_field(std::string_view text, std::string_view field) {
  int v = 0;
  const auto [p, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || p != text.data() + text.size()) {
    throw std::invalid_argument(std::string(field) + ": not a whole number: '" + std::string(text) +
                                "'");
  }
  return v;
}

double parse_double_field(std::string_view text, std::string_view field) {
  try {
    std::size_t used = 0;
    const double v = std::stod(std::string(text), &used);
    if (used == text.size()) return v;
  } catch (const std::exception&) {
  }
  throw std::invalid_argument(std::string(field) + ": not a number: '" + std::string(text) + "'");
}

// CSV lines as maps from the header's column names; no quoting.
std::vector<std::map<std::string, std::string>> csv_rows(std::string_view text,
                                                         std::string_view source,
                                                         const std::vector<std::string_view>& known,
                                                         std::vector<std::size_t>* line_numbers) {
  std::vector<std::vector<std::string>> lines;
  std::vector<std::size_t> numbers;
  std::size_t line_no = 0;
  while (!text.empty()) {
    const std::size_t nl = text.find('\n');
    std::string_view line = text.substr(0, nl);
    text = nl == std::string_view::npos ? std::string_view() : text.substr(nl + 1);
    ++line_no;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    if (line.empty() || line.front() == '#') continue;
    if (line.find('"') != std::string_view::npos) {
      throw std::invalid_argument(std::string(source) + " line " + std::to_string(line_no) +
                                  ": quoted fields are not supported (use the API)");
    }
    std::vector<std::string> fields;
    std::size_t start = 0;
    while (true) {
      const std::size_t comma = line.find(',', start);
      std::string f(
          line.substr(start, comma == std::string_view::npos ? line.npos : comma - start));
      while (!f.empty() && f.front() == ' ') f.erase(f.begin());
      while (!f.empty() && f.back() == ' ') f.pop_back();
      fields.push_back(std::move(f));
      if (comma == std::string_view::npos) break;
      start = comma + 1;
    }
    lines.push_back(std::move(fields));
    numbers.push_back(line_no);
  }
  if (lines.empty()) throw std::invalid_argument(std::string(source) + ": no header line");
  const std::vector<std::string> header = lines.front();
  for (const std::string& h : header) {
    bool ok = false;
    for (std::string_view k : known) ok = ok || k == h;
    if (!ok) {
      throw std::invalid_argument(std::string(source) + " line " + std::to_string(numbers[0]) +
                                  ": unknown column '" + h + "'");
    }
  }
  std::vector<std::map<std::string, std::string>> out;
  for (std::size_t i = 1; i < lines.size(); ++i) {
    if (lines[i].size() != header.size()) {
      throw std::invalid_argument(std::string(source) + " line " + std::to_string(numbers[i]) +
                                  ": " + std::to_string(lines[i].size()) +
                                  " fields, the header has " + std::to_string(header.size()));
    }
    std::map<std::string, std::string> row;
    for (std::size_t c = 0; c < header.size(); ++c) row[header[c]] = lines[i][c];
    out.push_back(std::move(row));
    line_numbers->push_back(numbers[i]);
  }
  return out;
}

std::string field_or_empty(const std::map<std::string, std::string>& row, const std::string& k) {
  const auto it = row.find(k);
  return it == row.end() ? "" : it->second;
}

std::optional<int> json_opt_int(const json& j, const char* key) {
  if (!j.contains(key) || j[key].is_null()) return std::nullopt;
  if (!j[key].is_number_integer())
    throw std::invalid_argument(std::string(key) + ": not an integer");
  return j[key].get<int>();
}

std::string json_str(const json& j, const char* key, bool required) {
  if (!j.contains(key) || j[key].is_null()) {
    if (required) throw std::invalid_argument(std::string(key) + ": required");
    return "";
  }
  if (!j[key].is_string()) throw std::invalid_argument(std::string(key) + ": not a string");
  return j[key].get<std::string>();
}

}  // namespace

void VehicleType::validate() const {
  if (!is_type_id(id)) {
    throw std::invalid_argument("vehicle_type_id '" + id + "': 1-64 of [A-Za-z0-9._-]");
  }
  if (name.size() > 128) throw std::invalid_argument("name: at most 128 bytes");
  if (!one_of(kFormFactors, form_factor)) {
    throw std::invalid_argument("form_factor '" + form_factor +
                                "': one of bicycle, cargo_bicycle, car, moped, scooter_standing, "
                                "scooter_seated, other");
  }
  if (!one_of(kPropulsions, propulsion_type)) {
    throw std::invalid_argument("propulsion_type '" + propulsion_type + "': not a GBFS propulsion");
  }
  if (max_speed_kph && (*max_speed_kph < 1 || *max_speed_kph > 300)) {
    throw std::invalid_argument("max_speed_kph: 1 to 300");
  }
  if (battery_capacity_wh && *battery_capacity_wh <= 0) {
    throw std::invalid_argument("battery_capacity_wh: must be > 0");
  }
  if (battery_capacity_mah && *battery_capacity_mah <= 0) {
    throw std::invalid_argument("battery_capacity_mah: must be > 0");
  }
  if (wh_per_km && !(*wh_per_km > 0 && *wh_per_km < 1e6)) {
    throw std::invalid_argument("wh_per_km: must be > 0");
  }
  // GBFS requires max_range_meters of every motorised type: the range model must give it.
  if (propulsion_type != "human" && !max_range_m()) {
    throw std::invalid_argument("vehicle type " + id +
                                ": a motorised type needs battery_capacity_wh and wh_per_km "
                                "(its range model; GBFS max_range_meters)");
  }
}

std::optional<double> VehicleType::max_range_m() const {
  if (!battery_capacity_wh || !wh_per_km) return std::nullopt;
  return *battery_capacity_wh / *wh_per_km * 1000.0;
}

void RegistryVehicle::validate() const {
  if (vehicle_id.empty() || vehicle_id.size() > 128) {
    throw std::invalid_argument("vehicle_id: 1 to 128 bytes");
  }
  if (!is_type_id(vehicle_type_id)) {
    throw std::invalid_argument("vehicle_type_id '" + vehicle_type_id +
                                "': 1-64 of [A-Za-z0-9._-]");
  }
  if (!device_id.empty() && !is_uuid(device_id)) {
    throw std::invalid_argument("device_id '" + device_id + "': not a UUID");
  }
  if (!is_uuid(provider_id)) {
    throw std::invalid_argument("provider_id '" + provider_id +
                                "': not a UUID (give one, or start serve with --provider-id)");
  }
  if (provider_name.size() > 128) throw std::invalid_argument("provider_name: at most 128 bytes");
}

void upsert_vehicle_type(PgConnection& c, const VehicleType& t, std::int64_t now_us) {
  t.validate();
  const PgParam p[] = {t.id,
                       t.name,
                       t.form_factor,
                       t.propulsion_type,
                       opt_param(t.max_speed_kph),
                       opt_param(t.battery_capacity_wh),
                       opt_param(t.battery_capacity_mah),
                       t.wh_per_km ? PgParam(std::to_string(*t.wh_per_km)) : std::nullopt,
                       std::to_string(now_us)};
  c.query(
      "INSERT INTO registry_vehicle_types (vehicle_type_id, name, form_factor, propulsion_type, "
      "max_speed_kph, battery_capacity_wh, battery_capacity_mah, wh_per_km, updated_at_us) "
      "VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9) ON CONFLICT (vehicle_type_id) DO UPDATE SET "
      "name = EXCLUDED.name, form_factor = EXCLUDED.form_factor, propulsion_type = "
      "EXCLUDED.propulsion_type, max_speed_kph = EXCLUDED.max_speed_kph, battery_capacity_wh = "
      "EXCLUDED.battery_capacity_wh, battery_capacity_mah = EXCLUDED.battery_capacity_mah, "
      "wh_per_km = EXCLUDED.wh_per_km, updated_at_us = EXCLUDED.updated_at_us",
      p, "vehicle type upsert");
}

std::string upsert_vehicle(PgConnection& c, const RegistryVehicle& v, std::int64_t now_us) {
  v.validate();
  PgTransaction tx(c);
  const PgParam type[] = {v.vehicle_type_id};
  if (c.query("SELECT 1 FROM registry_vehicle_types WHERE vehicle_type_id = $1", type,
              "vehicle type exists")
          .rows() == 0) {
    throw std::invalid_argument("vehicle_type_id '" + v.vehicle_type_id +
                                "': no such vehicle type (register it first)");
  }
  const PgParam id[] = {v.vehicle_id};
  const PgResult have =
      c.query("SELECT device_id::text FROM registry_vehicles WHERE vehicle_id = $1 FOR UPDATE", id,
              "registry vehicle");
  std::string device = v.device_id;
  if (have.rows() == 1) {
    if (!device.empty() && device != have.str(0, 0)) {
      throw std::invalid_argument("device_id of " + v.vehicle_id + " is " + have.str(0, 0) +
                                  ": a device UUID never changes");
    }
    device = have.str(0, 0);
  } else if (device.empty()) {
    device = random_uuid();
  }
  const PgParam p[] = {v.vehicle_id,
                       device,
                       v.vehicle_type_id,
                       v.provider_id,
                       v.provider_name,
                       std::to_string(now_us),
                       v.removed ? PgParam(std::to_string(now_us)) : std::nullopt};
  c.query(
      "INSERT INTO registry_vehicles (vehicle_id, device_id, vehicle_type_id, provider_id, "
      "provider_name, created_at_us, updated_at_us, removed_at_us) VALUES ($1, $2::uuid, $3, "
      "$4::uuid, $5, $6, $6, $7) ON CONFLICT (vehicle_id) DO UPDATE SET vehicle_type_id = "
      "EXCLUDED.vehicle_type_id, provider_id = EXCLUDED.provider_id, provider_name = "
      "EXCLUDED.provider_name, updated_at_us = EXCLUDED.updated_at_us, removed_at_us = "
      "CASE WHEN EXCLUDED.removed_at_us IS NULL THEN NULL "
      "ELSE coalesce(registry_vehicles.removed_at_us, EXCLUDED.removed_at_us) END",
      p, "registry vehicle upsert");
  tx.commit();
  return device;
}

json list_vehicle_types(PgConnection& c) {
  const PgResult r = c.exec(
      "SELECT vehicle_type_id, name, form_factor, propulsion_type, max_speed_kph, "
      "battery_capacity_wh, battery_capacity_mah, wh_per_km FROM registry_vehicle_types "
      "ORDER BY vehicle_type_id",
      "vehicle types");
  json out = json::array();
  for (int i = 0; i < r.rows(); ++i) {
    out.push_back({{"vehicle_type_id", r.str(i, 0)},
                   {"name", r.str(i, 1)},
                   {"form_factor", r.str(i, 2)},
                   {"propulsion_type", r.str(i, 3)},
                   {"max_speed_kph", opt_json_int(r, i, 4)},
                   {"battery_capacity_wh", opt_json_int(r, i, 5)},
                   {"battery_capacity_mah", opt_json_int(r, i, 6)},
                   {"wh_per_km", r.is_null(i, 7) ? json(nullptr) : json(std::stod(r.str(i, 7)))}});
  }
  return out;
}

json list_registry_vehicles(PgConnection& c) {
  const PgResult r = c.exec(
      "SELECT vehicle_id, device_id::text, vehicle_type_id, provider_id::text, provider_name, "
      "created_at_us, updated_at_us, removed_at_us FROM registry_vehicles ORDER BY vehicle_id",
      "registry vehicles");
  json out = json::array();
  for (int i = 0; i < r.rows(); ++i) {
    out.push_back({{"vehicle_id", r.str(i, 0)},
                   {"device_id", r.str(i, 1)},
                   {"vehicle_type_id", r.str(i, 2)},
                   {"provider_id", r.str(i, 3)},
                   {"provider_name", r.str(i, 4)},
                   {"created_at_us", opt_json_int(r, i, 5)},
                   {"updated_at_us", opt_json_int(r, i, 6)},
                   {"removed_at_us", opt_json_int(r, i, 7)}});
  }
  return out;
}

VehicleType vehicle_type_from_json(const json& j) {
  if (!j.is_object()) throw std::invalid_argument("expected a JSON object");
  VehicleType t;
  t.id = json_str(j, "vehicle_type_id", true);
  t.name = json_str(j, "name", false);
  t.form_factor = json_str(j, "form_factor", true);
  t.propulsion_type = json_str(j, "propulsion_type", true);
  t.max_speed_kph = json_opt_int(j, "max_speed_kph");
  t.battery_capacity_wh = json_opt_int(j, "battery_capacity_wh");
  t.battery_capacity_mah = json_opt_int(j, "battery_capacity_mah");
  if (j.contains("wh_per_km") && !j["wh_per_km"].is_null()) {
    if (!j["wh_per_km"].is_number()) throw std::invalid_argument("wh_per_km: not a number");
    t.wh_per_km = j["wh_per_km"].get<double>();
  }
  t.validate();
  return t;
}

RegistryVehicle registry_vehicle_from_json(const json& j) {
  if (!j.is_object()) throw std::invalid_argument("expected a JSON object");
  RegistryVehicle v;
  v.vehicle_id = json_str(j, "vehicle_id", true);
  v.vehicle_type_id = json_str(j, "vehicle_type_id", true);
  v.device_id = json_str(j, "device_id", false);
  v.provider_id = json_str(j, "provider_id", false);
  v.provider_name = json_str(j, "provider_name", false);
  if (j.contains("removed")) {
    if (!j["removed"].is_boolean()) throw std::invalid_argument("removed: not a boolean");
    v.removed = j["removed"].get<bool>();
  }
  return v;
}

std::vector<VehicleType> parse_vehicle_types_csv(std::string_view text, std::string_view source) {
  std::vector<std::size_t> lines;
  const auto rows =
      csv_rows(text, source,
               {"vehicle_type_id", "name", "form_factor", "propulsion_type", "max_speed_kph",
                "battery_capacity_wh", "battery_capacity_mah", "wh_per_km"},
               &lines);
  std::vector<VehicleType> out;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const auto& row = rows[i];
    try {
      VehicleType t;
      t.id = field_or_empty(row, "vehicle_type_id");
      t.name = field_or_empty(row, "name");
      t.form_factor = field_or_empty(row, "form_factor");
      t.propulsion_type = field_or_empty(row, "propulsion_type");
      for (const auto& [key, dest] : {std::pair{"max_speed_kph", &t.max_speed_kph},
                                      std::pair{"battery_capacity_wh", &t.battery_capacity_wh},
                                      std::pair{"battery_capacity_mah", &t.battery_capacity_mah}}) {
        const std::string f = field_or_empty(row, key);
        if (!f.empty()) *dest = parse_int_field(f, key);
      }
      const std::string wh = field_or_empty(row, "wh_per_km");
      if (!wh.empty()) t.wh_per_km = parse_double_field(wh, "wh_per_km");
      t.validate();
      out.push_back(std::move(t));
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(std::string(source) + " line " + std::to_string(lines[i]) + ": " +
                                  e.what());
    }
  }
  return out;
}

std::vector<RegistryVehicle> parse_registry_csv(std::string_view text, std::string_view source) {
  std::vector<std::size_t> lines;
  const auto rows = csv_rows(
      text, source, {"vehicle_id", "vehicle_type_id", "device_id", "provider_id", "provider_name"},
      &lines);
  std::vector<RegistryVehicle> out;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    RegistryVehicle v;
    v.vehicle_id = field_or_empty(rows[i], "vehicle_id");
    v.vehicle_type_id = field_or_empty(rows[i], "vehicle_type_id");
    v.device_id = field_or_empty(rows[i], "device_id");
    v.provider_id = field_or_empty(rows[i], "provider_id");
    v.provider_name = field_or_empty(rows[i], "provider_name");
    if (v.vehicle_id.empty() || v.vehicle_type_id.empty()) {
      throw std::invalid_argument(std::string(source) + " line " + std::to_string(lines[i]) +
                                  ": vehicle_id and vehicle_type_id are required");
    }
    out.push_back(std::move(v));
  }
  return out;
}

std::string add_mds_agency(PgConnection& c, std::string_view agency, std::int64_t now_us) {
  if (agency.empty() || agency.size() > 64) {
    throw std::invalid_argument("agency name: 1 to 64 bytes");
  }
  const std::string token = random_token(32);
  const PgParam p[] = {std::string(agency), sha256_hex(token), std::to_string(now_us)};
  c.query(
      "INSERT INTO mds_agencies (agency, token_sha256, created_at_us) VALUES ($1, $2, $3) "
      "ON CONFLICT (agency) DO UPDATE SET token_sha256 = EXCLUDED.token_sha256, created_at_us = "
      "EXCLUDED.created_at_us, revoked_at_us = NULL",
      p, "mds agency");
  return token;
}

std::optional<std::string> agency_for_token(PgConnection& c, std::string_view token) {
  if (token.empty() || token.size() > 256) return std::nullopt;
  const PgParam p[] = {sha256_hex(token)};
  const PgResult r =
      c.query("SELECT agency FROM mds_agencies WHERE token_sha256 = $1 AND revoked_at_us IS NULL",
              p, "mds token");
  if (r.rows() != 1) return std::nullopt;
  return r.str(0, 0);
}

std::uint64_t import_zone_bundle(PgConnection& c, std::string_view signed_bundle,
                                 std::string_view published_by, std::int64_t now_us) {
  fleetgw::v1::SignedZoneBundle signed_msg;
  fleetgw::v1::ZoneBundle bundle;
  if (!signed_msg.ParseFromArray(signed_bundle.data(), static_cast<int>(signed_bundle.size())) ||
      !bundle.ParseFromString(signed_msg.bundle())) {
    throw std::invalid_argument("not a SignedZoneBundle (fleetgw zones sign writes one)");
  }
  if (bundle.version() == 0) throw std::invalid_argument("zone bundle version 0");
  if (signed_msg.signature().empty()) throw std::invalid_argument("zone bundle is not signed");
  std::string hex(2 * signed_bundle.size() + 1, '\0');
  sodium_bin2hex(hex.data(), hex.size(),
                 reinterpret_cast<const unsigned char*>(signed_bundle.data()),
                 signed_bundle.size());
  hex.pop_back();
  const PgParam p[] = {bundle.vehicle_id(),
                       std::to_string(bundle.version()),
                       "\\x" + hex,
                       std::to_string(bundle.issued_at_us()),
                       std::to_string(now_us),
                       std::string(published_by)};
  c.query(
      "INSERT INTO zone_bundles (vehicle_id, version, signed_bundle, issued_at_us, "
      "published_at_us, published_by) VALUES ($1, $2, $3::bytea, $4, $5, $6) "
      "ON CONFLICT (vehicle_id, version) DO NOTHING",
      p, "zone bundle");
  return bundle.version();
}

std::string random_uuid() {
  std::array<unsigned char, 16> b{};
  if (sodium_init() < 0) throw std::runtime_error("libsodium cannot be initialised");
  randombytes_buf(b.data(), b.size());
  return uuid_text(b, 4);
}

std::string name_uuid(std::string_view name) {
  std::array<unsigned char, 16> b{};
  // A fixed key separates these ids from any other BLAKE2b use of the same names.
  static constexpr unsigned char kKey[] = "fleetgw standards ids v1";
  crypto_generichash(b.data(), b.size(), reinterpret_cast<const unsigned char*>(name.data()),
                     name.size(), kKey, sizeof kKey - 1);
  return uuid_text(b, 8);
}

bool is_uuid(std::string_view s) {
  if (s.size() != 36) return false;
  for (std::size_t i = 0; i < s.size(); ++i) {
    const char ch = s[i];
    if (i == 8 || i == 13 || i == 18 || i == 23) {
      if (ch != '-') return false;
    } else if (!((ch >= '0' && ch <= '9') || (ch >= 'a' && ch <= 'f') ||
                 (ch >= 'A' && ch <= 'F'))) {
      return false;
    }
  }
  return true;
}

}  // namespace fleetgw::web
