#include "gateway/campaign/campaign_authority.h"

#include <fmt/format.h>

#include <algorithm>
#include <stdexcept>

#include "fleetgw/v1/campaign.pb.h"
#include "gateway/command/document_signer.h"
#include "gateway/common/untrusted_text.h"

namespace fleetgw::campaign {
namespace {

std::span<const std::uint8_t> campaign_bytes_of(const std::string& s) {
  return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
}

CampaignVerdict refused(CampaignRefusal reason, std::string detail) {
  CampaignVerdict v;
  v.reason = reason;
  v.detail = std::move(detail);
  return v;
}

}  // namespace

std::string_view campaign_outcome_name(CampaignOutcome outcome) {
  switch (outcome) {
    case CampaignOutcome::kAccepted:
      return "accepted";
    case CampaignOutcome::kAlreadyInForce:
      return "already_in_force";
    case CampaignOutcome::kRefused:
      return "refused";
  }
  return "refused";
}

std::string_view campaign_refusal_name(CampaignRefusal reason) {
  switch (reason) {
    case CampaignRefusal::kNone:
      return "";
    case CampaignRefusal::kTooLarge:
      return "too_large";
    case CampaignRefusal::kMalformed:
      return "malformed";
    case CampaignRefusal::kUnknownKey:
      return "unknown_key";
    case CampaignRefusal::kBadSignature:
      return "signature_invalid";
    case CampaignRefusal::kDelegationInvalid:
      return "delegation_invalid";
    case CampaignRefusal::kRevoked:
      return "revoked";
    case CampaignRefusal::kOutOfScope:
      return "out_of_scope";
    case CampaignRefusal::kClockUnsynchronised:
      return "clock_unsynchronised";
    case CampaignRefusal::kDelegationNotYetValid:
      return "delegation_not_yet_valid";
    case CampaignRefusal::kDelegationExpired:
      return "delegation_expired";
    case CampaignRefusal::kInvalid:
      return "invalid_campaign";
    case CampaignRefusal::kNotForThisVehicle:
      return "not_for_this_vehicle";
    case CampaignRefusal::kExpired:
      return "expired";
    case CampaignRefusal::kNotNewer:
      return "not_newer";
    case CampaignRefusal::kVersionConflict:
      return "version_conflict";
    case CampaignRefusal::kOverBudget:
      return "over_budget";
  }
  return "";
}

CampaignAuthority::CampaignAuthority(const std::map<std::string, std::string>& trusted_keys,
                                     std::string vehicle_id, std::vector<std::string> groups,
                                     CampaignLimits limits)
    : vehicle_id_(std::move(vehicle_id)), groups_(std::move(groups)), limits_(limits) {
  for (const auto& [id, text] : trusted_keys) {
    auto key = command::Ed25519PublicKey::from_base64(text);
    if (!key) {
      throw std::invalid_argument("command.trusted_keys." + id +
                                  ": not a base64 raw Ed25519 public key");
    }
    keys_.emplace(id, std::move(*key));
  }
}

CampaignVerdict CampaignAuthority::offer(std::string_view payload, Micros now,
                                         CampaignTopic topic) {
  return offer(std::span<const std::uint8_t>(reinterpret_cast<const std::uint8_t*>(payload.data()),
                                             payload.size()),
               now, topic);
}

CampaignVerdict CampaignAuthority::offer(std::span<const std::uint8_t> payload, Micros now,
                                         CampaignTopic topic) {
  if (payload.size() > limits_.max_payload_bytes) {
    return refused(CampaignRefusal::kTooLarge,
                   fmt::format("{} bytes, at most {}", payload.size(), limits_.max_payload_bytes));
  }
  v1::SignedCampaign signed_campaign;
  if (!signed_campaign.ParseFromArray(payload.data(), static_cast<int>(payload.size()))) {
    return refused(CampaignRefusal::kMalformed, "not a SignedCampaign");
  }
  if (signed_campaign.campaign().empty() || signed_campaign.signature().empty() ||
      signed_campaign.key_id().empty()) {
    return refused(CampaignRefusal::kMalformed, "no campaign, signature or key_id");
  }
  const auto signed_bytes = campaign_bytes_of(signed_campaign.campaign());
  const auto signature = campaign_bytes_of(signed_campaign.signature());
  // Issue 28: a trusted key, or a delegated one judged like a command's (docs/commands.md
  // "Delegations"), by the helper the zone bundles share.
  const auto signer = command::judge_document_signer(
      keys_, signed_campaign.key_id(),
      signed_campaign.has_delegation() ? &signed_campaign.delegation() : nullptr, delegated_check_,
      signed_bytes, signature);
  switch (signer.outcome) {
    case command::SignerOutcome::kTrusted:
    case command::SignerOutcome::kDelegated:
      break;
    case command::SignerOutcome::kDelegatedSignatureInvalid:
      return refused(CampaignRefusal::kBadSignature,
                     "not a signature of the campaign by the delegated key '" +
                         common::untrusted_excerpt(signed_campaign.key_id()) + "'");
    case command::SignerOutcome::kDelegationRefused: {
      static constexpr CampaignRefusal kByReason[] = {CampaignRefusal::kDelegationInvalid,
                                                      CampaignRefusal::kRevoked,
                                                      CampaignRefusal::kOutOfScope,
                                                      CampaignRefusal::kClockUnsynchronised,
                                                      CampaignRefusal::kDelegationNotYetValid,
                                                      CampaignRefusal::kDelegationExpired};
      return refused(command::delegation_refusal_as(signer.problem->reason, kByReason),
                     signer.problem->detail);
    }
    case command::SignerOutcome::kUnknownKey:
      return refused(CampaignRefusal::kUnknownKey,
                     "key '" + common::untrusted_excerpt(signed_campaign.key_id()) +
                         "' is not in [command.trusted_keys]" +
                         (signer.delegation_unjudged
                              ? " (a delegation, but no [command.root_keys] to judge it)"
                              : ""));
    case command::SignerOutcome::kSignatureInvalid:
      return refused(CampaignRefusal::kBadSignature,
                     "not a signature of the campaign by '" +
                         common::untrusted_excerpt(signed_campaign.key_id()) + "'");
  }
  v1::Campaign campaign;
  if (!campaign.ParseFromString(signed_campaign.campaign())) {
    return refused(CampaignRefusal::kMalformed, "the signed bytes are not a Campaign");
  }
  auto compiled = compile_campaign(campaign);
  if (auto* problem = std::get_if<std::string>(&compiled)) {
    auto v = refused(CampaignRefusal::kInvalid, *problem);
    v.id = common::untrusted_excerpt(campaign.id());
    v.version = campaign.version();
    return v;
  }
  auto& c = std::get<CompiledCampaign>(compiled);
  auto judged = [&](CampaignRefusal reason, std::string detail) {
    auto v = refused(reason, std::move(detail));
    v.id = c.id;
    v.version = c.version;
    return v;
  };
  if (auto why = not_for_us(c, topic)) return judged(CampaignRefusal::kNotForThisVehicle, *why);
  if (now >= c.end) {
    return judged(CampaignRefusal::kExpired,
                  fmt::format("ended at {} us, now {} us", c.end.count(), now.count()));
  }
  if (const auto held = in_force_.find(c.id); held != in_force_.end()) {
    const auto held_version = held->second.compiled.version;
    if (c.version < held_version) {
      return judged(CampaignRefusal::kNotNewer,
                    fmt::format("version {} is older than {} in force", c.version, held_version));
    }
    if (c.version == held_version) {
      if (held->second.campaign_bytes == signed_campaign.campaign()) {
        CampaignVerdict v;
        v.outcome = CampaignOutcome::kAlreadyInForce;
        v.detail = fmt::format("version {} already in force", c.version);
        v.id = c.id;
        v.version = c.version;
        return v;
      }
      return judged(CampaignRefusal::kVersionConflict,
                    fmt::format("version {} in force has other contents", c.version));
    }
  }
  if (auto why = over_budget(c)) return judged(CampaignRefusal::kOverBudget, *why);
  CampaignVerdict v;
  v.outcome = CampaignOutcome::kAccepted;
  v.id = c.id;
  v.version = c.version;
  v.detail = fmt::format("version {}, {} signals, {} {}, at most {} bytes/h, disk budget {} bytes",
                         c.version, c.signals.size(), trigger_name(c.trigger),
                         sampling_name(c.sampling), c.cost.max_bytes_per_hour, c.disk_budget_bytes);
  const std::string id = c.id;
  in_force_[id] = CampaignInForce{
      .payload = std::string(reinterpret_cast<const char*>(payload.data()), payload.size()),
      .campaign_bytes = signed_campaign.campaign(),
      .key_id = signed_campaign.key_id(),
      .compiled = std::move(c)};
  return v;
}

std::optional<std::string> CampaignAuthority::not_for_us(const CompiledCampaign& c,
                                                         CampaignTopic topic) const {
  const bool named =
      std::find(c.vehicle_ids.begin(), c.vehicle_ids.end(), vehicle_id_) != c.vehicle_ids.end();
  if (topic == CampaignTopic::kVehicle && !named) {
    return "it came on this vehicle's own topic but does not name '" + vehicle_id_ + "'";
  }
  if (vehicle_id_.empty() || c.all_vehicles || named) return std::nullopt;
  for (const auto& g : c.groups) {
    if (std::find(groups_.begin(), groups_.end(), g) != groups_.end()) return std::nullopt;
  }
  return "its target names neither '" + vehicle_id_ + "' nor one of its groups";
}

std::optional<std::string> CampaignAuthority::over_budget(const CompiledCampaign& c) const {
  std::size_t count = 1;
  std::uint64_t disk = c.disk_budget_bytes, rate = c.cost.max_bytes_per_hour;
  for (const auto& [id, held] : in_force_) {
    if (id == c.id) continue;  // replaced by this version
    ++count;
    disk += held.compiled.disk_budget_bytes;
    rate += held.compiled.cost.max_bytes_per_hour;
  }
  if (count > limits_.max_campaigns) {
    return fmt::format("{} campaigns would be in force, at most {}", count, limits_.max_campaigns);
  }
  if (disk > limits_.total_disk_budget) {
    return fmt::format(
        "disk_budget_bytes: the campaigns would hold {} bytes, the store gives them {}", disk,
        limits_.total_disk_budget);
  }
  if (rate > limits_.max_bytes_per_hour) {
    return fmt::format("sampling.period_ms: the campaigns would make up to {} bytes/h, at most {}",
                       rate, limits_.max_bytes_per_hour);
  }
  return std::nullopt;
}

std::vector<std::string> CampaignAuthority::expire(Micros now) {
  std::vector<std::string> gone;
  for (auto it = in_force_.begin(); it != in_force_.end();) {
    if (now >= it->second.compiled.end) {
      gone.push_back(it->first);
      it = in_force_.erase(it);
    } else {
      ++it;
    }
  }
  return gone;
}

std::string sign_campaign(const v1::Campaign& campaign, const command::Ed25519PrivateKey& key,
                          std::string_view key_id) {
  v1::SignedCampaign s;
  s.set_campaign(campaign.SerializeAsString());
  const auto signature = key.sign(campaign_bytes_of(s.campaign()));
  s.set_signature(std::string(signature.begin(), signature.end()));
  s.set_key_id(std::string(key_id));
  return s.SerializeAsString();
}

}  // namespace fleetgw::campaign
