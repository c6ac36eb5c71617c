// The block table of remote diagnostics (issue 29) and the decoding of answers. See
// diag_blocks.h; the spec sections are quoted per line.
#include "gateway/command/diag_blocks.h"

#include <fmt/format.h>

#include <cmath>

#include "gateway/common/untrusted_text.h"
#include "motinova/catalogue.h"
#include "motinova/codec.h"
#include "motinova/signal_catalogue.h"

namespace fleetgw::command {
namespace {

using motinova::Node;
using node::MessageKey;
namespace ids = node::ids;

// U14: the MC answers IOT reads on 0x713 like OBC reads; 0x710 and 0x716 are accepted too.
std::vector<MessageKey> mc_answers(std::uint8_t function) {
  return {{ids::kMcToObc, function}, {ids::kMcBroadcast, function}, {ids::kMcToIot, function}};
}

DiagBlockSpec mc_read(v1::DiagnosticBlock b, std::string_view name, std::uint8_t read_fn,
                      std::uint8_t answer_fn, std::string_view answer) {
  return {b, name, Node::kMc, {{ids::kIotToMc, read_fn, mc_answers(answer_fn), answer, false}}};
}

DiagBlockSpec bms_read(v1::DiagnosticBlock b, std::string_view name, std::uint8_t read_fn,
                       MessageKey answer_key, std::string_view answer, bool capturable = false) {
  return {
      b, name, Node::kBms, {{ids::kIotToBms, read_fn, {answer_key}, answer, false}}, capturable};
}

// The CDL's ID towards the MC: the only reads of the MC lifetime records the spec defines.
constexpr std::uint16_t kCdlToMc = 0x751;
constexpr std::uint16_t kMcToCdl = 0x715;

std::vector<DiagBlockSpec> build_table() {
  std::vector<DiagBlockSpec> t;
  t.push_back(mc_read(v1::DIAGNOSTIC_BLOCK_MC_SETTINGS, "mc_settings", 0x33, 0x54, "mc_settings"));
  t.push_back(mc_read(v1::DIAGNOSTIC_BLOCK_MC_PARAMS, "mc_params", 0x39, 0x55, "mc_params2"));
  t.push_back(
      mc_read(v1::DIAGNOSTIC_BLOCK_MC_PARAMS_4100, "mc_params_4100", 0x41, 0x55, "mc_params2"));
  t.push_back(mc_read(v1::DIAGNOSTIC_BLOCK_MC_ASSIST_TUNING, "mc_assist_tuning", 0x43, 0x56,
                      "mc_assist_tuning"));
  // §3.3.9, pairing U16 (docs/simulator.md has the simulator's).
  t.push_back(bms_read(v1::DIAGNOSTIC_BLOCK_BMS_STATUS, "bms_status", 0x50,
                       {ids::kBmsBroadcast, node::fn::kBmsStatus}, "bms_status"));
  t.push_back(bms_read(v1::DIAGNOSTIC_BLOCK_BMS_CELLS, "bms_cells", 0x51,
                       {ids::kBmsBroadcast, node::fn::kBmsCells}, "bms_cells"));
  t.push_back(bms_read(v1::DIAGNOSTIC_BLOCK_BMS_FAULTS, "bms_faults", 0x52,
                       {ids::kBmsBroadcast, node::fn::kBmsFaults}, "bms_faults"));
  t.push_back(bms_read(v1::DIAGNOSTIC_BLOCK_BMS_NAMEPLATE, "bms_nameplate", 0x53,
                       {ids::kBmsBroadcast, node::fn::kBmsNameplate}, "bms_nameplate"));
  t.push_back(bms_read(v1::DIAGNOSTIC_BLOCK_BMS_TEMPS, "bms_temps", 0x54,
                       {ids::kBmsBroadcast, node::fn::kBmsExtra}, "bms_temps"));
  t.push_back(bms_read(v1::DIAGNOSTIC_BLOCK_BMS_MODEL, "bms_model", 0x51,
                       {ids::kBmsBroadcast, node::fn::kBmsModelInfo}, "device_info"));
  t.push_back({v1::DIAGNOSTIC_BLOCK_OBC_MODEL,
               "obc_model",
               Node::kObc,
               {{ids::kIotToObc,
                 node::fn::kObcReadModel,
                 {{ids::kObcBroadcast, node::fn::kObcModelInfo}},
                 "device_info",
                 false}}});
  t.push_back(lock_model_block(0));
  // §3.2.3: no read is defined for the MC's model block; it is broadcast on its own.
  t.push_back({v1::DIAGNOSTIC_BLOCK_MC_MODEL,
               "mc_model",
               Node::kMc,
               {{0, 0, {{ids::kMcBroadcast, 0x12}}, "device_info", false}}});
  // §3.2.11/3.2.12: only the CDL's reads exist (0x751 0x1200, and 0x1900 -- OCR "0xipoo",
  // U16 -- for record 2, which is therefore optional).
  t.push_back({v1::DIAGNOSTIC_BLOCK_MC_LIFETIME,
               "mc_lifetime",
               Node::kMc,
               {{kCdlToMc, 0x12, {{kMcToCdl, 0xA2}}, "mc_lifetime_1", false},
                {kCdlToMc, 0x19, {{kMcToCdl, 0xAC}}, "mc_lifetime_2", true}},
               true});
  t.push_back(bms_read(v1::DIAGNOSTIC_BLOCK_PACK_LIFETIME, "pack_lifetime", 0x54,
                       {ids::kBmsToCdl, node::fn::kBmsPackStats}, "pack_stats", true));
  return t;
}

const std::vector<DiagBlockSpec>& diag_table() {
  static const std::vector<DiagBlockSpec> t = build_table();
  return t;
}

// Values travel as integers times 10^6, as campaign samples do (no floating point on the wire).
std::int64_t diag_value_e6(double value) {
  constexpr double kLimit = 9.0e18;
  const double scaled = std::round(value * 1e6);
  if (!(scaled > -kLimit)) return static_cast<std::int64_t>(-kLimit);
  if (!(scaled < kLimit)) return static_cast<std::int64_t>(kLimit);
  return static_cast<std::int64_t>(scaled);
}

}  // namespace

std::span<const DiagBlockSpec> diag_blocks() {
  return diag_table();
}

const DiagBlockSpec* find_diag_block(v1::DiagnosticBlock block) {
  for (const auto& b : diag_table()) {
    if (b.block == block) return &b;
  }
  return nullptr;
}

const DiagBlockSpec* find_diag_block(std::string_view name) {
  for (const auto& b : diag_table()) {
    if (b.name == name) return &b;
  }
  return nullptr;
}

DiagBlockSpec lock_model_block(int k) {
  return {v1::DIAGNOSTIC_BLOCK_LOCK_MODEL,
          "lock_model",
          motinova::lock_node(k),
          {{ids::lock_command_id(k),
            ids::lock_function_base(k),
            {{ids::lock_broadcast_id(k), node::fn::kLockModelInfo}},
            "device_info",
            false}}};
}

std::string diag_block_names() {
  std::string out;
  for (const auto& b : diag_table()) out += (out.empty() ? "" : ", ") + std::string(b.name);
  return out;
}

std::optional<std::string> parse_diag_read(const v1::DiagnosticRead& read, DiagRequest& out) {
  const DiagBlockSpec* spec = find_diag_block(read.block());
  if (read.block() == v1::DIAGNOSTIC_BLOCK_UNSPECIFIED || spec == nullptr) {
    return fmt::format("diagnostic_read.block {} is not a known block",
                       static_cast<int>(read.block()));
  }
  const bool lock = read.block() == v1::DIAGNOSTIC_BLOCK_LOCK_MODEL;
  if (lock && read.lock_kind().empty()) return std::string("lock_model without lock_kind");
  if (!lock && !read.lock_kind().empty()) {
    return fmt::format("lock_kind is only for lock_model, not {}", spec->name);
  }
  if (read.last_captured() && !spec->capturable) {
    return fmt::format("last_captured is only for mc_lifetime and pack_lifetime, not {}",
                       spec->name);
  }
  out.block = read.block();
  out.lock_kind = read.lock_kind();
  out.last_captured = read.last_captured();
  return std::nullopt;
}

std::string diag_request_text(const DiagStep& step) {
  if (step.request_id == 0) {
    return fmt::format("broadcast 0x{:03X}/0x{:02X}..", step.answers.front().can_id,
                       step.answers.front().function);
  }
  return fmt::format("0x{:03X}/0x{:02X}00", step.request_id, step.request_function);
}

std::string diag_node_text(motinova::Node node) {
  std::string_view what = "node";
  switch (node) {
    case Node::kMc:
      what = "the MC";
      break;
    case Node::kBms:
      what = "the BMS";
      break;
    case Node::kObc:
      what = "the OBC";
      break;
    default:
      what = motinova::is_lock(node) ? "the lock" : "the node";
      break;
  }
  return fmt::format("{} (node {})", what, static_cast<int>(node));
}

void decode_diag_message(const motinova::AppFrame& frame, const motinova::DecodeOptions& options,
                         std::int64_t heard_wall_us, v1::DiagnosticMessage& out) {
  motinova::DecodedMessage m;
  motinova::decode(frame, motinova::Catalogue::standard(), options, m);
  out.set_message(std::string(m.name()));
  out.set_can_id(frame.can_id);
  out.set_command(frame.command());
  out.set_data(std::string(reinterpret_cast<const char*>(frame.data.data()), frame.data.size()));
  out.set_heard_at_us(heard_wall_us);
  if (m.status != motinova::DecodeStatus::kOk) return;
  for (const auto& signal : motinova::SignalCatalogue::standard().of_message(m.desc)) {
    const auto value = motinova::SignalCatalogue::read(signal, m);
    if (!value) continue;
    auto* v = out.add_values();
    v->set_name(signal.name);
    v->set_type(std::string(motinova::signal_type_name(signal.type)));
    v->set_unit(std::string(signal.unit));
    v->set_valid(value->valid);
    if (!value->valid) continue;
    switch (signal.type) {
      case motinova::SignalType::kText:
        // Received bytes: printable, valid UTF-8, one line.
        v->set_text(common::untrusted_excerpt(value->text, 64));
        break;
      case motinova::SignalType::kBytes:
        v->set_text(motinova::hex_text(value->bytes));
        break;
      default:
        v->set_text(fmt::format("{}", value->number));
        v->set_value_e6(diag_value_e6(value->number));
        break;
    }
  }
}

}  // namespace fleetgw::command
