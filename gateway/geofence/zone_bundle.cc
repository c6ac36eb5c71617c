#include "gateway/geofence/zone_bundle.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <stdexcept>

#include "fleetgw/v1/zones.pb.h"
#include "gateway/command/document_signer.h"
#include "gateway/command/sha256.h"
#include "gateway/command/signing.h"
#include "gateway/common/untrusted_text.h"

namespace fleetgw::geofence {
namespace {

constexpr std::int64_t kMaxLatE7 = 900'000'000;
constexpr std::int64_t kMaxLonE7 = 1'800'000'000;
constexpr std::int64_t kMaxLonSpanE7 = 1'800'000'000;  // no zone across the antimeridian
constexpr std::size_t kMaxQuotedBytes = 64;

std::string quote_zone_text(std::string_view untrusted) {
  return "'" + common::untrusted_excerpt(untrusted, kMaxQuotedBytes) + "'";
}

// "zone 3 ('old-town')": where in the bundle a problem is.
std::string zone_where(int index, const v1::Zone& zone) {
  return "zone " + std::to_string(index) + " (" + quote_zone_text(zone.id()) + ")";
}

// How many distinct vertices the ring has, counted up to 3 (one pass, no allocation): A-B-A-B
// has two, whatever its length.
std::size_t distinct_up_to_3(const Ring& ring) {
  if (ring.empty()) return 0;
  const Vertex a = ring.front();
  std::optional<Vertex> b;
  for (const auto& v : ring) {
    if (v == a || (b && v == *b)) continue;
    if (b) return 3;
    b = v;
  }
  return b ? 2 : 1;
}

// Every vertex within kMinRingWidthM of one line: the ring encloses no area worth the name (an
// operating area nobody can be inside, a slow zone nobody can enter). The line runs from the
// first vertex to the one farthest from it; distances on the plane tangent at the first vertex
// (exact enough for a threshold of centimetres). Rounding to 1e-7 degrees (1.1 cm) makes a line
// drawn on a map only nearly straight, hence a width rather than exact collinearity.
constexpr double kMinRingWidthM = 0.1;
constexpr double kMPerE7 = 6'371'008.8 * M_PI / 180.0 * 1e-7;

// A vertex on the plane tangent at `origin`, in metres east and north.
struct LocalPlane {
  Vertex origin;
  double kx = std::cos(origin.lat_e7 * 1e-7 * M_PI / 180.0) * kMPerE7;
  std::pair<double, double> operator()(const Vertex& v) const {
    return {static_cast<double>(std::int64_t{v.lon_e7} - origin.lon_e7) * kx,
            static_cast<double>(std::int64_t{v.lat_e7} - origin.lat_e7) * kMPerE7};
  }
};

bool collinear(const Ring& ring) {
  const LocalPlane local{ring.front()};
  double bx = 0, by = 0;
  for (const auto& v : ring) {
    const auto [x, y] = local(v);
    if (x * x + y * y > bx * bx + by * by) {
      bx = x;
      by = y;
    }
  }
  const double length = std::hypot(bx, by);
  if (!(length > 0)) return true;
  return std::all_of(ring.begin(), ring.end(), [&](const Vertex& v) {
    const auto [x, y] = local(v);
    return std::abs(bx * y - by * x) / length < kMinRingWidthM;
  });
}

// How many of the ring's edges are not cancelled by a retrace, counted up to 3. Under the
// even-odd rule the engine applies, an edge traced twice (A-B then B-A, or A-B twice) adds two
// crossings and so nothing: a ring that doubles back on itself (A-B-C-B) has three distinct
// vertices and a width, yet no point is inside it. A bow tie keeps all four edges and stays a
// zone (two triangles). The edges are sorted once: 16 bytes per vertex, freed before the index
// is built, so the documented peak per vertex is unchanged.
std::size_t uncancelled_edges_up_to_3(const Ring& ring) {
  using Key = std::uint64_t;
  auto key = [](const Vertex& v) {
    return (Key{static_cast<std::uint32_t>(v.lat_e7)} << 32) | static_cast<std::uint32_t>(v.lon_e7);
  };
  std::vector<std::pair<Key, Key>> edges;
  edges.reserve(ring.size());
  for (std::size_t i = 0; i < ring.size(); ++i) {
    const Key a = key(ring[i]), b = key(ring[(i + 1) % ring.size()]);
    edges.emplace_back(std::min(a, b), std::max(a, b));
  }
  std::sort(edges.begin(), edges.end());
  std::size_t odd = 0;
  for (std::size_t i = 0; i < edges.size() && odd < 3;) {
    std::size_t j = i;
    while (j < edges.size() && edges[j] == edges[i]) ++j;
    if ((j - i) % 2 == 1) ++odd;
    i = j;
  }
  return odd;
}

// The ring's vertices without consecutive repeats (nor a last vertex repeating the first), or
// a reason it cannot be one.
std::variant<Ring, std::string> ring_of(const v1::ZoneRing& r) {
  if (r.lat_e7_size() != r.lon_e7_size()) {
    return std::to_string(r.lat_e7_size()) + " latitudes but " + std::to_string(r.lon_e7_size()) +
           " longitudes";
  }
  Ring ring;
  ring.reserve(static_cast<std::size_t>(r.lat_e7_size()));
  std::int64_t lon_lo = kMaxLonE7, lon_hi = -kMaxLonE7;
  for (int i = 0; i < r.lat_e7_size(); ++i) {
    const std::int64_t lat = r.lat_e7(i), lon = r.lon_e7(i);
    if (lat < -kMaxLatE7 || lat > kMaxLatE7) {
      return "vertex " + std::to_string(i) + ": latitude " + std::to_string(lat) +
             "e-7 is outside -90..90 degrees";
    }
    if (lon < -kMaxLonE7 || lon > kMaxLonE7) {
      return "vertex " + std::to_string(i) + ": longitude " + std::to_string(lon) +
             "e-7 is outside -180..180 degrees";
    }
    lon_lo = std::min(lon_lo, lon);
    lon_hi = std::max(lon_hi, lon);
    const Vertex v{r.lat_e7(i), r.lon_e7(i)};
    if (ring.empty() || !(ring.back() == v)) ring.push_back(v);
  }
  if (ring.size() > 1 && ring.back() == ring.front()) ring.pop_back();
  if (const std::size_t distinct = distinct_up_to_3(ring); distinct < 3) {
    return std::to_string(distinct) + " distinct vertices (at least 3 needed)";
  }
  if (lon_hi - lon_lo > kMaxLonSpanE7) {
    return "spans more than 180 degrees of longitude (zones across the antimeridian are not "
           "supported)";
  }
  if (collinear(ring)) {
    return "all " + std::to_string(ring.size()) +
           " vertices lie on one line (within 0.1 m: the ring encloses no area)";
  }
  if (uncancelled_edges_up_to_3(ring) < 3) {
    return "doubles back on itself: every edge is traced twice, so it encloses nothing";
  }
  return ring;
}

std::optional<ZoneKind> kind_of(int kind) {
  switch (kind) {
    case v1::ZONE_KIND_OPERATING_AREA:
      return ZoneKind::kOperatingArea;
    case v1::ZONE_KIND_SLOW:
      return ZoneKind::kSlow;
    case v1::ZONE_KIND_NO_RIDE:
      return ZoneKind::kNoRide;
    case v1::ZONE_KIND_NO_PARKING:
      return ZoneKind::kNoParking;
    case v1::ZONE_KIND_NO_START:
      return ZoneKind::kNoStart;
    case v1::ZONE_KIND_RULES:
      return ZoneKind::kRules;
    default:
      return std::nullopt;
  }
}

// A GBFS rule as the engine applies it, or why it cannot be one.
std::variant<ZoneRuleSpec, std::string> rule_spec_of(const v1::ZoneRule& r) {
  ZoneRuleSpec spec;
  for (const auto& type : r.vehicle_type_ids()) {
    if (type.empty() || type.size() > 64 || !common::is_valid_utf8(type)) {
      return "a vehicle type id must be 1..64 bytes of UTF-8";
    }
    spec.vehicle_type_ids.push_back(type);
  }
  if (r.has_maximum_speed_kph()) {
    if (r.maximum_speed_kph() > 255) {
      return "maximum_speed_kph " + std::to_string(r.maximum_speed_kph()) + " is not in 0..255";
    }
    spec.effects.speed_limit_kmh = static_cast<int>(r.maximum_speed_kph());
  }
  spec.effects.no_start = !r.ride_start_allowed();
  spec.effects.no_parking = !r.ride_end_allowed();
  spec.effects.no_ride = !r.ride_through_allowed();
  return spec;
}

// The issue-27 fields of zone `z` (rules, window, polygons, names) into `zone`, or why not.
std::optional<std::string> gbfs_fields_of(const v1::Zone& z, EnforcedZone& zone,
                                          const BundleLimits& limits) {
  if (z.kind() != v1::ZONE_KIND_RULES && z.rules_size() > 0) {
    return std::string("rules are only for zones of kind rules");
  }
  for (int r = 0; r < z.rules_size(); ++r) {
    auto spec = rule_spec_of(z.rules(r));
    if (auto* error = std::get_if<std::string>(&spec)) {
      return "rule " + std::to_string(r) + ": " + *error;
    }
    zone.rules.push_back(std::move(std::get<ZoneRuleSpec>(spec)));
  }
  if (z.start_us() < 0 || z.end_us() < 0) return std::string("start_us/end_us before 1970");
  if (z.start_us() != 0 && z.end_us() != 0 && z.end_us() <= z.start_us()) {
    return "end_us " + std::to_string(z.end_us()) + " is not after start_us " +
           std::to_string(z.start_us());
  }
  zone.start = Micros(z.start_us());
  zone.end = Micros(z.end_us());
  if (z.polygon_rings_size() > 0) {
    std::uint64_t total = 0;
    for (const auto count : z.polygon_rings()) {
      if (count == 0) return std::string("polygon_rings: a polygon of 0 rings");
      total += count;
    }
    if (total != static_cast<std::uint64_t>(z.rings_size())) {
      return "polygon_rings add up to " + std::to_string(total) + " rings, the zone has " +
             std::to_string(z.rings_size());
    }
  }
  for (int n = 0; n < z.names_size(); ++n) {
    const auto& name = z.names(n);
    if (name.text().size() > limits.max_name_bytes || !common::is_valid_utf8(name.text()) ||
        name.language().size() > 35 || !common::is_valid_utf8(name.language())) {
      return "names " + std::to_string(n) + ": text must be at most " +
             std::to_string(limits.max_name_bytes) + " bytes of UTF-8, language at most 35";
    }
  }
  return std::nullopt;
}

std::string_view bundle_topic_name(BundleTopic topic) {
  return topic == BundleTopic::kVehicle ? "the vehicle's own topic" : "the fleet topic";
}

BundleVerdict refused(BundleRefusal reason, std::string detail, std::uint64_t version,
                      const std::optional<BundleInForce>& in_force) {
  BundleVerdict v;
  v.outcome = BundleOutcome::kRefused;
  v.reason = reason;
  v.detail = std::move(detail);
  v.version = version;
  v.in_force = in_force ? in_force->zones->version : 0;
  return v;
}

}  // namespace

std::variant<ZoneSet, std::string> compile_zones(const v1::ZoneBundle& bundle,
                                                 const BundleLimits& limits) {
  if (bundle.version() == 0) return std::string("version 0 (versions start at 1)");
  if (bundle.issued_at_us() <= 0) return std::string("no issued_at_us");
  if (!bundle.vehicle_id().empty() && !command::is_valid_tool_id(bundle.vehicle_id())) {
    return "vehicle_id " + quote_zone_text(bundle.vehicle_id()) +
           " must be 1..64 characters of [A-Za-z0-9._-] (or empty: fleet-wide)";
  }
  if (bundle.precedence() != v1::ZONE_PRECEDENCE_UNION &&
      bundle.precedence() != v1::ZONE_PRECEDENCE_FIRST_MATCH) {
    return "unknown precedence " + std::to_string(bundle.precedence());
  }
  if (bundle.precedence() != v1::ZONE_PRECEDENCE_FIRST_MATCH && bundle.default_rules_size() > 0) {
    return std::string("default_rules need precedence first_match (GBFS)");
  }
  if (static_cast<std::size_t>(bundle.zones_size()) > limits.max_zones) {
    return std::to_string(bundle.zones_size()) + " zones, at most " +
           std::to_string(limits.max_zones);
  }
  std::size_t vertices = 0;
  for (const auto& zone : bundle.zones()) {
    for (const auto& ring : zone.rings()) vertices += static_cast<std::size_t>(ring.lat_e7_size());
  }
  if (vertices > limits.max_vertices) {
    return std::to_string(vertices) + " vertices, at most " + std::to_string(limits.max_vertices);
  }
  ZoneSet set;
  set.version = bundle.version();
  set.issued_at = Micros(bundle.issued_at_us());
  set.precedence = bundle.precedence() == v1::ZONE_PRECEDENCE_FIRST_MATCH ? Precedence::kFirstMatch
                                                                          : Precedence::kUnion;
  for (int r = 0; r < bundle.default_rules_size(); ++r) {
    auto spec = rule_spec_of(bundle.default_rules(r));
    if (auto* error = std::get_if<std::string>(&spec)) {
      return "default rule " + std::to_string(r) + ": " + *error;
    }
    set.default_rules.push_back(std::move(std::get<ZoneRuleSpec>(spec)));
  }
  set.zones.reserve(static_cast<std::size_t>(bundle.zones_size()));
  std::set<std::string_view> ids;
  for (int i = 0; i < bundle.zones_size(); ++i) {
    const v1::Zone& z = bundle.zones(i);
    const std::string where = zone_where(i, z);
    if (!command::is_valid_tool_id(z.id())) {
      return where + ": id must be 1..64 characters of [A-Za-z0-9._-]";
    }
    if (!ids.insert(z.id()).second) return where + ": id repeated";
    if (z.name().size() > limits.max_name_bytes || !common::is_valid_utf8(z.name())) {
      return where + ": name must be at most " + std::to_string(limits.max_name_bytes) +
             " bytes of UTF-8";
    }
    const auto kind = kind_of(z.kind());
    if (!kind) return where + ": unknown kind " + std::to_string(z.kind());
    // 0 stays refused here: proto3 cannot tell it from a limit left out. GBFS's "stop" is a
    // rules zone's maximum_speed_kph of 0 (explicit presence; issue 27).
    if (*kind == ZoneKind::kSlow && (z.speed_limit_kmh() < 1 || z.speed_limit_kmh() > 255)) {
      return where + ": a slow zone needs speed_limit_kmh in 1..255, not " +
             std::to_string(z.speed_limit_kmh());
    }
    if (*kind != ZoneKind::kSlow && z.speed_limit_kmh() != 0) {
      return where + ": speed_limit_kmh is only for slow zones";
    }
    if (z.rings_size() == 0) return where + ": no ring";
    std::vector<Ring> rings;
    for (int r = 0; r < z.rings_size(); ++r) {
      auto ring = ring_of(z.rings(r));
      if (auto* error = std::get_if<std::string>(&ring)) {
        return where + ", ring " + std::to_string(r) + ": " + *error;
      }
      rings.push_back(std::move(std::get<Ring>(ring)));
    }
    EnforcedZone zone{z.id(),
              z.name(),
              *kind,
              static_cast<int>(z.speed_limit_kmh()),
              ZonePolygon::build(rings),
              {},
              Micros(0),
              Micros(0)};
    if (auto error = gbfs_fields_of(z, zone, limits)) return where + ": " + *error;
    set.vertices += zone.shape.vertex_count();
    set.zones.push_back(std::move(zone));
  }
  return set;
}

// Per vertex kept in force: points (8 bytes, plus one closing point per ring of >= 3
// vertices), the edge list (4), the band index (<= 16 entries of 4 + one band start per 4
// edges): 84 with rounding. Per zone: the Zone, its id and name, six allocations' overhead.
constexpr std::size_t kSetBytesPerVertex = 84;
constexpr std::size_t kSetBytesPerZone = 1024;
// While judging, per vertex: the parsed ZoneBundle's two repeated sint32 fields (capacity up to
// twice their size: 16 bytes) and the zone's rings being compiled (8). Per zone, the parsed
// Zone message. Per payload byte: the payload as received, the SignedZoneBundle's copy of the
// bundle bytes and the copy kept in force.
constexpr std::size_t kJudgingBytesPerVertex = 24;
constexpr std::size_t kJudgingBytesPerZone = 1024;
constexpr std::size_t kJudgingCopiesOfPayload = 3;
constexpr std::size_t kJudgingFixedBytes = 64u << 10;

std::size_t zone_set_bytes_bound(std::size_t vertices, std::size_t zones) {
  return sizeof(ZoneSet) + kSetBytesPerVertex * vertices + kSetBytesPerZone * zones;
}

std::size_t judging_bytes_bound(std::size_t payload_bytes, std::size_t vertices,
                                std::size_t zones) {
  return kJudgingFixedBytes + kJudgingCopiesOfPayload * payload_bytes +
         kJudgingBytesPerVertex * vertices + kJudgingBytesPerZone * zones +
         zone_set_bytes_bound(vertices, zones);
}

std::string_view bundle_outcome_name(BundleOutcome outcome) {
  switch (outcome) {
    case BundleOutcome::kAccepted:
      return "accepted";
    case BundleOutcome::kAlreadyInForce:
      return "already_in_force";
    case BundleOutcome::kRefused:
      return "refused";
  }
  return "unknown";
}

std::string_view bundle_refusal_name(BundleRefusal reason) {
  switch (reason) {
    case BundleRefusal::kNone:
      return "";
    case BundleRefusal::kTooLarge:
      return "too_large";
    case BundleRefusal::kMalformed:
      return "malformed";
    case BundleRefusal::kUnknownKey:
      return "unknown_key";
    case BundleRefusal::kBadSignature:
      return "signature_invalid";
    case BundleRefusal::kNotNewer:
      return "not_newer";
    case BundleRefusal::kVersionConflict:
      return "version_conflict";
    case BundleRefusal::kInvalidZones:
      return "invalid_zones";
    case BundleRefusal::kWrongVehicle:
      return "wrong_vehicle";
    case BundleRefusal::kDelegationInvalid:
      return "delegation_invalid";
    case BundleRefusal::kRevoked:
      return "revoked";
    case BundleRefusal::kOutOfScope:
      return "out_of_scope";
    case BundleRefusal::kClockUnsynchronised:
      return "clock_unsynchronised";
    case BundleRefusal::kDelegationNotYetValid:
      return "delegation_not_yet_valid";
    case BundleRefusal::kDelegationExpired:
      return "delegation_expired";
  }
  return "unknown";
}

ZoneAuthority::ZoneAuthority(const std::map<std::string, std::string>& trusted_keys,
                             BundleLimits limits, std::string vehicle_id)
    : limits_(limits), vehicle_id_(std::move(vehicle_id)) {
  for (const auto& [id, text] : trusted_keys) {
    auto key = command::Ed25519PublicKey::from_base64(text);
    if (id.empty() || !key) {
      throw std::invalid_argument("command.trusted_keys." + id +
                                  ": not a base64 raw Ed25519 public key (32 bytes)");
    }
    keys_.emplace(id, std::move(*key));
  }
}

BundleVerdict ZoneAuthority::offer(std::string_view payload, BundleTopic topic) {
  return offer(std::span(reinterpret_cast<const std::uint8_t*>(payload.data()), payload.size()),
               topic);
}

BundleVerdict ZoneAuthority::offer(std::span<const std::uint8_t> payload, BundleTopic topic) {
  if (payload.size() > limits_.max_payload_bytes) {
    return refused(BundleRefusal::kTooLarge,
                   "payload of " + std::to_string(payload.size()) + " bytes exceeds " +
                       std::to_string(limits_.max_payload_bytes),
                   0, in_force_);
  }
  v1::SignedZoneBundle signed_bundle;
  if (!signed_bundle.ParseFromArray(payload.data(), static_cast<int>(payload.size()))) {
    return refused(BundleRefusal::kMalformed, "not a fleetgw.v1.SignedZoneBundle", 0, in_force_);
  }
  if (signed_bundle.bundle().empty()) {
    return refused(BundleRefusal::kMalformed, "empty bundle", 0, in_force_);
  }
  if (signed_bundle.signature().empty()) {
    return refused(BundleRefusal::kMalformed, "no signature", 0, in_force_);
  }
  if (signed_bundle.key_id().empty()) {
    return refused(BundleRefusal::kMalformed, "no key id", 0, in_force_);
  }
  const auto* msg = reinterpret_cast<const std::uint8_t*>(signed_bundle.bundle().data());
  const auto* sig = reinterpret_cast<const std::uint8_t*>(signed_bundle.signature().data());
  // Issue 28: a trusted key, or a delegated one judged like a command's (docs/commands.md
  // "Delegations"), by the helper the campaigns share (gateway/command/document_signer.h).
  const auto signer = command::judge_document_signer(
      keys_, signed_bundle.key_id(),
      signed_bundle.has_delegation() ? &signed_bundle.delegation() : nullptr, delegated_check_,
      {msg, signed_bundle.bundle().size()}, {sig, signed_bundle.signature().size()});
  switch (signer.outcome) {
    case command::SignerOutcome::kTrusted:
    case command::SignerOutcome::kDelegated:
      break;
    case command::SignerOutcome::kDelegatedSignatureInvalid:
      return refused(BundleRefusal::kBadSignature,
                     "Ed25519 signature does not verify with delegated key " +
                         quote_zone_text(signed_bundle.key_id()),
                     0, in_force_);
    case command::SignerOutcome::kDelegationRefused: {
      static constexpr BundleRefusal kByReason[] = {BundleRefusal::kDelegationInvalid,
                                                    BundleRefusal::kRevoked,
                                                    BundleRefusal::kOutOfScope,
                                                    BundleRefusal::kClockUnsynchronised,
                                                    BundleRefusal::kDelegationNotYetValid,
                                                    BundleRefusal::kDelegationExpired};
      return refused(command::delegation_refusal_as(signer.problem->reason, kByReason),
                     signer.problem->detail, 0, in_force_);
    }
    case command::SignerOutcome::kUnknownKey:
      return refused(BundleRefusal::kUnknownKey,
                     "key id " + quote_zone_text(signed_bundle.key_id()) + " is not trusted", 0,
                     in_force_);
    case command::SignerOutcome::kSignatureInvalid:
      return refused(
          BundleRefusal::kBadSignature,
          "Ed25519 signature does not verify with key " + quote_zone_text(signed_bundle.key_id()),
          0, in_force_);
  }
  // Authentic from here on.
  v1::ZoneBundle bundle;
  if (!bundle.ParseFromString(signed_bundle.bundle())) {
    return refused(BundleRefusal::kMalformed, "bundle bytes are not a fleetgw.v1.ZoneBundle", 0,
                   in_force_);
  }
  const std::uint64_t version = bundle.version();
  // Who the bundle is for, before its version counts: a bundle for another bike (or an unnamed
  // one replayed on this bike's own topic) must not even refuse the next one as not_newer.
  if (auto wrong = wrong_vehicle(bundle.vehicle_id(), topic)) {
    return refused(BundleRefusal::kWrongVehicle, std::move(*wrong), version, in_force_);
  }
  std::string digest = command::sha256(signed_bundle.bundle());
  if (in_force_) {
    const std::uint64_t current = in_force_->zones->version;
    if (version == current && digest == in_force_->bundle_sha256) {
      BundleVerdict v;
      v.outcome = BundleOutcome::kAlreadyInForce;
      v.detail = "version " + std::to_string(version) + " is already in force";
      v.version = v.in_force = version;
      return v;
    }
    if (version == current) {
      return refused(BundleRefusal::kVersionConflict,
                     "version " + std::to_string(version) +
                         " is in force with different content; a change needs a new version",
                     version, in_force_);
    }
    if (version < current) {
      return refused(BundleRefusal::kNotNewer,
                     "version " + std::to_string(version) + " is older than version " +
                         std::to_string(current) + " in force",
                     version, in_force_);
    }
  }
  auto compiled = compile_zones(bundle, limits_);
  if (auto* error = std::get_if<std::string>(&compiled)) {
    return refused(BundleRefusal::kInvalidZones, std::move(*error), version, in_force_);
  }
  in_force_ = BundleInForce{
      std::string(reinterpret_cast<const char*>(payload.data()), payload.size()), std::move(digest),
      signed_bundle.key_id(),
      std::make_shared<const ZoneSet>(std::move(std::get<ZoneSet>(compiled))), bundle.vehicle_id()};
  BundleVerdict v;
  v.outcome = BundleOutcome::kAccepted;
  v.detail = "version " + std::to_string(version) +
             " in force: " + std::to_string(in_force_->zones->zones.size()) + " zones, " +
             std::to_string(in_force_->zones->vertices) + " vertices";
  if (!bundle.vehicle_id().empty()) v.detail += ", for vehicle '" + bundle.vehicle_id() + "'";
  v.version = v.in_force = version;
  return v;
}

std::optional<std::string> ZoneAuthority::wrong_vehicle(std::string_view named,
                                                        BundleTopic topic) const {
  if (named.empty()) {
    if (topic != BundleTopic::kVehicle) return std::nullopt;  // fleet-wide, on the fleet topic
    return "the bundle names no vehicle; on " + std::string(bundle_topic_name(topic)) +
           " only a bundle signed for '" + vehicle_id_ + "' is accepted (zones sign --vehicle " +
           vehicle_id_ + ")";
  }
  if (vehicle_id_.empty() || named == vehicle_id_) return std::nullopt;
  return "signed for vehicle " + quote_zone_text(named) + ", received on " +
         std::string(bundle_topic_name(topic)) + " of '" + vehicle_id_ + "'";
}

std::string sign_zone_bundle(const v1::ZoneBundle& bundle, const command::Ed25519PrivateKey& key,
                             std::string_view key_id) {
  v1::SignedZoneBundle s;
  // Serialized once: the signature covers exactly the bytes that travel.
  s.set_bundle(bundle.SerializeAsString());
  const auto* bytes = reinterpret_cast<const std::uint8_t*>(s.bundle().data());
  const auto sig = key.sign({bytes, s.bundle().size()});
  s.set_signature(std::string(sig.begin(), sig.end()));
  s.set_key_id(std::string(key_id));
  return s.SerializeAsString();
}

}  // namespace fleetgw::geofence
