#include "gateway/domain/signals.h"

#include <algorithm>
#include <cstdio>
#include <ctime>
#include <stdexcept>
#include <string>

#include "gateway/domain/domain_config.h"

namespace fleetgw::domain {
namespace {

bool keyword_intact(const motinova::DecodedMessage& msg) {
  // decode() marks a keyword field invalid when the bytes differ from the keyword.
  const auto values = msg.values();
  return std::all_of(values.begin(), values.end(), [](const auto& v) { return v.valid; });
}

}  // namespace

BusEvent classify(const motinova::DecodedMessage& msg) {
  if (msg.status != motinova::DecodeStatus::kOk || msg.desc == nullptr) return BusEvent::kOther;
  if (msg.desc->kind != motinova::MessageKind::kKeyword || !keyword_intact(msg)) {
    return BusEvent::kOther;
  }
  const std::string_view name = msg.desc->name;
  switch (msg.desc->can_id) {
    case 0x760:
      if (name == "lock") return BusEvent::kVehicleLock;
      if (name == "unlock") return BusEvent::kVehicleUnlock;
      if (name == "shutdown") return BusEvent::kShutdown;
      return BusEvent::kOther;
    case 0x730:  // OBC: the user switched the system off
    case 0x720:  // BMS auto-off
      return name == "shutdown" ? BusEvent::kShutdown : BusEvent::kOther;
    default:
      // 0x763 SHUTDOWN only powers the OBC down; the bike stays up.
      return BusEvent::kOther;
  }
}

std::string assist_name(const motinova::DecodedMessage& mc_status) {
  const std::string_view text = mc_status.text("assist");
  if (!text.empty()) return std::string(text);
  const auto raw = mc_status.raw("assist");
  if (!raw) return "unknown";
  char buf[8];
  std::snprintf(buf, sizeof buf, "0x%02X", static_cast<unsigned>(*raw & 0xFF));
  return buf;
}

std::string utc_basic(Micros t) {
  const int64_t us = t.count();
  const std::time_t secs = static_cast<std::time_t>(us >= 0 ? us / 1'000'000 : 0);
  std::tm tm{};
  gmtime_r(&secs, &tm);
  char buf[40];
  std::snprintf(buf, sizeof buf, "%04d%02d%02dT%02d%02d%02d.%06lldZ", tm.tm_year + 1900,
                tm.tm_mon + 1, tm.tm_mday, tm.tm_hour, tm.tm_min, tm.tm_sec,
                static_cast<long long>(us >= 0 ? us % 1'000'000 : 0));
  return buf;
}

void DomainConfig::validate() const {
  auto fail = [](const char* key, const char* why) {
    throw std::invalid_argument(std::string("domain config: ") + key + ": " + why);
  };
  if (!(ride.moving_speed_kmh > 0)) fail("ride.moving_speed_kmh", "must be > 0");
  if (!(ride.standstill_kmh > 0) || ride.standstill_kmh > ride.moving_speed_kmh) {
    fail("ride.standstill_kmh", "must be > 0 and <= ride.moving_speed_kmh");
  }
  if (ride.stationary_end <= Micros{0}) fail("ride.stationary_end_s", "must be > 0");
  if (ride.checkpoint_interval <= Micros{0}) fail("ride.checkpoint_interval_s", "must be > 0");
  if (ride.sample_gap <= Micros{0}) fail("ride.sample_gap_ms", "must be > 0");
  if (faults.debounce < Micros{0}) fail("faults.debounce_ms", "must be >= 0");
  if (faults.stale <= Micros{0}) fail("faults.stale_ms", "must be > 0");
  if (pack.period <= Micros{0}) fail("pack.snapshot_interval_s", "must be > 0");
  if (telemetry.riding_interval <= Micros{0}) fail("telemetry.riding_interval_ms", "must be > 0");
  if (telemetry.parked_interval <= Micros{0}) fail("telemetry.parked_interval_ms", "must be > 0");
  if (locks.cause_window <= Micros{0}) fail("locks.cause_window_s", "must be > 0");
}

}  // namespace fleetgw::domain
