#include "gateway/campaign/campaign_cli.h"

#include <algorithm>
#include <chrono>
#include <iostream>

#include "gateway/campaign/campaign_tool.h"
#include "gateway/campaign/signals_command.h"
#include "gateway/config/config.h"

namespace fleetgw::campaign {

struct CampaignCli::State {
  CLI::App* signals = nullptr;
  bool signals_json = false;
  CLI::App* sign = nullptr;
  CLI::App* check = nullptr;
  CampaignSignOptions sign_options;
  CampaignCheckOptions check_options;
  std::string check_config;
};

namespace {

motinova::Micros wall_now() {
  return std::chrono::duration_cast<motinova::Micros>(
      std::chrono::system_clock::now().time_since_epoch());
}

}  // namespace

CampaignCli::CampaignCli(CLI::App& app) : state_(std::make_unique<State>()) {
  state_->signals = app.add_subcommand(
      "signals", "list the signal catalogue: every decoded field a campaign may collect");
  state_->signals->add_flag("--json", state_->signals_json, "one JSON array instead of a table");

  auto* campaign = app.add_subcommand(
      "campaign", "sign a collection campaign from a TOML or JSON file, or check a signed one");
  campaign->require_subcommand(1);
  auto& s = state_->sign_options;
  state_->sign = campaign->add_subcommand("sign", "campaign file -> a signed campaign file");
  state_->sign->add_option("file", s.file, "campaign (TOML or JSON)")->required();
  state_->sign->add_option("--key", s.key_pem, "Ed25519 private key (PEM)")->required();
  state_->sign->add_option("--key-id", s.key_id, "key id (default: the key file's name)");
  state_->sign->add_option("--version", s.version, "campaign version (default: the file's)");
  state_->sign->add_option("--out", s.out, "signed campaign file to write")->required();
  state_->sign->add_option("--delegation", s.delegation,
                           "the key's signed delegation (fleetgw keys delegate, action campaign)");
  auto& c = state_->check_options;
  state_->check = campaign->add_subcommand("check", "judge a signed campaign as a gateway would");
  state_->check->add_option("signed", c.signed_file, "signed campaign file")->required();
  state_->check
      ->add_option("--config", state_->check_config,
                   "configuration with [command.trusted_keys] and/or [command.root_keys] "
                   "(and [vehicle])")
      ->required();
  state_->check->add_option(
      "--revocations", c.revocations,
      "a root's signed revocation list (fleetgw keys revoke) the gateway would hold");
  state_->check->add_option("--vehicle", c.vehicle_id,
                            "judge as this vehicle's gateway (default: the configuration's)");
}

CampaignCli::~CampaignCli() = default;

std::optional<int> CampaignCli::run() const {
  if (state_->signals->parsed()) return run_signals(state_->signals_json, std::cout);
  if (state_->sign->parsed()) {
    auto options = state_->sign_options;
    options.issued_at = wall_now();
    return run_campaign_sign(options, std::cout, std::cerr);
  }
  if (state_->check->parsed()) {
    auto options = state_->check_options;
    const auto config = config::load_config(state_->check_config);
    options.trusted_keys = config.command.trusted_keys;
    options.root_keys = config.command.root_keys;
    options.store_budget_bytes = static_cast<std::uint64_t>(std::max(config.storage.max_mb, 0))
                                 << 20;
    if (options.vehicle_id.empty()) options.vehicle_id = config.vehicle.id;
    options.groups = config.vehicle.groups;
    options.now = wall_now();
    return run_campaign_check(options, std::cout, std::cerr);
  }
  return std::nullopt;
}

}  // namespace fleetgw::campaign
