#include "gateway/runtime/store_outbox.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <limits>

#include "fleetgw/v1/eviction.pb.h"

namespace fleetgw::runtime {

std::string uplink_kind(storage::OutboxKind kind) {
  return std::string(storage::to_string(kind));
}

// Stores written before eviction reports were stored as protobuf hold the JSON report
// (EvictionPass::to_json()); so does a store opened without the gateway's encoder.
std::string eviction_payload_from_json(std::string_view text, uint64_t seq) {
  fleetgw::v1::EvictionReport report;
  const auto j = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (j.is_object()) {
    const auto evicted = j.value("evicted", nlohmann::json::object());
    const uint64_t telemetry = evicted.value("telemetry", uint64_t{0});
    const uint64_t packs = evicted.value("pack_snapshots", uint64_t{0});
    report.set_evicted_records(telemetry + packs);
    (*report.mutable_evicted_by_kind())["telemetry"] = telemetry;
    (*report.mutable_evicted_by_kind())["pack"] = packs;
    if (j.contains("oldest_telemetry_kept_us") && j["oldest_telemetry_kept_us"].is_number()) {
      report.set_newest_created_at_us(j["oldest_telemetry_kept_us"].get<int64_t>());
    }
    report.set_reason(j.value("budget_exhausted", false) ? "disk budget exhausted"
                                                         : "disk budget reached");
  } else {
    report.set_reason("disk budget reached (unreadable report)");
  }
  report.set_last_sequence(seq);
  return report.SerializeAsString();
}

namespace {

// A JSON report starts with '{' (0x7b: field 15, wire type 3, a group start). EvictionReport has
// no field 15 and proto3 never writes groups, so its wire bytes never start with it.
bool is_legacy_json_report(const storage::Bytes& payload) {
  return !payload.empty() && payload.front() == '{';
}

}  // namespace

std::vector<uplink::OutgoingRecord> StoreOutbox::peek(std::size_t max_entries,
                                                      std::size_t max_bytes,
                                                      const std::set<std::uint64_t>& exclude,
                                                      const uplink::KindSet& exclude_kinds) {
  std::vector<uplink::OutgoingRecord> out;
  if (max_entries == 0) return out;
  retry_deletes();
  std::vector<storage::OutboxKind> skip;
  for (const auto& name : exclude_kinds) {
    if (const auto k = storage::outbox_kind_from_string(name)) skip.push_back(*k);
  }
  store_.release_all();
  auto rows = store_.peek_outbox(max_entries + exclude.size() + undeleted_.size(),
                                 std::numeric_limits<std::size_t>::max(), skip);
  store_.release_all();
  std::size_t bytes = 0;
  for (auto& row : rows) {
    if (exclude.count(row.seq) || undeleted_.count(row.seq)) continue;
    uplink::OutgoingRecord e;
    e.seq = row.seq;
    e.priority = row.priority;
    // An unknown stored kind keeps its name: the uplink refuses it by name and drops it.
    e.kind = row.unknown_kind ? *row.unknown_kind : uplink_kind(row.kind);
    e.created_us = row.created_us;
    if (row.kind == storage::OutboxKind::kEvictionReport && !row.unknown_kind &&
        is_legacy_json_report(row.payload)) {
      e.payload = eviction_payload_from_json(
          std::string_view(reinterpret_cast<const char*>(row.payload.data()), row.payload.size()),
          row.seq);
    } else {
      e.payload.assign(row.payload.begin(), row.payload.end());
    }
    if (!out.empty() && bytes + e.payload.size() > max_bytes) break;
    bytes += e.payload.size();
    out.push_back(std::move(e));
    if (out.size() >= max_entries) break;
  }
  return out;
}

void StoreOutbox::ack(std::span<const std::uint64_t> seqs) {
  if (seqs.empty()) return;
  // A failing disk is not asked again before the back-off allows: the rows wait with the
  // others for the next retry.
  if (!undeleted_.empty() && retry_.waiting(env_.steady_now())) {
    remember(seqs);
    return;
  }
  if (undeleted_.empty()) {
    if (!delete_rows(seqs)) remember(seqs);
    return;
  }
  // The retry is due: one attempt for the waiting rows and these.
  remember(seqs);
  retry_deletes();
}

void StoreOutbox::remember(std::span<const std::uint64_t> seqs) {
  undeleted_.insert(seqs.begin(), seqs.end());
  while (undeleted_.size() > kMaxUndeleted) undeleted_.erase(undeleted_.begin());
}

bool StoreOutbox::delete_rows(std::span<const std::uint64_t> seqs) {
  if (store_.ack(seqs).ok()) {
    retry_.succeeded();
    return true;
  }
  retry_.failed(env_.steady_now());
  return false;
}

void StoreOutbox::retry_deletes() {
  if (undeleted_.empty() || retry_.waiting(env_.steady_now())) return;
  const std::vector<std::uint64_t> seqs(undeleted_.begin(), undeleted_.end());
  if (delete_rows(seqs)) undeleted_.clear();
}

uplink::OutboxStats StoreOutbox::stats() const {
  uplink::OutboxStats s;
  for (const auto& d : store_.outbox_depth()) s.depth += d.entries;
  s.depth -= std::min<std::uint64_t>(s.depth, undeleted_.size());
  s.oldest_created_us = store_.oldest_unsent_us().value_or(0);
  return s;
}

}  // namespace fleetgw::runtime
