// Geofence benchmarks (Google Benchmark; issue 14: point-in-zone with >= 10,000 polygon
// vertices in the bundle, target < 1 ms per fix on one core):
//  - BM_EngineStep/<vertices>: ZoneEngine::step() for one fix against a whole bundle: a city
//    operating area with a wiggly boundary of half the vertices, the other half in 100 slow,
//    no-ride and no-parking zones of 50 vertices scattered in it; fixes along a random walk
//    through the city. THE figure: time per fix (items_per_second = fixes per second).
//  - BM_LocateOneZone/<vertices>/<shape>: ZonePolygon::locate() (band index) on one zone of that
//    many vertices, uniform fixes over its bounding box, margin 10 m; shape 0 a smooth city
//    boundary, shape 1 a "hedgehog" (every vertex +-300 m at random: edges spanning many
//    bands, the index's worst case).
//  - BM_LinearScan/<vertices>: (smooth shape) the same question answered by scanning every edge
//  (what the band
//    index saves).
//  - BM_OfferBundle/<vertices>: ZoneAuthority::offer() of the signed bundle: parse, Ed25519
//    verification, validation and index building -- the cost of a new bundle, paid once.
// Shapes are laid out in metres around Berlin (tests/geofence/zone_test_util.h).
#include <benchmark/benchmark.h>

#include <random>

#include "fleetgw/v1/zones.pb.h"
#include "gateway/geofence/zone_bundle.h"
#include "tests/geofence/zone_test_util.h"

using namespace fleetgw::geofence;
using namespace fleetgw::geofence::testing;

namespace {

constexpr int kSmallZones = 100;
constexpr int kSmallZoneVertices = 50;

// The bundle of BM_EngineStep: `vertices` in all.
fleetgw::v1::ZoneBundle city_bundle(std::size_t vertices) {
  fleetgw::v1::ZoneBundle b;
  b.set_version(1);
  b.set_issued_at_us(1'790'000'000'000'000);
  const std::size_t area = vertices - kSmallZones * kSmallZoneVertices;
  add_zone(b, "city", fleetgw::v1::ZONE_KIND_OPERATING_AREA, {smooth_ring(area, 6000, 300)});
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> where(-4000, 4000);
  for (int i = 0; i < kSmallZones; ++i) {
    const auto kind = i % 3 == 0   ? fleetgw::v1::ZONE_KIND_SLOW
                      : i % 3 == 1 ? fleetgw::v1::ZONE_KIND_NO_RIDE
                                   : fleetgw::v1::ZONE_KIND_NO_PARKING;
    add_zone(b, "z" + std::to_string(i), kind,
             {smooth_ring(kSmallZoneVertices, 250, 30, where(rng), where(rng), i + 2u)},
             kind == fleetgw::v1::ZONE_KIND_SLOW ? 12 : 0);
  }
  return b;
}

std::shared_ptr<const ZoneSet> compiled(const fleetgw::v1::ZoneBundle& b) {
  auto set = compile_zones(b);
  if (auto* error = std::get_if<std::string>(&set)) throw std::runtime_error(*error);
  return std::make_shared<const ZoneSet>(std::move(std::get<ZoneSet>(set)));
}

void BM_EngineStep(benchmark::State& state) {
  const auto vertices = static_cast<std::size_t>(state.range(0));
  auto zones = compiled(city_bundle(vertices));
  ZoneEngine engine;
  std::vector<ZoneEvent> events;
  engine.set_zones(zones, Micros(0), events);
  // A random walk at riding speed, 1 fix per second of virtual time.
  std::mt19937 rng(2);
  std::normal_distribution<double> step(0, 5);
  std::vector<fleetgw::gnss::Fix> track;
  double x = 0, y = 0;
  for (int i = 0; i < 100'000; ++i) {
    x = std::clamp(x + step(rng), -6500.0, 6500.0);
    y = std::clamp(y + step(rng), -6500.0, 6500.0);
    track.push_back(fix_at(x, y, std::chrono::seconds(i)));
  }
  std::size_t i = 0;
  std::size_t transitions = 0;
  for (auto _ : state) {
    const auto& fix = track[i % track.size()];
    const Micros now = std::chrono::seconds(static_cast<std::int64_t>(i));
    benchmark::DoNotOptimize(engine.step(now, &fix, events));
    transitions += events.size();
    events.clear();
    ++i;
  }
  state.SetItemsProcessed(state.iterations());
  state.counters["vertices"] = static_cast<double>(zones->vertices);
  state.counters["zones"] = static_cast<double>(zones->zones.size());
  state.counters["transitions"] = static_cast<double>(transitions);
}
BENCHMARK(BM_EngineStep)->Arg(10'000)->Arg(50'000)->Arg(100'000);

ZonePolygon one_zone(std::size_t vertices, bool hedgehog = false) {
  const std::vector<Ring> rings{hedgehog ? wiggly_ring(vertices, 6000, 300)
                                         : smooth_ring(vertices, 6000, 300)};
  return ZonePolygon::build(rings);
}

std::vector<std::pair<double, double>> uniform_fixes() {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> coord(-6500, 6500);
  std::vector<std::pair<double, double>> fixes;
  for (int i = 0; i < 65'536; ++i) fixes.emplace_back(lat_at(coord(rng)), lon_at(coord(rng)));
  return fixes;
}

void BM_LocateOneZone(benchmark::State& state) {
  const auto zone = one_zone(static_cast<std::size_t>(state.range(0)), state.range(1) == 1);
  const auto fixes = uniform_fixes();
  std::size_t i = 0;
  for (auto _ : state) {
    const auto& [lat, lon] = fixes[i++ & 0xffff];
    benchmark::DoNotOptimize(zone.locate(lat, lon, 10.0));
  }
  state.SetItemsProcessed(state.iterations());
  state.counters["bands"] = static_cast<double>(zone.band_count());
  state.counters["index_entries"] = static_cast<double>(zone.index_entries());
}
BENCHMARK(BM_LocateOneZone)->ArgsProduct({{10'000, 100'000}, {0, 1}});

void BM_LinearScan(benchmark::State& state) {
  const auto zone = one_zone(static_cast<std::size_t>(state.range(0)));
  const auto fixes = uniform_fixes();
  std::size_t i = 0;
  for (auto _ : state) {
    const auto& [lat, lon] = fixes[i++ & 0xffff];
    benchmark::DoNotOptimize(zone.distance_to_boundary_m(lat, lon));
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_LinearScan)->Arg(10'000);

void BM_OfferBundle(benchmark::State& state) {
  const auto key = fleetgw::command::Ed25519PrivateKey::generate();
  const std::map<std::string, std::string> trusted{{"ops", key.public_key().base64()}};
  const std::string payload =
      sign_zone_bundle(city_bundle(static_cast<std::size_t>(state.range(0))), key, "ops");
  for (auto _ : state) {
    ZoneAuthority authority(trusted);
    const auto verdict = authority.offer(payload);
    if (!verdict.accepted()) state.SkipWithError(verdict.detail.c_str());
  }
  state.counters["payload_bytes"] = static_cast<double>(payload.size());
}
BENCHMARK(BM_OfferBundle)->Arg(10'000)->Arg(100'000)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
