// Console schema version 3 (issue 27): the vehicle registry and the state behind the GBFS and
// MDS feeds. Listed in console_schema.cc's versions; released versions are never edited.
//
//  * registry_vehicle_types: a vehicle type as GBFS and MDS describe it, plus its range model
//    (wh_per_km: the energy a kilometre takes when the bike has not measured its own).
//  * registry_vehicles: vehicle id (the gateway's) -> device UUID (MDS device_id, constant for
//    the device's life), type and provider; removed_at_us marks a vehicle taken out of the fleet.
//  * gbfs_public_ids: the random id GBFS shows for a vehicle, one row per vehicle (only the
//    current one is kept: an old id cannot be linked to the vehicle afterwards). It is replaced
//    after every trip (gbfs_feeds.h says when).
//  * zone_bundles: signed zone bundles as published to the bikes (SignedZoneBundle bytes); the
//    fleet-wide one (vehicle_id '') with the highest version is the one in force.
//  * mds_agencies: one bearer token per agency; only its SHA-256 is stored.
#pragma once

#include <string_view>

namespace fleetgw::web {

inline constexpr std::string_view kRegistrySchemaV3 = R"sql(
CREATE TABLE registry_vehicle_types (
  vehicle_type_id text PRIMARY KEY CHECK (vehicle_type_id ~ '^[A-Za-z0-9._-]{1,64}$'),
  name text NOT NULL DEFAULT '' CHECK (length(name) <= 128),
  form_factor text NOT NULL CHECK (form_factor IN ('bicycle', 'cargo_bicycle', 'car', 'moped',
    'scooter_standing', 'scooter_seated', 'other')),
  propulsion_type text NOT NULL CHECK (propulsion_type IN ('human', 'electric_assist',
    'electric', 'combustion', 'combustion_diesel', 'hybrid', 'plug_in_hybrid',
    'hydrogen_fuel_cell')),
  max_speed_kph integer CHECK (max_speed_kph BETWEEN 1 AND 300),
  battery_capacity_wh integer CHECK (battery_capacity_wh > 0),
  battery_capacity_mah integer CHECK (battery_capacity_mah > 0),
  wh_per_km double precision CHECK (wh_per_km > 0),
  updated_at_us bigint NOT NULL);

CREATE TABLE registry_vehicles (
  vehicle_id text PRIMARY KEY CHECK (length(vehicle_id) BETWEEN 1 AND 128),
  device_id uuid NOT NULL UNIQUE,
  vehicle_type_id text NOT NULL REFERENCES registry_vehicle_types (vehicle_type_id),
  provider_id uuid NOT NULL,
  provider_name text NOT NULL DEFAULT '',
  created_at_us bigint NOT NULL, updated_at_us bigint NOT NULL, removed_at_us bigint);

CREATE TABLE gbfs_public_ids (
  vehicle_id text PRIMARY KEY REFERENCES registry_vehicles (vehicle_id) ON DELETE CASCADE,
  public_id text NOT NULL UNIQUE, epoch_us bigint NOT NULL,
  riding_seen boolean NOT NULL DEFAULT false);

CREATE TABLE zone_bundles (
  vehicle_id text NOT NULL DEFAULT '', version bigint NOT NULL CHECK (version > 0),
  signed_bundle bytea NOT NULL, issued_at_us bigint NOT NULL, published_at_us bigint NOT NULL,
  published_by text NOT NULL, PRIMARY KEY (vehicle_id, version));

CREATE TABLE mds_agencies (
  agency text PRIMARY KEY CHECK (length(agency) BETWEEN 1 AND 64),
  token_sha256 text NOT NULL UNIQUE, created_at_us bigint NOT NULL, revoked_at_us bigint);
)sql";

// Console schema version 5 (issue 27, registry_reservations.h): vehicle reservations, one row
// per reservation, kept after it ends (MDS reads past ones). ends_at_us is when it stopped
// holding the vehicle: cancelled or expired, whichever came first.
inline constexpr std::string_view kReservationSchemaV5 = R"sql(
CREATE TABLE vehicle_reservations (
  id bigserial PRIMARY KEY,
  vehicle_id text NOT NULL REFERENCES registry_vehicles (vehicle_id) ON DELETE CASCADE,
  reserved_by text NOT NULL, started_at_us bigint NOT NULL,
  expires_at_us bigint NOT NULL CHECK (expires_at_us > started_at_us),
  ended_at_us bigint, end_reason text,
  ends_at_us bigint GENERATED ALWAYS AS (least(coalesce(ended_at_us, expires_at_us),
                                               expires_at_us)) STORED);
CREATE INDEX vehicle_reservations_by_vehicle ON vehicle_reservations (vehicle_id, started_at_us);
CREATE INDEX vehicle_reservations_by_end ON vehicle_reservations (ends_at_us);
)sql";

}  // namespace fleetgw::web
