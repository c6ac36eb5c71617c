// The zone bundle in force as GBFS v3.0 geofencing_zones (gbfs_feeds.h), through the one
// mapping the bike's zones tool uses too (proto/convert/gbfs_zones.h): a bundle made from GBFS
// comes back as it came (features in order, rules, names, windows, coordinates, global rules);
// an older bundle (zones by kind, precedence UNION) as the rules the bike enforces, most
// restrictive first.
#include <sodium.h>

#include <stdexcept>

#include "backend/web/gbfs_feeds.h"
#include "fleetgw/v1/zones.pb.h"
#include "proto/convert/gbfs_zones.h"

namespace fleetgw::web {

using nlohmann::json;
namespace pb = fleetgw::v1;

json gbfs_zones_from_bundle(std::string_view bundle_bytes, const StandardsOptions&) {
  pb::ZoneBundle b;
  if (!b.ParseFromArray(bundle_bytes.data(), static_cast<int>(bundle_bytes.size()))) {
    throw std::invalid_argument("zone bundle does not parse");
  }
  return fleetgw::convert::gbfs_from_zone_bundle(b)["data"];
}

json gbfs_geofencing_zones_data(PgConnection& c, const StandardsOptions& o) {
  const PgResult r = c.exec(
      "SELECT encode(signed_bundle, 'hex') FROM zone_bundles WHERE vehicle_id = '' "
      "ORDER BY version DESC LIMIT 1",
      "zone bundle in force");
  if (r.rows() == 0) {
    return {{"geofencing_zones", {{"type", "FeatureCollection"}, {"features", json::array()}}},
            {"global_rules", json::array()}};
  }
  const std::string_view hex = r.text(0, 0);
  std::string raw(hex.size() / 2, '\0');
  std::size_t len = 0;
  if (sodium_hex2bin(reinterpret_cast<unsigned char*>(raw.data()), raw.size(), hex.data(),
                     hex.size(), nullptr, &len, nullptr) != 0) {
    throw std::runtime_error("zone_bundles: stored bundle is not hex");
  }
  raw.resize(len);
  pb::SignedZoneBundle signed_msg;
  if (!signed_msg.ParseFromString(raw))
    throw std::runtime_error("zone_bundles: not a SignedZoneBundle");
  return gbfs_zones_from_bundle(signed_msg.bundle(), o);
}

}  // namespace fleetgw::web
