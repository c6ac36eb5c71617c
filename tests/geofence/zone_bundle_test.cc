// Zone bundles: signed with the commands' trusted keys, versioned, validated with a reason that
// names the zone, ring and vertex; what is in force survives a refused offer and a restart.
#include "gateway/geofence/zone_bundle.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <functional>
#include <map>
#include <random>

#include "fleetgw/v1/zones.pb.h"
#include "gateway/geofence/zone_file.h"
#include "tests/geofence/zone_test_util.h"
#include "tests/support/temp_dir.h"

namespace fleetgw::geofence {
namespace {

using namespace testing;

constexpr std::int64_t kIssuedUs = 1'790'000'000'000'000;

class ZoneBundles : public ::testing::Test {
 protected:
  command::Ed25519PrivateKey key = command::Ed25519PrivateKey::generate();
  command::Ed25519PrivateKey stranger = command::Ed25519PrivateKey::generate();
  std::map<std::string, std::string> trusted{{"ops-1", key.public_key().base64()}};

  static v1::ZoneBundle bundle(std::uint64_t version, std::uint32_t limit = 15) {
    v1::ZoneBundle b;
    b.set_version(version);
    b.set_issued_at_us(kIssuedUs);
    add_zone(b, "city", v1::ZONE_KIND_OPERATING_AREA, {rect(-3000, -3000, 3000, 3000)});
    add_zone(b, "old-town", v1::ZONE_KIND_SLOW,
             {rect(-500, -500, 500, 500), rect(-100, -100, 100, 100)}, limit);
    add_zone(b, "park", v1::ZONE_KIND_NO_RIDE, {wiggly_ring(64, 300, 20, 1500, 0)});
    add_zone(b, "station", v1::ZONE_KIND_NO_PARKING, {rect(2000, 2000, 2100, 2100)});
    return b;
  }
  std::string signed_bundle(const v1::ZoneBundle& b) const {
    return sign_zone_bundle(b, key, "ops-1");
  }
  // The refusal of a bundle with one defect, from a fresh authority.
  BundleVerdict offer_fresh(const v1::ZoneBundle& b) const {
    ZoneAuthority authority(trusted);
    return authority.offer(signed_bundle(b));
  }
};

TEST_F(ZoneBundles, ASignedBundleIsAcceptedAndCompiled) {
  ZoneAuthority authority(trusted);
  const auto v = authority.offer(signed_bundle(bundle(3)));
  EXPECT_EQ(v.outcome, BundleOutcome::kAccepted) << v.detail;
  EXPECT_EQ(v.in_force, 3u);
  ASSERT_TRUE(authority.in_force());
  const auto& zones = *authority.in_force()->zones;
  EXPECT_EQ(zones.version, 3u);
  ASSERT_EQ(zones.zones.size(), 4u);
  EXPECT_EQ(zones.zones[1].kind, ZoneKind::kSlow);
  EXPECT_EQ(zones.zones[1].speed_limit_kmh, 15);
  EXPECT_EQ(zones.vertices, 4u + 8u + 64u + 4u);
  EXPECT_EQ(authority.in_force()->key_id, "ops-1");
  // The hole of the old town is not in it.
  EXPECT_FALSE(zones.zones[1].shape.contains(lat_at(0), lon_at(0)));
  EXPECT_TRUE(zones.zones[1].shape.contains(lat_at(300), lon_at(0)));
}

TEST_F(ZoneBundles, ABadSignatureIsRefusedAndTheBundleInForceStays) {
  ZoneAuthority authority(trusted);
  ASSERT_TRUE(authority.offer(signed_bundle(bundle(3))).accepted());
  // Version 4, one bit of the signed bytes flipped after signing.
  v1::SignedZoneBundle forged;
  ASSERT_TRUE(forged.ParseFromString(signed_bundle(bundle(4, 5))));
  std::string bytes = forged.bundle();
  bytes[bytes.size() / 2] ^= 0x01;
  forged.set_bundle(bytes);
  auto v = authority.offer(forged.SerializeAsString());
  EXPECT_EQ(v.outcome, BundleOutcome::kRefused);
  EXPECT_EQ(v.reason, BundleRefusal::kBadSignature);
  EXPECT_EQ(bundle_refusal_name(v.reason), "signature_invalid");
  EXPECT_NE(v.detail.find("ops-1"), std::string::npos) << v.detail;
  // Signed by a key that is not trusted under a trusted id: the same.
  v = authority.offer(sign_zone_bundle(bundle(4, 5), stranger, "ops-1"));
  EXPECT_EQ(v.reason, BundleRefusal::kBadSignature);
  v = authority.offer(sign_zone_bundle(bundle(4, 5), stranger, "intruder\n"));
  EXPECT_EQ(v.reason, BundleRefusal::kUnknownKey);
  EXPECT_NE(v.detail.find("'intruder\\n'"), std::string::npos) << v.detail;  // escaped
  // Still version 3, with its 15 km/h.
  EXPECT_EQ(v.in_force, 3u);
  EXPECT_EQ(authority.in_force()->zones->version, 3u);
  EXPECT_EQ(authority.in_force()->zones->zones[1].speed_limit_kmh, 15);
}

TEST_F(ZoneBundles, AnOlderOrConflictingVersionIsRefusedTheSameOneIsAlreadyInForce) {
  ZoneAuthority authority(trusted);
  const std::string v5 = signed_bundle(bundle(5));
  ASSERT_TRUE(authority.offer(v5).accepted());
  auto v = authority.offer(signed_bundle(bundle(4, 10)));
  EXPECT_EQ(v.reason, BundleRefusal::kNotNewer);
  EXPECT_EQ(v.detail, "version 4 is older than version 5 in force");
  v = authority.offer(signed_bundle(bundle(5, 10)));
  EXPECT_EQ(v.reason, BundleRefusal::kVersionConflict);
  // The retained message again on reconnect: no error, nothing changes.
  v = authority.offer(v5);
  EXPECT_EQ(v.outcome, BundleOutcome::kAlreadyInForce);
  EXPECT_EQ(authority.in_force()->zones->zones[1].speed_limit_kmh, 15);
  v = authority.offer(signed_bundle(bundle(6, 10)));
  EXPECT_TRUE(v.accepted()) << v.detail;
  EXPECT_EQ(authority.in_force()->zones->zones[1].speed_limit_kmh, 10);
}

TEST_F(ZoneBundles, MalformedPolygonsAreRefusedNamingZoneRingAndVertex) {
  struct Case {
    std::string name;
    std::function<void(v1::ZoneBundle&)> edit;
    std::string expected;
  };
  const std::vector<Case> cases{
      {"two vertices",
       [](v1::ZoneBundle& b) {
         auto* r = b.mutable_zones(2)->mutable_rings(0);
         r->mutable_lat_e7()->Truncate(2);
         r->mutable_lon_e7()->Truncate(2);
       },
       "zone 2 ('park'), ring 0: 2 distinct vertices (at least 3 needed)"},
      {"a triangle repeating a vertex",
       [](v1::ZoneBundle& b) {
         auto* r = b.mutable_zones(3)->mutable_rings(0);
         r->set_lat_e7(2, r->lat_e7(0));
         r->set_lon_e7(2, r->lon_e7(0));
         r->mutable_lat_e7()->Truncate(3);
         r->mutable_lon_e7()->Truncate(3);
       },
       "zone 3 ('station'), ring 0: 2 distinct vertices (at least 3 needed)"},
      {"two distinct vertices repeated (A-B-A-B)",
       [](v1::ZoneBundle& b) {
         *b.mutable_zones(2)->mutable_rings(0) =
             to_proto({vertex_at(0, 0), vertex_at(100, 0), vertex_at(0, 0), vertex_at(100, 0)});
       },
       "zone 2 ('park'), ring 0: 2 distinct vertices (at least 3 needed)"},
      {"every vertex on one line",
       [](v1::ZoneBundle& b) {
         *b.mutable_zones(3)->mutable_rings(0) = to_proto(
             {vertex_at(0, 0), vertex_at(100, 100), vertex_at(300, 300), vertex_at(200, 200)});
       },
       "zone 3 ('station'), ring 0: all 4 vertices lie on one line (within 0.1 m: the ring "
       "encloses no area)"},
      {"a ring that doubles back on itself (A-B-C-B): three distinct vertices, no inside",
       [](v1::ZoneBundle& b) {
         *b.mutable_zones(3)->mutable_rings(0) =
             to_proto({vertex_at(0, 0), vertex_at(100, 0), vertex_at(100, 100), vertex_at(100, 0)});
       },
       "zone 3 ('station'), ring 0: doubles back on itself: every edge is traced twice, so it "
       "encloses nothing"},
      {"a longer ring retracing its way back (A-B-C-D-C-B)",
       [](v1::ZoneBundle& b) {
         *b.mutable_zones(3)->mutable_rings(0) =
             to_proto({vertex_at(0, 0), vertex_at(100, 0), vertex_at(100, 100), vertex_at(0, 100),
                       vertex_at(100, 100), vertex_at(100, 0)});
       },
       "zone 3 ('station'), ring 0: doubles back on itself: every edge is traced twice, so it "
       "encloses nothing"},
      {"a vehicle id that is not an id", [](v1::ZoneBundle& b) { b.set_vehicle_id("bike 7"); },
       "vehicle_id 'bike 7' must be 1..64 characters of [A-Za-z0-9._-] (or empty: fleet-wide)"},
      {"latitude out of range",
       [](v1::ZoneBundle& b) { b.mutable_zones(1)->mutable_rings(1)->set_lat_e7(2, 900'000'001); },
       "zone 1 ('old-town'), ring 1: vertex 2: latitude 900000001e-7 is outside -90..90 degrees"},
      {"longitude out of range",
       [](v1::ZoneBundle& b) {
         b.mutable_zones(0)->mutable_rings(0)->set_lon_e7(0, -1'800'000'001);
       },
       "zone 0 ('city'), ring 0: vertex 0: longitude -1800000001e-7 is outside -180..180 degrees"},
      {"lengths differ",
       [](v1::ZoneBundle& b) { b.mutable_zones(0)->mutable_rings(0)->add_lat_e7(1); },
       "zone 0 ('city'), ring 0: 5 latitudes but 4 longitudes"},
      {"across the antimeridian",
       [](v1::ZoneBundle& b) {
         auto* r = b.mutable_zones(0)->mutable_rings(0);
         r->set_lon_e7(0, -1'790'000'000);
         r->set_lon_e7(1, 1'790'000'000);
       },
       "zone 0 ('city'), ring 0: spans more than 180 degrees of longitude (zones across the "
       "antimeridian are not supported)"},
      {"no ring", [](v1::ZoneBundle& b) { b.mutable_zones(3)->clear_rings(); },
       "zone 3 ('station'): no ring"},
      {"repeated id", [](v1::ZoneBundle& b) { b.mutable_zones(3)->set_id("park"); },
       "zone 3 ('park'): id repeated"},
      {"bad id", [](v1::ZoneBundle& b) { b.mutable_zones(0)->set_id("a b"); },
       "zone 0 ('a b'): id must be 1..64 characters of [A-Za-z0-9._-]"},
      {"unknown kind",
       [](v1::ZoneBundle& b) { b.mutable_zones(0)->set_kind(static_cast<v1::ZoneKind>(9)); },
       "zone 0 ('city'): unknown kind 9"},
      {"slow without a limit",
       [](v1::ZoneBundle& b) { b.mutable_zones(1)->set_speed_limit_kmh(0); },
       "zone 1 ('old-town'): a slow zone needs speed_limit_kmh in 1..255, not 0"},
      {"limit on a no-ride zone",
       [](v1::ZoneBundle& b) { b.mutable_zones(2)->set_speed_limit_kmh(5); },
       "zone 2 ('park'): speed_limit_kmh is only for slow zones"},
      {"name too long",
       [](v1::ZoneBundle& b) { b.mutable_zones(2)->set_name(std::string(129, 'n')); },
       "zone 2 ('park'): name must be at most 128 bytes of UTF-8"},
      {"version 0", [](v1::ZoneBundle& b) { b.set_version(0); }, "version 0 (versions start at 1)"},
  };
  for (const auto& c : cases) {
    auto b = bundle(2);
    c.edit(b);
    const auto v = offer_fresh(b);
    EXPECT_EQ(v.reason, BundleRefusal::kInvalidZones) << c.name;
    EXPECT_EQ(v.detail, c.expected) << c.name;
    EXPECT_EQ(v.in_force, 0u) << c.name;
  }
  // A name that is not UTF-8 does not even parse (a proto3 string): malformed.
  auto bad_name = bundle(2);
  bad_name.mutable_zones(2)->set_name("\xff\xfe");
  EXPECT_EQ(offer_fresh(bad_name).reason, BundleRefusal::kMalformed);
  // A closing vertex equal to the first and a self-intersecting ring are fine.
  auto b = bundle(2);
  auto* r = b.mutable_zones(3)->mutable_rings(0);
  r->add_lat_e7(r->lat_e7(0));
  r->add_lon_e7(r->lon_e7(0));
  *b.mutable_zones(2)->mutable_rings(0) =
      to_proto({vertex_at(0, 0), vertex_at(100, 100), vertex_at(100, 0), vertex_at(0, 100)});
  EXPECT_TRUE(offer_fresh(b).accepted());
  // A sliver 0.5 m wide is a zone (drawn on purpose along a kerb, say).
  *b.mutable_zones(3)->mutable_rings(0) =
      to_proto({vertex_at(0, 0), vertex_at(100, 0), vertex_at(100, 0.5)});
  EXPECT_TRUE(offer_fresh(b).accepted());
}

TEST_F(ZoneBundles, TooManyVerticesOrBytesAreRefusedBeforeBuildingAnything) {
  BundleLimits limits;
  limits.max_vertices = 50;
  ZoneAuthority small(trusted, limits);
  auto v = small.offer(signed_bundle(bundle(1)));
  EXPECT_EQ(v.reason, BundleRefusal::kInvalidZones);
  EXPECT_EQ(v.detail, "80 vertices, at most 50");
  limits = BundleLimits{};
  limits.max_payload_bytes = 100;
  ZoneAuthority tiny(trusted, limits);
  v = tiny.offer(signed_bundle(bundle(1)));
  EXPECT_EQ(v.reason, BundleRefusal::kTooLarge);
}

TEST_F(ZoneBundles, GarbageNeverCrashesAndIsMalformed) {
  ZoneAuthority authority(trusted);
  ASSERT_TRUE(authority.offer(signed_bundle(bundle(1))).accepted());
  const std::string good = signed_bundle(bundle(2));
  std::mt19937 rng(5);
  for (int i = 0; i < 2000; ++i) {
    std::string bytes = good.substr(0, rng() % good.size());  // truncated
    if (i % 2 == 1) {
      bytes = good;
      for (int k = 0; k < 4; ++k) bytes[rng() % bytes.size()] = static_cast<char>(rng());
    }
    const auto v = authority.offer(bytes);
    EXPECT_NE(v.outcome, BundleOutcome::kAccepted) << i;
    EXPECT_FALSE(v.detail.empty());
  }
  EXPECT_EQ(authority.offer(std::string_view("")).reason, BundleRefusal::kMalformed);
  EXPECT_EQ(authority.in_force()->zones->version, 1u);
}

TEST_F(ZoneBundles, TheBundleInForceSurvivesARestartAndATamperedFileIsRefused) {
  fleetgw::testing::TempDir dir("geofence");
  const auto path = dir / "zones.pb";
  std::string error;
  {
    ZoneAuthority authority(trusted);
    EXPECT_FALSE(restore_zones(authority, path, error));  // no file yet: nothing, no error
    EXPECT_EQ(error, "");
    ASSERT_TRUE(authority.offer(signed_bundle(bundle(7))).accepted());
    ASSERT_TRUE(write_zone_file(path, authority.in_force()->payload, error)) << error;
  }
  // Only the file is left in the directory: the temporary one was renamed over it.
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir.path()),
                          std::filesystem::directory_iterator()),
            1);
  {
    ZoneAuthority restarted(trusted);
    const auto v = restore_zones(restarted, path, error);
    ASSERT_TRUE(v) << error;
    EXPECT_TRUE(v->accepted()) << v->detail;
    EXPECT_EQ(restarted.in_force()->zones->version, 7u);
    // And it keeps refusing what is older.
    EXPECT_EQ(restarted.offer(signed_bundle(bundle(6))).reason, BundleRefusal::kNotNewer);
  }
  {
    // A file changed on disk fails its signature like any forged payload.
    auto bytes = read_zone_file(path, error);
    ASSERT_TRUE(bytes);
    (*bytes)[bytes->size() / 3] ^= 0x20;
    ASSERT_TRUE(write_zone_file(path, *bytes, error)) << error;
    ZoneAuthority restarted(trusted);
    const auto v = restore_zones(restarted, path, error);
    ASSERT_TRUE(v);
    EXPECT_FALSE(v->accepted());
    EXPECT_FALSE(restarted.in_force());
  }
  // Unwritable place: an error naming it, no exception.
  EXPECT_FALSE(write_zone_file(dir / "missing" / "zones.pb", "x", error));
  EXPECT_NE(error.find("missing"), std::string::npos) << error;
  EXPECT_FALSE(read_zone_file(dir.path(), error));  // a directory
  EXPECT_NE(error.find("not a regular file"), std::string::npos) << error;
}

// A bundle signed for one bike, replayed on another bike's own topic (or on the fleet topic):
// refused as wrong_vehicle, whatever its version, and what is in force stays. An unnamed
// (fleet-wide) bundle is accepted on the fleet topic only.
TEST_F(ZoneBundles, ABundleSignedForAnotherVehicleIsRefusedOnEveryTopic) {
  ZoneAuthority bike7(trusted, {}, "bike-7");
  auto for_bike7 = bundle(4);
  for_bike7.set_vehicle_id("bike-7");
  auto for_bike8 = bundle(5);
  for_bike8.set_vehicle_id("bike-8");

  auto v = bike7.offer(signed_bundle(for_bike7), BundleTopic::kVehicle);
  ASSERT_TRUE(v.accepted()) << v.detail;
  EXPECT_EQ(v.detail, "version 4 in force: 4 zones, 80 vertices, for vehicle 'bike-7'");
  EXPECT_EQ(bike7.in_force()->vehicle_id, "bike-7");

  v = bike7.offer(signed_bundle(for_bike8), BundleTopic::kVehicle);
  EXPECT_EQ(v.reason, BundleRefusal::kWrongVehicle);
  EXPECT_EQ(bundle_refusal_name(v.reason), "wrong_vehicle");
  EXPECT_EQ(v.detail,
            "signed for vehicle 'bike-8', received on the vehicle's own topic of 'bike-7'");
  EXPECT_EQ(v.in_force, 4u);
  v = bike7.offer(signed_bundle(for_bike8), BundleTopic::kFleet);
  EXPECT_EQ(v.reason, BundleRefusal::kWrongVehicle);
  EXPECT_EQ(v.detail, "signed for vehicle 'bike-8', received on the fleet topic of 'bike-7'");

  // A fleet-wide bundle (no vehicle) on the vehicle's own topic: refused, it could be any
  // bike's; on the fleet topic: accepted.
  v = bike7.offer(signed_bundle(bundle(6)), BundleTopic::kVehicle);
  EXPECT_EQ(v.reason, BundleRefusal::kWrongVehicle);
  EXPECT_EQ(v.detail,
            "the bundle names no vehicle; on the vehicle's own topic only a bundle signed for "
            "'bike-7' is accepted (zones sign --vehicle bike-7)");
  EXPECT_EQ(bike7.in_force()->zones->version, 4u);
  EXPECT_TRUE(bike7.offer(signed_bundle(bundle(6)), BundleTopic::kFleet).accepted());

  // The stored file of another bike, copied over: refused at start-up.
  ZoneAuthority other(trusted, {}, "bike-9");
  EXPECT_EQ(other.offer(signed_bundle(for_bike7)).reason, BundleRefusal::kWrongVehicle);
  // An operator's check with no vehicle given accepts a named bundle and says whose it is.
  ZoneAuthority check(trusted);
  EXPECT_TRUE(check.offer(signed_bundle(for_bike8)).accepted());
}

// The largest bundle a gateway accepts, in the worst shape (100,000 vertices zig-zagging across
// the zone's whole height): accepted, and the zones kept in force stay within the documented
// bound (issue 24: 1.6 GB before).
TEST_F(ZoneBundles, TheLargestZigZagBundleIsKeptWithinItsMemoryBound) {
  v1::ZoneBundle b;
  b.set_version(1);
  b.set_issued_at_us(kIssuedUs);
  add_zone(b, "zig-zag", v1::ZONE_KIND_SLOW, {zig_zag(100'000, 3000)}, 12);
  const std::string payload = signed_bundle(b);
  ZoneAuthority authority(trusted);
  const auto v = authority.offer(payload);
  ASSERT_TRUE(v.accepted()) << v.detail;
  const auto& set = *authority.in_force()->zones;
  ASSERT_EQ(set.vertices, 100'000u);
  std::size_t bytes = 0;
  for (const auto& z : set.zones) {
    bytes += z.shape.memory_bytes();
    EXPECT_LE(z.shape.index_entries(), 16 * z.shape.vertex_count() + z.shape.band_count());
  }
  EXPECT_LE(bytes, zone_set_bytes_bound(set.vertices, set.zones.size()));
  EXPECT_LE(bytes, 9'000'000u);  // docs/location.md: 84 bytes per vertex
  EXPECT_EQ(set.zones[0].shape.locate(lat_at(-5), lon_at(1000), 1), Where::kInside);
  EXPECT_EQ(set.zones[0].shape.locate(lat_at(-20), lon_at(1000), 1), Where::kOutside);
}

TEST(ZoneBundleKeys, AnUntrustableKeyInTheConfigurationIsNamed) {
  try {
    const std::map<std::string, std::string> keys{{"ops-2", "not base64"}};
    ZoneAuthority a(keys);
    FAIL() << "accepted a bad key";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("ops-2"), std::string::npos);
  }
}

}  // namespace
}  // namespace fleetgw::geofence
