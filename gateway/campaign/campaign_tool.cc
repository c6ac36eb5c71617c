#include "gateway/campaign/campaign_tool.h"

#include <algorithm>
#include <memory>
#include <ostream>

#include "fleetgw/v1/campaign.pb.h"
#include "fleetgw/v1/keys.pb.h"
#include "gateway/campaign/campaign_authority.h"
#include "gateway/campaign/campaign_file.h"
#include "gateway/campaign/campaign_spec.h"
#include "gateway/command/delegation.h"
#include "gateway/command/signing.h"
#include "gateway/common/untrusted_text.h"
#include "gateway/geofence/zone_file.h"

namespace fleetgw::campaign {
namespace {

constexpr std::size_t kMaxCampaignFileBytes = 1u << 20;

void print_cost(const CompiledCampaign& c, std::ostream& out) {
  out << "  " << c.signals.size() << " signals, " << trigger_name(c.trigger);
  if (c.trigger == TriggerKind::kCondition) {
    out << " (" << condition_name(c.condition.kind) << " " << c.condition.signal->name << ")";
  }
  out << ", " << sampling_name(c.sampling) << " every " << c.period.count() / 1000 << " ms";
  if (c.sampling == SamplingKind::kWindow) {
    out << " (" << c.before.count() / 1000 << " ms before, " << c.after.count() / 1000
        << " ms after)";
  }
  out << "\n  cost: at most " << c.cost.max_samples_per_hour << " samples/h, "
      << c.cost.max_bytes_per_hour << " bytes/h, ring " << c.cost.ring_samples << " samples ("
      << c.cost.ring_bytes << " bytes), disk budget " << c.disk_budget_bytes << " bytes, priority "
      << c.priority << '\n';
}

}  // namespace

int run_campaign_sign(const CampaignSignOptions& options, std::ostream& out, std::ostream& err) {
  try {
    std::string error;
    const auto text = geofence::read_zone_file(options.file, error, kMaxCampaignFileBytes);
    if (!text) {
      err << "campaign sign: " << (error.empty() ? options.file.string() + ": no such file" : error)
          << '\n';
      return 1;
    }
    auto parsed = parse_campaign_text(*text, options.file.string());
    if (auto* problem = std::get_if<std::string>(&parsed)) {
      err << "campaign sign: " << *problem << '\n';
      return 1;
    }
    auto& campaign = std::get<v1::Campaign>(parsed);
    if (options.version > 0) campaign.set_version(options.version);
    campaign.set_issued_at_us(options.issued_at.count());
    const auto compiled = compile_campaign(campaign);
    if (auto* problem = std::get_if<std::string>(&compiled)) {
      err << "campaign sign: " << options.file.string() << ": " << *problem << '\n';
      return 1;
    }
    const std::string key_id =
        options.key_id.empty() ? options.key_pem.stem().string() : options.key_id;
    if (!command::is_valid_tool_id(key_id)) {
      err << "campaign sign: key id '" << common::untrusted_excerpt(key_id)
          << "' must be 1..64 characters of [A-Za-z0-9._-]\n";
      return 1;
    }
    const auto key = command::Ed25519PrivateKey::load_pem(options.key_pem);
    std::string payload = sign_campaign(campaign, key, key_id);
    if (!options.delegation.empty()) {
      // Issue 28: outside the signed bytes, as the root signed it.
      const auto delegation = geofence::read_zone_file(options.delegation, error, 64 * 1024);
      v1::SignedCampaign s;
      if (!delegation || !s.ParseFromString(payload) ||
          !s.mutable_delegation()->ParseFromString(*delegation)) {
        err << "campaign sign: --delegation " << options.delegation.string()
            << ": not a signed delegation " << error << '\n';
        return 1;
      }
      payload = s.SerializeAsString();
    }
    if (!geofence::write_zone_file(options.out, payload, error)) {
      err << "campaign sign: " << error << '\n';
      return 1;
    }
    out << "campaign sign: '" << campaign.id() << "' version " << campaign.version()
        << " signed by '" << key_id << "' -> " << options.out.string() << " (" << payload.size()
        << " bytes)\n";
    print_cost(std::get<CompiledCampaign>(compiled), out);
    return 0;
  } catch (const std::exception& e) {
    err << "campaign sign: " << e.what() << '\n';
    return 1;
  }
}

int run_campaign_check(const CampaignCheckOptions& options, std::ostream& out, std::ostream& err) {
  try {
    std::string error;
    const auto payload = geofence::read_zone_file(options.signed_file, error, 1u << 20);
    if (!payload) {
      err << "campaign check: "
          << (error.empty() ? options.signed_file.string() + ": no such file" : error) << '\n';
      return 1;
    }
    CampaignLimits limits;
    if (options.store_budget_bytes > 0) {
      limits.total_disk_budget = std::min(limits.total_disk_budget, options.store_budget_bytes / 4);
    }
    CampaignAuthority authority(options.trusted_keys, options.vehicle_id, options.groups, limits);
    if (!options.root_keys.empty()) {
      // Issue 28: what the bike's command service does for action "campaign".
      auto roots = std::make_shared<const command::RootKeys>(options.root_keys);
      auto revocations = std::make_shared<command::Revocations>();
      if (!options.revocations.empty()) {
        const auto list =
            geofence::read_zone_file(options.revocations, error, command::kMaxRevocationBytes);
        if (!list) {
          err << "campaign check: --revocations "
              << (error.empty() ? options.revocations.string() + ": no such file" : error) << '\n';
          return 1;
        }
        const auto v = revocations->offer(
            {reinterpret_cast<const std::uint8_t*>(list->data()), list->size()}, *roots);
        if (!v.accepted()) {
          err << "campaign check: --revocations " << options.revocations.string() << ": refused ("
              << v.reason << "): " << v.detail << '\n';
          return 1;
        }
      }
      const command::VehicleIdentity vehicle{options.vehicle_id, options.groups};
      const auto now = options.now;
      authority.set_delegated_check(
          [roots, revocations, vehicle, now](
              const v1::SignedDelegation& delegation, std::string_view key_id,
              std::span<const std::uint8_t> signed_bytes, std::span<const std::uint8_t> signature) {
            return command::check_delegated(delegation, key_id, signed_bytes, signature, "campaign",
                                            vehicle, now, true, *roots, *revocations);
          });
    }
    const auto verdict = authority.offer(*payload, options.now);
    out << campaign_outcome_name(verdict.outcome);
    if (verdict.reason != CampaignRefusal::kNone) {
      out << " (" << campaign_refusal_name(verdict.reason) << ")";
    }
    out << ": " << verdict.detail << '\n';
    if (!verdict.accepted()) return 1;
    print_cost(authority.in_force().begin()->second.compiled, out);
    return 0;
  } catch (const std::exception& e) {
    err << "campaign check: " << e.what() << '\n';
    return 1;
  }
}

}  // namespace fleetgw::campaign
