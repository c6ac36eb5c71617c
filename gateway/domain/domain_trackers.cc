#include "gateway/domain/domain_trackers.h"

#include <utility>

namespace fleetgw::domain {
namespace {

DomainConfig validated(DomainConfig config) {
  config.validate();
  return config;
}

AlarmConfig alarm_config(const DomainConfig& c) {
  AlarmConfig a = c.alarms;
  a.lock_kinds = c.locks.lock_kinds;
  a.command_window = c.locks.cause_window;
  a.frame_lock_kinds = c.telemetry.wheel_lock_kinds;
  return a;
}

}  // namespace

DomainTrackers::DomainTrackers(DomainConfig config, DomainSink& sink)
    : config_(validated(std::move(config))),
      rides_(config_.ride, sink),
      faults_(config_.faults, sink),
      packs_(config_.pack, sink),
      telemetry_(config_.telemetry, config_.locks.lock_kinds, sink),
      locks_(config_.locks, sink),
      alarms_(alarm_config(config_), sink) {}

void DomainTrackers::restore(std::span<const storage::RideRow> open_rides, Micros now) {
  rides_.restore(open_rides, now);
  telemetry_.set_riding(fast_telemetry(), now);
}

void DomainTrackers::on_message(const motinova::DecodedMessage& msg, Micros now) {
  // Faults first, so that a fault raised by this very message counts for the ride it happens in;
  // the ride before telemetry, so that a sample taken on a change already sees the ride state.
  faults_.on_message(msg, now);
  sync(now);
  rides_.on_message(msg, now);
  alarms_.on_message(msg, now);
  telemetry_.set_riding(fast_telemetry(), now);
  telemetry_.on_message(msg, now);
  packs_.on_message(msg, now);
  locks_.on_message(msg, now);
}

void DomainTrackers::tick(Micros now) {
  faults_.tick(now);
  sync(now);
  rides_.tick(now);
  alarms_.tick(now);
  telemetry_.set_riding(fast_telemetry(), now);
  telemetry_.tick(now);
  packs_.tick(now);
  locks_.tick(now);
}

void DomainTrackers::sync(Micros now) {
  for (; faults_seen_ < faults_.raised_total(); ++faults_seen_) rides_.on_fault_raised(now);
}

}  // namespace fleetgw::domain
