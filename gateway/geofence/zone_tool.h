// `fleetgw zones sign|check`: the operator's side of zone bundles (issue 14). The CLI (gateway/
// app/cli.cc) parses the arguments and the configuration; everything else is here, testable
// with streams.
//
// Contract:
//  * run_zones_sign() reads a GeoJSON FeatureCollection (zone_geojson.h), builds the bundle of
//    `version` issued at `issued_at`, validates it with the gateway's own rules, signs it with
//    the Ed25519 PEM key (the `fleetgw keygen` key; key id: `key_id`, by default the key file's
//    name without .pem, as keygen names it) and writes the SignedZoneBundle atomically to `out`
//    (zone_file.h). With `vehicle_id` the bundle names that vehicle (ZoneBundle.vehicle_id):
//    only that vehicle's gateway accepts it, on its own topic or the fleet's. It prints one
//    line saying what it wrote. Exit 0; 1 with a message on `err`
//    naming the file and the problem (unreadable, invalid zone, bad key); nothing is written
//    then.
//  * Issue 27: run_zones_sign() also reads a GBFS v3.0 geofencing_zones.json as published (a
//    document with data.geofencing_zones; proto/convert/gbfs_zones.h maps it): precedence
//    first_match, one `rules` zone per feature, global_rules as the default. Every note of the
//    conversion (read, no effect on the bike) is printed on `err` as "zones sign: note: <json
//    path>: ..." and the bundle is signed; a rule it cannot express is refused, naming the rule
//    and its JSON path, and nothing is written. With `mds_geography` the input is an MDS 2.0
//    Policy whose speed rules become rules zones over that Geography (proto/convert/
//    mds_policy.h), with the same notes and refusals.
//  * run_zones_export() writes a signed bundle file (the gateway's bundle_file: the bundle in
//    force) back as GBFS v3.0 geofencing_zones.json on `out` or into `out_file` (atomically).
//    With trusted keys it first judges the file as a gateway would and exports only what one
//    would accept (exit 1 with the verdict otherwise); without, it says on `err` that the
//    signature was not checked. Exit 1 when the file is unreadable or not a SignedZoneBundle.
//  * run_zones_check() judges a signed bundle file exactly as a gateway would: with the trusted
//    keys given and, when `in_force` names a file (the gateway's stored bundle), against the
//    bundle in force there, and with `vehicle_id` as that vehicle's gateway (a bundle signed
//    for another vehicle is refused as wrong_vehicle). It prints the verdict and, when the bundle
//    authenticates and is valid, one line per zone (id, kind, vertices, limit, name). Exit 0 when a
//    gateway would accept it (or already has it), 1 when it would refuse it.
#pragma once

#include <cstdint>
#include <filesystem>
#include <iosfwd>
#include <map>
#include <optional>
#include <string>

#include "gateway/geofence/zone_engine.h"

namespace fleetgw::geofence {

struct ZonesSignOptions {
  std::filesystem::path geojson;
  std::filesystem::path key_pem;
  std::string key_id;  // empty: the key file's stem
  std::uint64_t version = 0;
  Micros issued_at{0};
  std::filesystem::path out;
  std::string vehicle_id;  // empty: a fleet-wide bundle; else only that vehicle accepts it
  // Issue 27: set, `geojson` is an MDS 2.0 Policy and this its Geography (mds_policy.h).
  std::filesystem::path mds_geography{};
  // Issue 28: the signing key's SignedDelegation (fleetgw keys delegate, action "zones"), sent in
  // SignedZoneBundle.delegation for a key the gateways know only through their root keys.
  std::filesystem::path delegation{};
};
int run_zones_sign(const ZonesSignOptions& options, std::ostream& out, std::ostream& err);

struct ZonesCheckOptions {
  std::filesystem::path bundle;
  std::map<std::string, std::string> trusted_keys;  // as [command.trusted_keys]
  std::optional<std::filesystem::path> in_force;
  std::string vehicle_id;  // judge as this vehicle's gateway; empty: any vehicle
};
int run_zones_check(const ZonesCheckOptions& options, std::ostream& out, std::ostream& err);

struct ZonesExportOptions {
  std::filesystem::path bundle;                     // a signed bundle file
  std::map<std::string, std::string> trusted_keys;  // empty: the signature is not checked
  std::string vehicle_id;                           // judge as this vehicle's gateway
  std::filesystem::path out_file;                   // empty: `out`
  std::uint32_t ttl_s = 0;
};
int run_zones_export(const ZonesExportOptions& options, std::ostream& out, std::ostream& err);

}  // namespace fleetgw::geofence
