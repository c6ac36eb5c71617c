// The vehicle registry (console schema v3, registry_schema.h): vehicle types, vehicles, MDS
// agency tokens and published zone bundles, shared by the admin API, the CLI and the feeds.
//
// Contract:
//  * validate() of a type or vehicle throws std::invalid_argument naming the field and why; the
//    upserts validate first, so the database's CHECKs are only a backstop.
//  * upsert_vehicle() keeps a vehicle's device UUID for ever: an update that gives another one is
//    refused (MDS: device_id is constant for the device's life); none given on creation: a
//    random UUIDv4. Returns the device UUID. Its type must exist (refused otherwise).
//  * CSV imports (parse_*_csv): a header line naming the columns (any order; unknown columns
//    refused), comma separated, no quoting (a field holding a comma or quote is refused: use the
//    API); errors name the source and line. Vehicle types: vehicle_type_id, form_factor,
//    propulsion_type required; name, max_speed_kph, battery_capacity_wh, battery_capacity_mah,
//    wh_per_km optional. Vehicles: vehicle_id, vehicle_type_id required; device_id, provider_id,
//    provider_name optional.
//  * add_mds_agency() creates (or replaces the token of) an agency and returns its new bearer
//    token (256 random bits, base64url); only the token's SHA-256 is stored.
//    agency_for_token() is the agency of a live token, nullopt otherwise.
//  * import_zone_bundle() stores a SignedZoneBundle's bytes after parsing the bundle inside
//    (refused when it does not parse or has version 0); the signature is the bikes' to verify.
//  * name_uuid() is a stable UUID (RFC 9562 version 8) derived from a name by BLAKE2b: the same
//    name gives the same id on every instance and request (trip, event and telemetry ids).
#pragma once

#include <nlohmann/json.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "backend/common/pg.h"

namespace fleetgw::web {

struct VehicleType {
  std::string id;
  std::string name;
  std::string form_factor = "bicycle";
  std::string propulsion_type = "electric_assist";
  std::optional<int> max_speed_kph;
  std::optional<int> battery_capacity_wh;
  std::optional<int> battery_capacity_mah;
  std::optional<double> wh_per_km;
  void validate() const;
  // The range on a full pack by the type's model (capacity / energy per km), if both are known.
  std::optional<double> max_range_m() const;
};

struct RegistryVehicle {
  std::string vehicle_id;
  std::string vehicle_type_id;
  std::string device_id;  // empty: keep the stored one, or a random one on creation
  std::string provider_id;
  std::string provider_name;
  bool removed = false;
  void validate() const;
};

void upsert_vehicle_type(PgConnection& c, const VehicleType& t, std::int64_t now_us);
std::string upsert_vehicle(PgConnection& c, const RegistryVehicle& v, std::int64_t now_us);
nlohmann::json list_vehicle_types(PgConnection& c);
nlohmann::json list_registry_vehicles(PgConnection& c);

// From API bodies; throw std::invalid_argument naming the field.
VehicleType vehicle_type_from_json(const nlohmann::json& j);
RegistryVehicle registry_vehicle_from_json(const nlohmann::json& j);

std::vector<VehicleType> parse_vehicle_types_csv(std::string_view text, std::string_view source);
std::vector<RegistryVehicle> parse_registry_csv(std::string_view text, std::string_view source);

std::string add_mds_agency(PgConnection& c, std::string_view agency, std::int64_t now_us);
std::optional<std::string> agency_for_token(PgConnection& c, std::string_view token);

std::uint64_t import_zone_bundle(PgConnection& c, std::string_view signed_bundle,
                                 std::string_view published_by, std::int64_t now_us);

std::string random_uuid();
std::string name_uuid(std::string_view name);
bool is_uuid(std::string_view s);

}  // namespace fleetgw::web
