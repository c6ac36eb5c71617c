#include "gateway/geofence/zone_tool.h"

#include <ostream>

#include "fleetgw/v1/zones.pb.h"
#include "gateway/command/ed25519.h"
#include "gateway/command/signing.h"
#include "gateway/common/untrusted_text.h"
#include "gateway/geofence/zone_bundle.h"
#include "gateway/geofence/zone_file.h"
#include "gateway/geofence/zone_geojson.h"
#include "proto/convert/gbfs_zones.h"
#include "proto/convert/mds_policy.h"

namespace fleetgw::geofence {
namespace {

constexpr std::size_t kMaxGeojsonBytes = 64u << 20;

void print_verdict(const BundleVerdict& v, std::ostream& out) {
  out << bundle_outcome_name(v.outcome);
  if (v.reason != BundleRefusal::kNone) out << " (" << bundle_refusal_name(v.reason) << ")";
  out << ": " << v.detail << '\n';
}

// A GBFS document (or an MDS Policy with its Geography) into a bundle the gateway accepts; its
// notes on `err`.
std::variant<v1::ZoneBundle, std::string> bundle_from_gbfs(
    std::string_view text, std::uint64_t version, Micros issued_at, std::ostream& err,
    const std::optional<std::string>& mds_geography = std::nullopt) {
  auto imported = mds_geography ? convert::zone_bundle_from_mds(text, *mds_geography)
                                : convert::zone_bundle_from_gbfs(text);
  if (auto* problem = std::get_if<std::string>(&imported)) {
    return (mds_geography ? "MDS " : "GBFS ") + *problem;
  }
  auto& gbfs = std::get<convert::GbfsZonesImport>(imported);
  for (const auto& note : gbfs.notes) {
    err << "zones sign: note: " << common::untrusted_excerpt(note, 256) << '\n';
  }
  gbfs.bundle.set_version(version);
  gbfs.bundle.set_issued_at_us(issued_at.count());
  // The gateway's own rules, so a bundle signed here is one it accepts.
  auto compiled = compile_zones(gbfs.bundle);
  if (auto* error = std::get_if<std::string>(&compiled)) {
    return (mds_geography ? "MDS: " : "GBFS data.geofencing_zones.features: ") + *error;
  }
  return std::move(gbfs.bundle);
}

}  // namespace

int run_zones_sign(const ZonesSignOptions& options, std::ostream& out, std::ostream& err) {
  try {
    if (options.version == 0) {
      err << "zones sign: --version must be at least 1 (greater than the bundle in force)\n";
      return 1;
    }
    std::string error;
    const auto text = read_zone_file(options.geojson, error, kMaxGeojsonBytes);
    if (!text) {
      err << "zones sign: " << (error.empty() ? options.geojson.string() + ": no such file" : error)
          << '\n';
      return 1;
    }
    std::optional<std::string> geography;
    if (!options.mds_geography.empty()) {
      geography = read_zone_file(options.mds_geography, error, kMaxGeojsonBytes);
      if (!geography) {
        err << "zones sign: "
            << (error.empty() ? options.mds_geography.string() + ": no such file" : error) << '\n';
        return 1;
      }
    }
    auto bundle = geography || convert::is_gbfs_geofencing_zones(*text)
                      ? bundle_from_gbfs(*text, options.version, options.issued_at, err, geography)
                      : bundle_from_geojson(*text, options.version, options.issued_at);
    if (auto* problem = std::get_if<std::string>(&bundle)) {
      err << "zones sign: " << options.geojson.string() << ": " << *problem << '\n';
      return 1;
    }
    const std::string key_id =
        options.key_id.empty() ? options.key_pem.stem().string() : options.key_id;
    if (!command::is_valid_tool_id(key_id)) {
      err << "zones sign: key id '" << common::untrusted_excerpt(key_id)
          << "' must be 1..64 characters of [A-Za-z0-9._-]\n";
      return 1;
    }
    if (!options.vehicle_id.empty() && !command::is_valid_tool_id(options.vehicle_id)) {
      err << "zones sign: --vehicle '" << common::untrusted_excerpt(options.vehicle_id)
          << "' must be 1..64 characters of [A-Za-z0-9._-]\n";
      return 1;
    }
    const auto key = command::Ed25519PrivateKey::load_pem(options.key_pem);
    auto& b = std::get<v1::ZoneBundle>(bundle);
    b.set_vehicle_id(options.vehicle_id);
    std::string payload = sign_zone_bundle(b, key, key_id);
    if (!options.delegation.empty()) {
      // Issue 28: outside the signed bytes, as the root signed it.
      const auto delegation = read_zone_file(options.delegation, error, 64 * 1024);
      v1::SignedZoneBundle s;
      s.ParseFromString(payload);
      if (!delegation || !s.mutable_delegation()->ParseFromString(*delegation)) {
        err << "zones sign: --delegation " << options.delegation.string()
            << ": not a signed delegation " << error << '\n';
        return 1;
      }
      payload = s.SerializeAsString();
    }
    if (!write_zone_file(options.out, payload, error)) {
      err << "zones sign: " << error << '\n';
      return 1;
    }
    // Counted as the gateway counts them (a closing vertex repeating the first is not one).
    const auto compiled = compile_zones(b);
    const std::size_t vertices =
        std::holds_alternative<ZoneSet>(compiled) ? std::get<ZoneSet>(compiled).vertices : 0;
    out << "zones sign: version " << b.version() << ", " << b.zones_size() << " zones, " << vertices
        << " vertices, ";
    if (!b.vehicle_id().empty()) out << "for vehicle '" << b.vehicle_id() << "', ";
    out << "signed by '" << key_id << "': " << payload.size() << " bytes -> "
        << options.out.string() << '\n';
    return 0;
  } catch (const std::exception& e) {
    err << "zones sign: " << e.what() << '\n';
    return 1;
  }
}

int run_zones_check(const ZonesCheckOptions& options, std::ostream& out, std::ostream& err) {
  try {
    ZoneAuthority authority(options.trusted_keys, {}, options.vehicle_id);
    std::string error;
    if (options.in_force) {
      const auto v = restore_zones(authority, *options.in_force, error);
      if (!error.empty()) {
        err << "zones check: " << error << '\n';
        return 1;
      }
      out << "in force (" << options.in_force->string() << "): ";
      if (v) {
        print_verdict(*v, out);
      } else {
        out << "none\n";
      }
    }
    const auto payload = read_zone_file(options.bundle, error);
    if (!payload) {
      err << "zones check: " << (error.empty() ? options.bundle.string() + ": no such file" : error)
          << '\n';
      return 1;
    }
    const auto v = authority.offer(*payload);
    out << options.bundle.string() << ": ";
    print_verdict(v, out);
    if (v.outcome == BundleOutcome::kRefused) return 1;
    for (const auto& z : authority.in_force()->zones->zones) {
      out << "  " << z.id << "  " << zone_kind_name(z.kind) << "  " << z.shape.vertex_count()
          << " vertices";
      if (z.kind == ZoneKind::kSlow) out << "  " << z.speed_limit_kmh << " km/h";
      if (z.kind == ZoneKind::kRules) out << "  " << z.rules.size() << " rule(s)";
      if (z.start.count() != 0) out << "  from " << convert::rfc3339_from_us(z.start.count());
      if (z.end.count() != 0) out << "  until " << convert::rfc3339_from_us(z.end.count());
      if (!z.name.empty()) out << "  \"" << common::untrusted_excerpt(z.name, 128) << '"';
      out << '\n';
    }
    return 0;
  } catch (const std::exception& e) {
    err << "zones check: " << e.what() << '\n';
    return 1;
  }
}

int run_zones_export(const ZonesExportOptions& options, std::ostream& out, std::ostream& err) {
  try {
    std::string error;
    const auto payload = read_zone_file(options.bundle, error);
    if (!payload) {
      err << "zones export: "
          << (error.empty() ? options.bundle.string() + ": no such file" : error) << '\n';
      return 1;
    }
    if (options.trusted_keys.empty()) {
      err << "zones export: " << options.bundle.string()
          << ": signature not checked (no --config with [command.trusted_keys])\n";
    } else {
      ZoneAuthority authority(options.trusted_keys, {}, options.vehicle_id);
      const auto v = authority.offer(*payload);
      if (v.outcome == BundleOutcome::kRefused) {
        err << "zones export: " << options.bundle.string() << ": a gateway would refuse it: ";
        print_verdict(v, err);
        return 1;
      }
    }
    v1::SignedZoneBundle signed_bundle;
    v1::ZoneBundle bundle;
    if (!signed_bundle.ParseFromString(*payload) ||
        !bundle.ParseFromString(signed_bundle.bundle())) {
      err << "zones export: " << options.bundle.string() << ": not a fleetgw.v1.SignedZoneBundle\n";
      return 1;
    }
    convert::GbfsExportOptions gbfs;
    gbfs.ttl_s = options.ttl_s;
    const std::string text = convert::gbfs_from_zone_bundle(bundle, gbfs).dump(2) + "\n";
    if (options.out_file.empty()) {
      out << text;
      return 0;
    }
    if (!write_zone_file(options.out_file, text, error)) {
      err << "zones export: " << error << '\n';
      return 1;
    }
    out << "zones export: version " << bundle.version() << ", " << bundle.zones_size()
        << " zones -> " << options.out_file.string() << '\n';
    return 0;
  } catch (const std::exception& e) {
    err << "zones export: " << e.what() << '\n';
    return 1;
  }
}

}  // namespace fleetgw::geofence
