#include "gateway/geofence/zone_controller.h"

#include "gateway/geofence/zone_file.h"

namespace fleetgw::geofence {

ZoneController::ZoneController(ZoneControllerConfig config)
    : config_(std::move(config)),
      authority_(config_.trusted_keys, config_.limits, config_.vehicle_id),
      engine_(config_.engine),
      enforcer_(config_.enforcer) {
  authority_.set_delegated_check(config_.delegated_check);  // issue 28
}

std::optional<BundleVerdict> ZoneController::restore(Micros now, std::string& error,
                                                     std::vector<ZoneEvent>& events) {
  error.clear();
  if (config_.bundle_file.empty()) return std::nullopt;
  auto verdict = restore_zones(authority_, config_.bundle_file, error);
  if (verdict && verdict->accepted()) engine_.set_zones(authority_.in_force()->zones, now, events);
  return verdict;
}

BundleVerdict ZoneController::on_bundle(std::span<const std::uint8_t> payload, Micros now,
                                        std::vector<ZoneEvent>& events, std::string& persist_error,
                                        const gnss::Fix* fix, BundleTopic topic) {
  persist_error.clear();
  BundleVerdict verdict = authority_.offer(payload, topic);
  count(verdict, now);
  if (!verdict.accepted()) return verdict;
  // Stored before it is enforced, so what the bike obeys is what it finds after a restart.
  if (!config_.bundle_file.empty()) {
    write_zone_file(config_.bundle_file, authority_.in_force()->payload, persist_error);
  }
  engine_.set_zones(authority_.in_force()->zones, now, events);
  if (fix != nullptr) engine_.relocate(now, *fix, events);
  return verdict;
}

BundleVerdict ZoneController::on_oversized(std::size_t bytes, std::size_t limit, Micros now) {
  BundleVerdict verdict;
  verdict.outcome = BundleOutcome::kRefused;
  verdict.reason = BundleRefusal::kTooLarge;
  verdict.detail = "payload of " + std::to_string(bytes) + " bytes exceeds " +
                   std::to_string(limit) + " (refused unread)";
  verdict.in_force = authority_.in_force() ? authority_.in_force()->zones->version : 0;
  count(verdict, now);
  return verdict;
}

void ZoneController::count(const BundleVerdict& verdict, Micros now) {
  ++counters_.offered;
  if (verdict.accepted()) ++counters_.accepted;
  if (verdict.outcome != BundleOutcome::kRefused) return;
  ++counters_.refused;
  counters_.last_refusal = verdict;
  counters_.last_refusal_at = now;
}

void ZoneController::on_position(Micros now, const gnss::Fix* fix,
                                 std::vector<ZoneEvent>& events) {
  engine_.step(now, fix, events);
}

std::optional<McWrite> ZoneController::tick(Micros now, const McView& mc,
                                            std::vector<ZoneEvent>& events) {
  engine_.advance(now, events);
  return enforcer_.next(engine_.demands(now), mc, now);
}

}  // namespace fleetgw::geofence
