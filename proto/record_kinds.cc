#include "proto/record_kinds.h"

namespace fleetgw::records {

namespace {

constexpr bool indexed_by_enum() {
  for (std::size_t i = 0; i < kRecordKinds.size(); ++i) {
    if (static_cast<std::size_t>(kRecordKinds[i].kind) != i) return false;
  }
  return true;
}
static_assert(indexed_by_enum(), "kRecordKinds must list the kinds in RecordKind order");

}  // namespace

std::optional<RecordKind> kind_from_stored_name(std::string_view name) {
  for (const auto& s : kRecordKinds) {
    if (s.stored_name == name) return s.kind;
  }
  return std::nullopt;
}

const RecordKindSpec* find_by_envelope_field(int field) {
  for (const auto& s : kRecordKinds) {
    if (s.envelope_field == field) return &s;
  }
  return nullptr;
}

const RecordKindSpec* find_by_topic_leaf(std::string_view leaf) {
  for (const auto& s : kRecordKinds) {
    if (s.topic_leaf == leaf) return &s;
  }
  return nullptr;
}

std::string unknown_kind_message(std::string_view name) {
  std::string out = "unknown record kind '";
  // The name comes from a file on disk: keep the log line printable and short.
  for (const char c : name.substr(0, 64)) {
    out += (c >= 0x20 && c < 0x7f) ? c : '?';
  }
  out += "' (this version knows:";
  for (const auto& s : kRecordKinds) {
    out += ' ';
    out += s.stored_name;
  }
  out += ')';
  return out;
}

}  // namespace fleetgw::records
