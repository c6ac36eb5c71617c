#include "gateway/command/document_signer.h"

namespace fleetgw::command {

SignerVerdict judge_document_signer(
    const std::map<std::string, Ed25519PublicKey, std::less<>>& trusted, std::string_view key_id,
    const v1::SignedDelegation* delegation, const DelegatedDocumentCheck& delegated,
    std::span<const std::uint8_t> signed_bytes, std::span<const std::uint8_t> signature) {
  SignerVerdict v;
  if (const auto key = trusted.find(key_id); key != trusted.end()) {
    v.outcome = key->second.verify(signed_bytes, signature) ? SignerOutcome::kTrusted
                                                            : SignerOutcome::kSignatureInvalid;
    return v;
  }
  if (delegation == nullptr || !delegated) {
    v.outcome = SignerOutcome::kUnknownKey;
    v.delegation_unjudged = delegation != nullptr;
    return v;
  }
  auto check = delegated(*delegation, key_id, signed_bytes, signature);
  if (check.signature_invalid) {
    v.outcome = SignerOutcome::kDelegatedSignatureInvalid;
  } else if (check.problem) {
    v.outcome = SignerOutcome::kDelegationRefused;
    v.problem = std::move(check.problem);
  } else {
    v.outcome = SignerOutcome::kDelegated;
  }
  return v;
}

}  // namespace fleetgw::command
