#include "storage/records.h"

#include <nlohmann/json.hpp>

namespace fleetgw::storage {
std::string_view to_string(OutboxKind kind) {
  return records::stored_name(kind);
}

std::optional<OutboxKind> outbox_kind_from_string(std::string_view text) {
  return records::kind_from_stored_name(text);
}

std::string_view to_string(FaultEventKind kind) {
  switch (kind) {
    case FaultEventKind::kRaised:
      return "raised";
    case FaultEventKind::kCleared:
      return "cleared";
    case FaultEventKind::kUnknown:
      return "unknown";
  }
  return "invalid";
}

std::string_view to_string(AlarmTransition transition) {
  switch (transition) {
    case AlarmTransition::kRaised:
      return "raised";
    case AlarmTransition::kCleared:
      return "cleared";
  }
  return "invalid";
}

std::string_view to_string(RideState state) {
  switch (state) {
    case RideState::kOpen:
      return "open";
    case RideState::kClosed:
      return "closed";
  }
  return "invalid";
}

std::string EvictionPass::to_json() const {
  nlohmann::json j = {
      {"at_us", at_us},
      {"budget_bytes", budget_bytes},
      {"bytes_before", bytes_before},
      {"bytes_after", bytes_after},
      {"evicted",
       {{"telemetry", telemetry_rows},
        {"pack_snapshots", pack_snapshot_rows},
        {"outbox", outbox_rows},
        {"campaign", campaign_records}}},
      {"budget_exhausted", budget_exhausted},
  };
  j["oldest_telemetry_kept_us"] =
      oldest_telemetry_kept_us ? nlohmann::json(*oldest_telemetry_kept_us) : nlohmann::json();
  return j.dump();
}

}  // namespace fleetgw::storage
