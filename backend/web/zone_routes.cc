// Zones from the console (issue 28): an admin uploads GeoJSON (zones by kind, as `fleetgw zones
// sign` reads it) or a GBFS v3.0 geofencing_zones.json, previews it on the map, and publishes
// it: the server checks the zones as the gateways will (proto/convert/geojson_zones.h),
// versions the bundle, signs it with its own key under its delegation (action "zones"), puts
// the delegation in SignedZoneBundle.delegation, publishes it retained on the fleet's bundle
// topic <prefix>/zones, records it in the registry's zone_bundles (what /gbfs/
// geofencing_zones.json serves) and audits it (`zones_publish`).
#include <sodium.h>

#include <algorithm>

#include "backend/web/admin_pages.h"
#include "backend/web/registry_store.h"
#include "fleetgw/v1/keys.pb.h"
#include "fleetgw/v1/zones.pb.h"
#include "proto/convert/gbfs_zones.h"
#include "proto/convert/geojson_zones.h"

namespace fleetgw::web {
namespace {

using nlohmann::json;

struct UploadedZones {
  v1::ZoneBundle bundle;
  std::string format;  // geojson | gbfs
  std::vector<std::string> notes;
  std::size_t vertices = 0;
};

// The upload as a bundle the gateways accept, or the refusal naming field and place.
std::variant<UploadedZones, std::string> read_upload(std::string_view body) {
  UploadedZones out;
  std::string features_path = "features";
  if (convert::is_gbfs_geofencing_zones(body)) {
    auto r = convert::zone_bundle_from_gbfs(body);
    if (auto* e = std::get_if<std::string>(&r)) return *e;
    auto& imported = std::get<convert::GbfsZonesImport>(r);
    out.bundle = std::move(imported.bundle);
    out.notes = std::move(imported.notes);
    out.format = "gbfs";
    features_path = "data.geofencing_zones.features";
  } else {
    auto r = convert::zone_bundle_from_geojson(body);
    if (auto* e = std::get_if<std::string>(&r)) return *e;
    out.bundle = std::move(std::get<v1::ZoneBundle>(r));
    out.format = "geojson";
  }
  if (auto e = convert::check_zone_bundle(out.bundle, features_path)) return *e;
  for (const auto& z : out.bundle.zones()) {
    for (const auto& ring : z.rings()) out.vertices += static_cast<std::size_t>(ring.lat_e7_size());
  }
  return out;
}

std::optional<v1::ZoneBundle> bundle_in_force(PgConnection& c, std::string& published_by,
                                              std::int64_t& published_at_us) {
  const PgResult r = c.exec(
      "SELECT encode(signed_bundle, 'hex'), published_by, published_at_us FROM zone_bundles "
      "WHERE vehicle_id = '' ORDER BY version DESC LIMIT 1",
      "zone bundle in force");
  if (r.rows() == 0) return std::nullopt;
  const std::string_view hex = r.text(0, 0);
  std::string raw(hex.size() / 2, '\0');
  std::size_t len = 0;
  if (sodium_hex2bin(reinterpret_cast<unsigned char*>(raw.data()), raw.size(), hex.data(),
                     hex.size(), nullptr, &len, nullptr) != 0) {
    return std::nullopt;
  }
  raw.resize(len);
  v1::SignedZoneBundle sb;
  v1::ZoneBundle b;
  if (!sb.ParseFromString(raw) || !b.ParseFromString(sb.bundle())) return std::nullopt;
  published_by = r.str(0, 1);
  published_at_us = r.int64(0, 2);
  return b;
}

// Newer than every fleet-wide bundle stored, and than any hand-numbered bundle signed offline
// with small versions (`fleetgw zones sign --version 3`): the Unix time in seconds when that is
// greater. The gateways accept only a greater version than the one in force.
std::uint64_t next_version(PgConnection& c, std::int64_t now) {
  const PgResult r = c.exec(
      "SELECT coalesce(max(version), 0) FROM zone_bundles WHERE vehicle_id = ''", "zone version");
  const auto stored = static_cast<std::uint64_t>(r.int64(0, 0));
  return std::max(stored + 1, static_cast<std::uint64_t>(now / 1'000'000));
}

json preview_json(const UploadedZones& u) {
  return {{"format", u.format},
          {"zones", u.bundle.zones_size()},
          {"vertices", u.vertices},
          {"notes", u.notes},
          {"geojson", convert::geojson_from_zone_bundle(u.bundle)}};
}

}  // namespace

void add_zone_routes(httplib::Server& s, RouteContext& ctx) {
  // The fleet-wide bundle in force, for every console's map.
  s.Get("/api/zones", [&ctx](const httplib::Request& req, httplib::Response& res) {
    if (!ctx.authorise(req, res, Role::Viewer, "zones")) return;
    std::string by;
    std::int64_t at = 0;
    auto c = ctx.pool.lease();
    const auto b = bundle_in_force(*c, by, at);
    if (!b) {
      send_json(res, 200,
                {{"version", nullptr},
                 {"geojson", {{"type", "FeatureCollection"}, {"features", json::array()}}}});
      return;
    }
    send_json(res, 200,
              {{"version", b->version()},
               {"issued_at_us", b->issued_at_us()},
               {"published_by", by},
               {"published_at_us", at},
               {"zones", b->zones_size()},
               {"geojson", convert::geojson_from_zone_bundle(*b)}});
  });

  s.Post("/api/zones/preview", [&ctx](const httplib::Request& req, httplib::Response& res) {
    const auto session = ctx.authorise(req, res, Role::Admin, "zones_preview");
    if (!session) return;
    auto u = read_upload(req.body);
    if (auto* e = std::get_if<std::string>(&u)) {
      send_error(res, 400, *e);
      return;
    }
    json out = preview_json(std::get<UploadedZones>(u));
    {
      auto c = ctx.pool.lease();
      out["next_version"] = next_version(*c, now_us());
    }
    out["signing"] = ctx.signer ? ctx.signer->describe() : json(nullptr);
    send_json(res, 200, out);
  });

  s.Post("/api/zones/publish", [&ctx](const httplib::Request& req, httplib::Response& res) {
    const auto session = ctx.authorise(req, res, Role::Admin, "zones_publish");
    if (!session) return;
    auto refuse = [&](int status, const std::string& result, const std::string& why) {
      ctx.auth.audit(session->operator_name, req.remote_addr, "zones_publish", "fleet", result,
                     why);
      send_error(res, status, why);
    };
    if (ctx.signer == nullptr || ctx.hub == nullptr) {
      refuse(503, "commands_off",
             "publishing is off: this fleetgw serve runs without --broker and --signing-key");
      return;
    }
    auto u = read_upload(req.body);
    if (auto* e = std::get_if<std::string>(&u)) {
      refuse(400, "bad_request", *e);
      return;
    }
    UploadedZones& up = std::get<UploadedZones>(u);
    const std::int64_t now = now_us();
    if (const auto why = ctx.signer->document_out_of_scope("zones", now)) {
      refuse(403, "out_of_scope", "outside this server's delegation: " + *why);
      return;
    }
    {
      auto c = ctx.pool.lease();
      up.bundle.set_version(next_version(*c, now));
    }
    up.bundle.set_issued_at_us(now);
    v1::SignedZoneBundle sb;
    sb.set_bundle(up.bundle.SerializeAsString());
    sb.set_signature(ctx.signer->sign_document(sb.bundle()));
    sb.set_key_id(ctx.signer->key_id());
    if (const v1::SignedDelegation* d = ctx.signer->signed_delegation()) {
      *sb.mutable_delegation() = *d;
    }
    const std::string payload = sb.SerializeAsString();
    const std::string target = "fleet/v" + std::to_string(up.bundle.version());
    try {
      ctx.hub->publish_retained({ctx.options.topic_prefix + "/zones"}, payload);
    } catch (const std::runtime_error& e) {
      refuse(502, "not_published", e.what());
      return;
    }
    {
      auto c = ctx.pool.lease();
      import_zone_bundle(*c, payload, session->operator_name, now);
    }
    ctx.auth.audit(session->operator_name, req.remote_addr, "zones_publish", target, "ok",
                   std::to_string(up.bundle.zones_size()) + " zones, " +
                       std::to_string(up.vertices) + " vertices (" + up.format + ")");
    json out = preview_json(up);
    out["version"] = up.bundle.version();
    out["topic"] = ctx.options.topic_prefix + "/zones";
    out["key_id"] = ctx.signer->key_id();
    send_json(res, 200, out);
  });
}

}  // namespace fleetgw::web
