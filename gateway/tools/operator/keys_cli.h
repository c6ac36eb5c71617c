// The command-line words of issue 28, registered on `fleetgw`'s CLI11 app from here so that
// gateway/cli/cli.cc carries two lines for them: `fleetgw keys root|delegate|revoke|show|
// publish-revocations` (keys_tool.h). Their manual page and bash completion come from these
// definitions (deploy/man/make-man-pages.sh, completion.h).
//
// Contract: the constructor registers the subcommands (before parsing); run() after parsing
// returns the exit status of the one that was parsed, or nullopt when none of them was.
#pragma once

#include <CLI/CLI.hpp>

#include <memory>
#include <optional>

namespace fleetgw::tools {

class KeysCli {
 public:
  explicit KeysCli(CLI::App& app);
  ~KeysCli();
  KeysCli(const KeysCli&) = delete;
  KeysCli& operator=(const KeysCli&) = delete;

  std::optional<int> run() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace fleetgw::tools
