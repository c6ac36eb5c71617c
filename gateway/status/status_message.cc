#include "gateway/status/status_message.h"

namespace fleetgw::status {

void fill_status(v1::Status& status, const Health& health, const AttentionRules& rules) {
  if (const auto& st = health.storage) {
    auto* h = status.mutable_storage();
    h->set_failing(st->failing);
    h->set_last_error(st->last_error);
    h->set_failed_writes(st->failed_writes);
    h->set_failing_since_us(st->failing_since_us);
    h->set_configured_budget_bytes(st->configured_budget_bytes);
    h->set_effective_budget_bytes(st->effective_budget_bytes);
    h->set_dropped_records(st->dropped_records);
  }
  const auto findings = evaluate(health, rules);
  status.set_attention_needed(!findings.empty());
  status.clear_attention();
  for (const auto& f : findings) status.add_attention(f.detail);
}

}  // namespace fleetgw::status
