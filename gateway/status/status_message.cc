#include "gateway/status/status_message.h"

#include <cstdint>

namespace fleetgw::status {
namespace {

using nlohmann::json;

const json* object_member(const json& j, const char* key) {
  if (!j.is_object()) return nullptr;
  const auto it = j.find(key);
  return it != j.end() && it->is_object() ? &*it : nullptr;
}

template <typename T>
T number(const json& j, const char* key) {
  const auto it = j.find(key);
  if (it == j.end() || !it->is_number()) return T{};
  const double v = it->get<double>();
  return v > 0 ? static_cast<T>(v) : T{};
}

std::string text(const json& j, const char* key) {
  const auto it = j.find(key);
  return it != j.end() && it->is_string() ? it->get<std::string>() : std::string();
}

}  // namespace

void fill_status_health(v1::Status& status, const json& document, const AttentionRules& rules) {
  if (const json* st = object_member(document, "storage")) {
    auto* h = status.mutable_storage();
    const auto failing = st->find("failing");
    h->set_failing(failing != st->end() && failing->is_boolean() && failing->get<bool>());
    h->set_last_error(text(*st, "last_error"));
    h->set_failed_writes(number<std::uint64_t>(*st, "failed_writes"));
    h->set_failing_since_us(number<std::int64_t>(*st, "failing_since_us"));
    h->set_configured_budget_bytes(number<std::uint64_t>(*st, "configured_budget_bytes"));
    h->set_effective_budget_bytes(number<std::uint64_t>(*st, "effective_budget_bytes"));
    h->set_dropped_records(number<std::uint64_t>(*st, "dropped_records"));
  }
  if (const json* broker = object_member(document, "broker")) {
    status.set_last_connect_error(text(*broker, "last_connect_error"));
    status.set_last_connect_error_at_us(number<std::int64_t>(*broker, "last_connect_error_us"));
    status.set_tls_failures(number<std::uint64_t>(*broker, "tls_failures"));
  }
  const auto findings = evaluate(document, rules);
  status.set_attention_needed(!findings.empty());
  status.clear_attention();
  for (const auto& f : findings) status.add_attention(f.detail);
}

}  // namespace fleetgw::status
