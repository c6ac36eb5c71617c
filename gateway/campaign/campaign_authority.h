// Which signed campaigns a gateway runs: each offer (a serialized fleetgw.v1.SignedCampaign from
// a retained topic, the store at start-up, or an operator's check) judged and either put in
// force or refused with a reason. Pure: no I/O; the caller passes the wall clock.
//
// Contract -- checks, in order, the first failing one is the reason:
//    too_large              payload over max_payload_bytes
//    malformed              not a SignedCampaign, or no signature / key id / campaign bytes, or
//                           the campaign bytes are not a Campaign
//    unknown_key            key id not in [command.trusted_keys], and no delegation (or no
//                           delegated check: no [command.root_keys])
//    signature_invalid      not an Ed25519 signature of exactly the campaign bytes (by the
//                           trusted key, or by the delegate's key)
//    delegation_invalid     (issue 28, a delegated key: SignedCampaign.delegation) the
//    revoked                delegation is not a valid root's signature, or does not delegate
//    out_of_scope           this key id; its serial is revoked; it lacks the action "campaign"
//    clock_unsynchronised   or does not cover this vehicle; the wall clock is not synchronised;
//    delegation_not_yet_valid  its window has not begun; its window has ended
//    delegation_expired     (command::check_delegated, names as for commands and zone bundles)
//    invalid_campaign       compile_campaign() refused it (the detail names the field; an
//                           unknown signal is one)
//    not_for_this_vehicle   its target names neither this vehicle, nor one of its groups, nor
//                           all vehicles; or it came on the vehicle's own topic without naming
//                           the vehicle
//    expired                now >= end_us
//    not_newer              version lower than the one in force for its id
//    version_conflict       same version as the one in force, different bytes
//    over_budget            with it in force, more than max_campaigns campaigns, or their disk
//                           budgets over total_disk_budget, or their bytes an hour over
//                           max_bytes_per_hour (each campaign's bound, campaign_spec.h)
//  The same version with the same bytes is kAlreadyInForce (retained messages come again on
//  every reconnect). A refusal changes nothing. A key in [command.trusted_keys] is judged as
//  trusted even when the campaign also carries a delegation. Stored campaigns are judged again
//  at start-up, against the revocation list in force then.
//  * expire(now) drops the campaigns past their end (their ids, for the caller's store).
//  * Received strings in a detail go through common::untrusted_excerpt.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "gateway/campaign/campaign_spec.h"
#include "gateway/command/delegation.h"
#include "gateway/command/ed25519.h"

namespace fleetgw::v1 {
class Campaign;
class SignedDelegation;
}  // namespace fleetgw::v1

namespace fleetgw::campaign {

struct CampaignLimits {
  std::size_t max_payload_bytes = 64u << 10;
  std::size_t max_campaigns = 16;
  std::uint64_t total_disk_budget = 64ull << 20;
  std::uint64_t max_bytes_per_hour = 256ull << 20;
};

enum class CampaignOutcome : std::uint8_t { kAccepted, kAlreadyInForce, kRefused };
enum class CampaignRefusal : std::uint8_t {
  kNone,
  kTooLarge,
  kMalformed,
  kUnknownKey,
  kBadSignature,
  // Issue 28: a key delegated by a root (set_delegated_check); names as for commands.
  kDelegationInvalid,
  kRevoked,
  kOutOfScope,
  kClockUnsynchronised,
  kDelegationNotYetValid,
  kDelegationExpired,
  kInvalid,
  kNotForThisVehicle,
  kExpired,
  kNotNewer,
  kVersionConflict,
  kOverBudget,
};
enum class CampaignTopic : std::uint8_t { kFleet, kVehicle };
std::string_view campaign_outcome_name(CampaignOutcome outcome);
std::string_view campaign_refusal_name(CampaignRefusal reason);

struct CampaignVerdict {
  CampaignOutcome outcome = CampaignOutcome::kRefused;
  CampaignRefusal reason = CampaignRefusal::kNone;
  std::string detail;
  std::string id;             // once authenticated
  std::uint64_t version = 0;  // once authenticated
  bool accepted() const { return outcome == CampaignOutcome::kAccepted; }
};

struct CampaignInForce {
  std::string payload;  // the SignedCampaign as received: what is stored
  std::string campaign_bytes;
  std::string key_id;
  CompiledCampaign compiled;
};

class CampaignAuthority {
 public:
  // trusted_keys as [command.trusted_keys]; vehicle_id empty (an operator's check without
  // --vehicle) accepts any target. Throws std::invalid_argument for a key that is not a base64
  // raw Ed25519 public key, naming its id.
  CampaignAuthority(const std::map<std::string, std::string>& trusted_keys,
                    std::string vehicle_id = {}, std::vector<std::string> groups = {},
                    CampaignLimits limits = {});

  CampaignVerdict offer(std::span<const std::uint8_t> payload, Micros now,
                        CampaignTopic topic = CampaignTopic::kFleet);
  CampaignVerdict offer(std::string_view payload, Micros now,
                        CampaignTopic topic = CampaignTopic::kFleet);
  std::vector<std::string> expire(Micros now);
  const std::map<std::string, CampaignInForce, std::less<>>& in_force() const { return in_force_; }
  const CampaignLimits& limits() const { return limits_; }
  // Issue 28: how a campaign whose key id is not trusted but carries SignedCampaign.delegation
  // is judged (command::check_delegated with the action "campaign": root, scope, window,
  // revocations); unset: such a campaign is unknown_key.
  using DelegatedCheck = std::function<command::DelegatedCheck(
      const v1::SignedDelegation&, std::string_view key_id,
      std::span<const std::uint8_t> signed_bytes, std::span<const std::uint8_t> signature)>;
  void set_delegated_check(DelegatedCheck check) { delegated_check_ = std::move(check); }

 private:
  std::optional<std::string> not_for_us(const CompiledCampaign& c, CampaignTopic topic) const;
  std::optional<std::string> over_budget(const CompiledCampaign& c) const;

  std::map<std::string, command::Ed25519PublicKey, std::less<>> keys_;
  std::string vehicle_id_;
  std::vector<std::string> groups_;
  CampaignLimits limits_;
  std::map<std::string, CampaignInForce, std::less<>> in_force_;
  DelegatedCheck delegated_check_;
};

// Serialized SignedCampaign over `campaign` serialized once.
std::string sign_campaign(const v1::Campaign& campaign, const command::Ed25519PrivateKey& key,
                          std::string_view key_id);

}  // namespace fleetgw::campaign
