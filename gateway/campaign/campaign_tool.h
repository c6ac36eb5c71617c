// `fleetgw campaign sign|check` (issue 29): the engineer's side of campaigns, like `fleetgw zones
// sign|check`. The CLI (campaign_cli.cc) parses the arguments; everything else is here, testable
// with streams.
//
// Contract:
//  * run_campaign_sign() reads a TOML or JSON campaign (campaign_file.h), sets its version when
//    `version` > 0 and issued_at, checks it with the gateway's own rules (compile_campaign: a
//    malformed file, an unknown signal, an unbounded cost are refused with the field named),
//    signs it with the Ed25519 PEM key (key id: `key_id`, by default the key file's stem) and
//    writes the SignedCampaign atomically to `out`. It prints one line: id, version, signals,
//    trigger, sampling and the cost bounds. Exit 0; 1 with a message on `err`, nothing written.
//  * run_campaign_check() judges a signed campaign file as a gateway would at `now`
//    (CampaignAuthority with the trusted keys, the root keys and the revocation list when
//    given -- a delegated key gets the bike's six delegation refusals --, the vehicle and its
//    groups when given), prints
//    the verdict and, when it authenticates and compiles, its cost. Exit 0 when a gateway
//    would accept it, 1 when it would refuse it.
#pragma once

#include <cstdint>
#include <filesystem>
#include <iosfwd>
#include <map>
#include <string>
#include <vector>

#include "motinova/can.h"

namespace fleetgw::campaign {

struct CampaignSignOptions {
  std::filesystem::path file;
  std::filesystem::path key_pem;
  std::string key_id;         // empty: the key file's stem
  std::uint64_t version = 0;  // 0: the file's
  motinova::Micros issued_at{0};
  std::filesystem::path out;
  // Issue 28: the signing key's SignedDelegation (fleetgw keys delegate, action "campaign"),
  // sent in SignedCampaign.delegation (outside the signed bytes) for a key the gateways know
  // only through their root keys. Empty: none.
  std::filesystem::path delegation{};
};
int run_campaign_sign(const CampaignSignOptions& options, std::ostream& out, std::ostream& err);

struct CampaignCheckOptions {
  std::filesystem::path signed_file;
  std::map<std::string, std::string> trusted_keys;
  std::string vehicle_id;
  std::vector<std::string> groups;
  motinova::Micros now{0};
  // Issue 28: [command.root_keys]; with them a campaign under a delegation is judged as the
  // bike judges it (command::check_delegated, action "campaign", on `now`, the tool's clock
  // taken as synchronised) instead of refused as unknown_key.
  std::map<std::string, std::string> root_keys{};
  // A root's SignedRevocationList as published (fleetgw keys revoke): the revocations the
  // bike would hold. Empty: none (the tool cannot know the bike's list otherwise).
  std::filesystem::path revocations{};
  // The store's budget ([storage] max_mb in bytes, 0: none): the campaigns' disk budgets
  // together may take at most a quarter of it, as on the bike.
  std::uint64_t store_budget_bytes = 0;
};
int run_campaign_check(const CampaignCheckOptions& options, std::ostream& out, std::ostream& err);

}  // namespace fleetgw::campaign
