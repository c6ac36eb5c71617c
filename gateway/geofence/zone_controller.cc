#include "gateway/geofence/zone_controller.h"

#include "gateway/geofence/zone_file.h"

namespace fleetgw::geofence {

ZoneController::ZoneController(ZoneControllerConfig config)
    : config_(std::move(config)),
      authority_(config_.trusted_keys, config_.limits),
      engine_(config_.engine),
      enforcer_(config_.enforcer) {}

std::optional<BundleVerdict> ZoneController::restore(Micros now, std::string& error,
                                                     std::vector<ZoneEvent>& events) {
  error.clear();
  if (config_.bundle_file.empty()) return std::nullopt;
  auto verdict = restore_zones(authority_, config_.bundle_file, error);
  if (verdict && verdict->accepted()) engine_.set_zones(authority_.in_force()->zones, now, events);
  return verdict;
}

BundleVerdict ZoneController::on_bundle(std::span<const std::uint8_t> payload, Micros now,
                                        std::vector<ZoneEvent>& events,
                                        std::string& persist_error) {
  persist_error.clear();
  BundleVerdict verdict = authority_.offer(payload);
  if (!verdict.accepted()) return verdict;
  // Stored before it is enforced, so what the bike obeys is what it finds after a restart.
  if (!config_.bundle_file.empty()) {
    write_zone_file(config_.bundle_file, authority_.in_force()->payload, persist_error);
  }
  engine_.set_zones(authority_.in_force()->zones, now, events);
  return verdict;
}

void ZoneController::on_position(Micros now, const gnss::Position* fix,
                                 std::vector<ZoneEvent>& events) {
  engine_.step(now, fix, events);
}

std::optional<McWrite> ZoneController::tick(Micros now, const McView& mc) {
  return enforcer_.next(engine_.demands(now), mc, now);
}

}  // namespace fleetgw::geofence
