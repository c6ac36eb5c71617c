// Who signed a document (a zone bundle, a campaign: issues 24, 28, 29): a key of
// [command.trusted_keys], or a key a root delegated (the document's SignedDelegation, judged by
// command::check_delegated for one action). The zone and campaign authorities, and the
// `fleetgw campaign check` tool, share this one judgement, so the same document gets the same
// verdict and the same six delegation refusal names (delegation_refusal_name) everywhere.
//
// Contract (judge_document_signer, pure, never throws):
//  * key_id in `trusted`: kTrusted when that key's Ed25519 signature over `signed_bytes`
//    verifies, else kSignatureInvalid -- a trusted key id is judged as trusted even when a
//    delegation comes with it.
//  * otherwise, with a delegation and a `delegated` check: kDelegated when the delegation opens,
//    the delegate's signature verifies and the grant covers the action/vehicle/window;
//    kDelegatedSignatureInvalid when the delegate's signature does not verify; kDelegationRefused
//    with `problem` (delegation_invalid, revoked, out_of_scope, clock_unsynchronised,
//    delegation_not_yet_valid, delegation_expired) otherwise.
//  * otherwise kUnknownKey (`delegation_unjudged` tells a delegation came but nobody could
//    judge it: no [command.root_keys]).
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <string_view>

#include "gateway/command/delegation.h"
#include "gateway/command/ed25519.h"

namespace fleetgw::command {

// The delegated-key check of one action (CommandService::delegated_document_check, or the
// tool's own over [command.root_keys]).
using DelegatedDocumentCheck = std::function<DelegatedCheck(
    const v1::SignedDelegation& delegation, std::string_view signer_key_id,
    std::span<const std::uint8_t> signed_bytes, std::span<const std::uint8_t> signature)>;

enum class SignerOutcome : std::uint8_t {
  kTrusted,
  kDelegated,
  kUnknownKey,
  kSignatureInvalid,
  kDelegatedSignatureInvalid,
  kDelegationRefused,
};

struct SignerVerdict {
  SignerOutcome outcome = SignerOutcome::kUnknownKey;
  std::optional<DelegationProblem> problem;  // kDelegationRefused
  bool delegation_unjudged = false;          // kUnknownKey with a delegation nobody could judge
  bool ok() const {
    return outcome == SignerOutcome::kTrusted || outcome == SignerOutcome::kDelegated;
  }
};

SignerVerdict judge_document_signer(
    const std::map<std::string, Ed25519PublicKey, std::less<>>& trusted, std::string_view key_id,
    const v1::SignedDelegation* delegation, const DelegatedDocumentCheck& delegated,
    std::span<const std::uint8_t> signed_bytes, std::span<const std::uint8_t> signature);

// A delegation refusal as an authority's own reason: `by_reason` lists that authority's six
// reasons in DelegationRefusal order (invalid, revoked, out_of_scope, clock_unsynchronised,
// not_yet_valid, expired), so the names stay those of delegation_refusal_name.
template <typename Refusal>
Refusal delegation_refusal_as(DelegationRefusal reason, const Refusal (&by_reason)[6]) {
  return by_reason[static_cast<std::size_t>(reason)];
}

}  // namespace fleetgw::command
