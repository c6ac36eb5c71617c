// ZoneController: the geofence parts composed as the runtime will drive them -- the bundle in
// force (ZoneAuthority) and its file, the engine, the enforcer. The runtime's wiring is then four
// calls: restore() at start-up, on_bundle() for each payload of the zones topic, on_position()
// for each position change from gnss::GnssFeed, tick() whenever it wakes (with what it knows of
// the MC) -- plus on_write_result() from the MC action's Done callback. No clock, no bus, no
// uplink; the only I/O is the bundle file (zone_file.h).
//
// Contract:
//  * restore(): the stored bundle offered like any payload (a tampered or no-longer-trusted file
//    is refused, with its verdict); nullopt when there is no file or it cannot be read (`error`).
//  * on_bundle(): an accepted bundle is written to the file FIRST (atomically), then put in
//    force; a failed write is reported in `persist_error` but the bundle is enforced all the
//    same (the bike obeys the newest zones; it would fall back to the stored ones after a
//    restart). A refusal changes nothing. Zones removed by a new bundle end with exit events.
//  * on_bundle(payload, ..., topic): `topic` says whether the payload came on the fleet topic or
//    on the vehicle's own one; the authority binds a bundle to `vehicle_id` (zone_bundle.h,
//    wrong_vehicle).
//  * on_bundle(..., fix): with the current fix (a bundle replaced at run time) the new zones are
//    evaluated there at once (ZoneEngine::relocate), so a moved operating area, a new slow or
//    no-ride zone applies without waiting for the next fix and a dwell.
//  * on_oversized(): a payload refused unread (over the uplink's limit) as too_large.
//  * counters(): every offer through on_bundle()/on_oversized() counted, the latest refusal
//    kept (for `fleetgw status`); restore() is not counted (it is not received).
//  * on_position(now, fix): `fix` is the CURRENT position or nullptr when it is unknown or
//    stale; only a real change of position should be passed (a fix counts once towards the
//    dwell). Appends enter/exit events.
//  * tick(now, mc): the MC write to make now (ZoneEnforcer::next on the engine's demands), or
//    nullopt; next_deadline(now) is when tick() should run next for a ramp or a zone's time
//    window (issue 27). tick(now, mc, events) first moves the engine to `now` (a window that
//    opened or closed around the bike: an ENTER or EXIT appended); tick(now, mc) does the same
//    and drops those events (tests of the writes alone).
//  * starting(fix, ride_starting, now): an unlock judged against the no-start zones (issue 27,
//    ZoneEngine::starting).
#pragma once

#include <filesystem>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "gateway/geofence/zone_bundle.h"
#include "gateway/geofence/zone_enforcer.h"
#include "gateway/geofence/zone_engine.h"

namespace fleetgw::geofence {

struct ZoneControllerConfig {
  EngineConfig engine;
  EnforcerConfig enforcer;
  BundleLimits limits;
  std::map<std::string, std::string> trusted_keys;  // [command.trusted_keys]
  ZoneAuthority::DelegatedCheck delegated_check;     // issue 28: bundles of delegated keys
  std::string vehicle_id;             // [vehicle] id: bundles naming another are refused
  std::filesystem::path bundle_file;  // empty: not persisted
};

struct BundleCounters {
  std::uint64_t offered = 0;   // payloads received (oversized included)
  std::uint64_t accepted = 0;  // put in force
  std::uint64_t refused = 0;   // already_in_force is neither accepted nor refused
  std::optional<BundleVerdict> last_refusal;
  Micros last_refusal_at{0};
};

class ZoneController {
 public:
  explicit ZoneController(ZoneControllerConfig config);

  std::optional<BundleVerdict> restore(Micros now, std::string& error,
                                       std::vector<ZoneEvent>& events);
  BundleVerdict on_bundle(std::span<const std::uint8_t> payload, Micros now,
                          std::vector<ZoneEvent>& events, std::string& persist_error,
                          const gnss::Fix* fix = nullptr,
                          BundleTopic topic = BundleTopic::kFleet);
  BundleVerdict on_oversized(std::size_t bytes, std::size_t limit, Micros now);
  const BundleCounters& counters() const { return counters_; }
  void on_position(Micros now, const gnss::Fix* fix, std::vector<ZoneEvent>& events);
  std::optional<McWrite> tick(Micros now, const McView& mc, std::vector<ZoneEvent>& events);
  std::optional<McWrite> tick(Micros now, const McView& mc) {
    std::vector<ZoneEvent> dropped;
    return tick(now, mc, dropped);
  }
  void on_write_result(bool succeeded, Micros now) { enforcer_.on_result(succeeded, now); }
  std::optional<Micros> next_deadline(Micros now) const { return engine_.next_change(now); }

  Demands demands(Micros now) const { return engine_.demands(now); }
  ParkingVerdict parking(const gnss::Fix* fix, bool ride_ending, Micros now) const {
    return engine_.parking(fix, ride_ending, now);
  }
  ParkingVerdict starting(const gnss::Fix* fix, bool ride_starting, Micros now) const {
    return engine_.starting(fix, ride_starting, now);
  }
  const ZoneAuthority& authority() const { return authority_; }

 private:
  ZoneControllerConfig config_;
  ZoneAuthority authority_;
  ZoneEngine engine_;
  ZoneEnforcer enforcer_;
  BundleCounters counters_;

  void count(const BundleVerdict& verdict, Micros now);
};

}  // namespace fleetgw::geofence
