// Envelope → rows (envelope_rows.h): topic and payload checks, dispatch to the per-kind row
// functions (record_rows.h), the commands seen on `cmd`, sequence ranges.
#include "backend/ingest/envelope_rows.h"

#include <fmt/format.h>

#include <google/protobuf/arena.h>

#include <algorithm>
#include <array>

#include "backend/ingest/campaign_rows.h"
#include "backend/ingest/copy_text.h"
#include "backend/ingest/record_rows.h"
#include "backend/ingest/safe_text.h"
#include "fleetgw/v1/command.pb.h"
#include "fleetgw/v1/envelope.pb.h"
#include "proto/record_kinds.h"

namespace fleetgw::ingest {
namespace {

namespace v1 = fleetgw::v1;
using namespace rows;

std::variant<Decoded, Reject> command_message(std::string_view vehicle, std::string_view payload) {
  v1::SignedCommand signed_cmd;
  v1::Command cmd;
  if (!signed_cmd.ParseFromArray(payload.data(), static_cast<int>(payload.size())) ||
      !cmd.ParseFromString(signed_cmd.command())) {
    return Reject{"not_a_command", "payload on cmd is not a fleetgw.v1.SignedCommand"};
  }
  if (cmd.vehicle_id() != vehicle) {
    return Reject{"vehicle_mismatch", fmt::format("command for \"{}\" on this vehicle's cmd topic",
                                                  untrusted_excerpt(cmd.vehicle_id()))};
  }
  if (cmd.command_id().empty()) return Reject{"not_a_command", "command without command_id"};
  Decoded d;
  d.vehicle_id = std::string(vehicle);
  RowSet& rows = new_rows(d, kCommands);
  RowBuilder b(rows);
  b.text("command_id", cmd.command_id());
  b.text("vehicle_id", cmd.vehicle_id());
  b.text("key_id", signed_cmd.key_id());
  b.i64(cmd.issued_at_us());
  b.i64(cmd.expires_at_us());
  if (cmd.mc_action_case() != v1::Command::MC_ACTION_NOT_SET) {
    b.raw(fmt::format("mc:{}", static_cast<int>(cmd.mc_action_case())));
  } else {
    b.name(&v1::CommandAction_Name<v1::CommandAction>, cmd.action());
  }
  b.text("lock_kind", cmd.whole_vehicle() ? std::string_view("vehicle") : cmd.lock_kind());
  if (b.error) return *b.error;
  return d;
}

// The leaf each body must arrive on: the record-kind table's topic (proto/record_kinds.h), and
// "state" for the retained VehicleState (no record). Empty for a body newer than this ingest:
// rejected as unsupported.
std::string_view leaf_of(v1::Envelope::BodyCase body) {
  if (body == v1::Envelope::kState) return "state";
  const auto* kind = records::find_by_envelope_field(static_cast<int>(body));
  return kind != nullptr ? kind->topic_leaf : std::string_view();
}

}  // namespace

const TableSpec* table_of(int envelope_field) {
  if (envelope_field == v1::Envelope::kState) return &kState;
  const auto* kind = records::find_by_envelope_field(envelope_field);
  if (kind == nullptr) return nullptr;
  for (const TableSpec* t : {&kRides, &kFaults, &kPacks, &kLocks, &kInfo, &kResults, &kAlarms,
                             &kZones, &kEvictions, &kStatus, &kTelemetry, &kCampaignSamplesTable}) {
    if (t->table == kind->ingest_table) return t;
  }
  return nullptr;
}

std::vector<PgParam> RowSet::values() const {
  std::vector<PgParam> out;
  std::vector<std::string_view> fields;
  std::string_view rest = copy;
  while (!rest.empty()) {
    split_row(next_row(rest), fields);
    for (const std::string_view f : fields) out.push_back(copy_value(f));
  }
  return out;
}

std::vector<SequenceRange> to_ranges(std::vector<std::uint64_t> seqs) {
  std::sort(seqs.begin(), seqs.end());
  std::vector<SequenceRange> out;
  for (std::uint64_t s : seqs) {
    if (!out.empty() && s <= out.back().last + 1) {
      out.back().last = std::max(out.back().last, s);
    } else {
      out.push_back({s, s});
    }
  }
  return out;
}

std::variant<Decoded, Reject> decode_message(std::string_view topic_prefix, std::string_view topic,
                                             std::string_view payload) {
  // <prefix>/<vehicle>/<leaf>, leaf possibly "cmd/result".
  if (topic.size() <= topic_prefix.size() + 1 || !topic.starts_with(topic_prefix) ||
      topic[topic_prefix.size()] != '/') {
    return Reject{"bad_topic", "topic outside the prefix"};
  }
  const std::string_view rest = topic.substr(topic_prefix.size() + 1);
  const std::size_t slash = rest.find('/');
  if (slash == 0 || slash == std::string_view::npos) {
    return Reject{"bad_topic", "topic without <vehicle_id>/<leaf>"};
  }
  const std::string_view vehicle = rest.substr(0, slash);
  const std::string_view leaf = rest.substr(slash + 1);
  if (vehicle.size() > 128 || !is_valid_utf8(vehicle)) {
    return Reject{"bad_topic", "vehicle id in the topic too long or not UTF-8"};
  }
  if (leaf == "cmd") return command_message(vehicle, payload);

  // The parsed message lives in an arena whose first block is on the stack: a telemetry batch's
  // samples (a message each, a Position each) cost no malloc/free per message (profiled, issue
  // 25: allocation was the worker's largest share). Bigger messages grow it on the heap.
  alignas(std::max_align_t) std::array<char, 8192> first_block;
  google::protobuf::Arena arena(first_block.data(), first_block.size());
  v1::Envelope& e = *google::protobuf::Arena::CreateMessage<v1::Envelope>(&arena);
  if (!e.ParseFromArray(payload.data(), static_cast<int>(payload.size()))) {
    return Reject{"not_an_envelope",
                  fmt::format("{} bytes do not parse as fleetgw.v1.Envelope", payload.size())};
  }
  if (e.body_case() == v1::Envelope::BODY_NOT_SET) {
    return Reject{"no_body", "Envelope without a body (or one this schema does not know)"};
  }
  if (leaf_of(e.body_case()).empty()) {
    return Reject{"unsupported_body", fmt::format("Envelope body field {} is not known to this "
                                                  "ingest",
                                                  static_cast<int>(e.body_case()))};
  }
  if (e.vehicle_id() != vehicle) {
    return Reject{"vehicle_mismatch",
                  fmt::format("Envelope.vehicle_id \"{}\" on the topic of \"{}\"",
                              untrusted_excerpt(e.vehicle_id()), untrusted_excerpt(vehicle))};
  }
  if (leaf_of(e.body_case()) != leaf) {
    return Reject{"wrong_leaf", fmt::format("a {} body on leaf \"{}\"", leaf_of(e.body_case()),
                                            untrusted_excerpt(leaf))};
  }
  Decoded d;
  d.vehicle_id = e.vehicle_id();
  d.store_id = e.store_id();
  const auto body = e.body_case();
  if (body == v1::Envelope::kTelemetry) {
    if (auto r = telemetry_rows(e, d)) return *r;
    return d;
  }
  if (body != v1::Envelope::kStatus && body != v1::Envelope::kState &&
      body != v1::Envelope::kCommandResult && e.sequence() == 0) {
    return Reject{"record_without_sequence",
                  fmt::format("a {} record with sequence 0", leaf_of(body))};
  }
  if (body == v1::Envelope::kCampaign) {  // issue 29: a row per sample (campaign_rows.h)
    if (auto r = campaign_rows(e, d)) return *r;
    d.ranges.push_back({e.sequence(), e.sequence()});
    return d;
  }
  const TableSpec* spec = table_of(static_cast<int>(body));
  if (spec == nullptr) return Reject{"no_body", "unexpected body"};
  RowSet& rows = new_rows(d, *spec);
  RowBuilder b(rows);
  switch (body) {
    case v1::Envelope::kRide:
      ride_rows(e, d, b);
      break;
    case v1::Envelope::kFault:
      fault_rows(e, d, b);
      break;
    case v1::Envelope::kPack:
      pack_rows(e, d, b);
      break;
    case v1::Envelope::kLock:
      lock_rows(e, d, b);
      break;
    case v1::Envelope::kInfo:
      info_rows(e, d, b);
      break;
    case v1::Envelope::kCommandResult:
      result_rows(e, d, b);
      break;
    case v1::Envelope::kAlarm:
      alarm_rows(e, d, b);
      break;
    case v1::Envelope::kZone:
      zone_rows(e, d, b);
      break;
    case v1::Envelope::kEviction:
      eviction_rows(e, d, b);
      break;
    case v1::Envelope::kStatus:
      status_rows(e, b);
      break;
    case v1::Envelope::kState:
      state_rows(e, b);
      break;
    default:
      break;
  }
  if (b.error) return *b.error;
  // After the status's own row is checked: the history row holds a subset of its values.
  if (body == v1::Envelope::kStatus) status_history_rows(e, d);
  // A record accounts for its own sequence (an eviction report also for the evicted range,
  // added by eviction_rows); status, state and unstored command results for none.
  if (d.records > 0) d.ranges.push_back({e.sequence(), e.sequence()});
  return d;
}

}  // namespace fleetgw::ingest
