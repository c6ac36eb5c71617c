// The command-line words of issue 29, registered on `fleetgw`'s CLI11 app from here so that
// gateway/cli/cli.cc carries two lines for them: `fleetgw signals [--json]` and
// `fleetgw campaign sign|check` (campaign_tool.h).
//
// Contract: add() registers the subcommands (before parsing); run() after parsing returns the
// exit status of the one that was parsed, or nullopt when none of them was.
#pragma once

#include <CLI/CLI.hpp>

#include <memory>
#include <optional>

namespace fleetgw::campaign {

class CampaignCli {
 public:
  explicit CampaignCli(CLI::App& app);
  ~CampaignCli();
  CampaignCli(const CampaignCli&) = delete;
  CampaignCli& operator=(const CampaignCli&) = delete;

  std::optional<int> run() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace fleetgw::campaign
