#include "gateway/tools/operator/keys_cli.h"

#include <chrono>
#include <iostream>

#include "gateway/config/config.h"
#include "gateway/tools/operator/keys_tool.h"

namespace fleetgw::tools {

struct KeysCli::State {
  CLI::App* root = nullptr;
  CLI::App* delegate = nullptr;
  CLI::App* revoke = nullptr;
  CLI::App* show = nullptr;
  CLI::App* publish = nullptr;
  KeysRootOptions root_options;
  KeysDelegateOptions delegate_options;
  KeysRevokeOptions revoke_options;
  KeysShowOptions show_options;
  std::string show_config;
  KeysPublishOptions publish_options;
  std::int64_t publish_timeout_s = 10;
};

namespace {

Micros keys_wall_now() {
  return std::chrono::duration_cast<Micros>(std::chrono::system_clock::now().time_since_epoch());
}

}  // namespace

KeysCli::KeysCli(CLI::App& app) : state_(std::make_unique<State>()) {
  State& s = *state_;
  auto* keys = app.add_subcommand(
      "keys", "the fleet's root key: delegate scoped, expiring signing keys, revoke them");
  keys->require_subcommand(1);

  s.root = keys->add_subcommand("root", "write a root key pair (keep the private key offline)");
  s.root
      ->add_option("--out", s.root_options.out_prefix,
                   "writes PREFIX.pem (private, 0600) and PREFIX.pub")
      ->required();
  s.root->add_option("--key-id", s.root_options.key_id, "root key id (default: PREFIX's name)");

  auto& d = s.delegate_options;
  s.delegate = keys->add_subcommand(
      "delegate", "sign a delegation: a key may sign these actions on these vehicles until then");
  s.delegate->add_option("--root", d.root_pem, "the root's private key (PEM)")->required();
  s.delegate->add_option("--root-id", d.root_id, "the root's key id ([command.root_keys])")
      ->required();
  s.delegate->add_option("--key-id", d.key_id, "the delegated key's id (SignedCommand.key_id)")
      ->required();
  auto* pub = s.delegate->add_option("--public-key", d.public_key,
                                     "the delegated public key: a .pub file or base64");
  s.delegate
      ->add_option("--new-key", d.new_key_prefix,
                   "instead: create the delegated key pair PREFIX.pem (0600) and PREFIX.pub")
      ->excludes(pub);
  s.delegate
      ->add_option("--actions", d.actions,
                   "comma-separated: lock, unlock, speed_limit, assist_level, headlight, "
                   "clear_trip, power_off, diagnostics, zones, campaign")
      ->delimiter(',')
      ->required();
  s.delegate->add_option("--vehicles", d.vehicles, "comma-separated vehicle ids")->delimiter(',');
  s.delegate->add_option("--groups", d.groups, "comma-separated [vehicle] groups")->delimiter(',');
  s.delegate->add_flag("--all-vehicles", d.all_vehicles, "every vehicle of the fleet");
  s.delegate->add_option("--not-before", d.not_before, "ISO 8601 UTC (default: now)");
  s.delegate->add_option("--not-after", d.not_after, "ISO 8601 UTC, e.g. 2027-01-01T00:00:00Z")
      ->required();
  s.delegate->add_option("--serial", d.serial, "> 0, unique per root")->required();
  s.delegate->add_option("--holder", d.holder, "who holds the key, for people");
  s.delegate->add_option("--out", d.out, "the signed delegation file to write")->required();

  auto& r = s.revoke_options;
  s.revoke = keys->add_subcommand(
      "revoke", "sign a revocation list (it replaces the root's previous one on the gateways)");
  s.revoke->add_option("--root", r.root_pem, "the root's private key (PEM)")->required();
  s.revoke->add_option("--root-id", r.root_id, "the root's key id")->required();
  s.revoke->add_option("--version", r.version, "> the version the gateways hold")->required();
  s.revoke->add_option("--serial", r.serials, "revoked delegation serials (repeat or commas)")
      ->delimiter(',');
  s.revoke->add_option("--key-id", r.key_ids, "key ids revoked outright (repeat or commas)")
      ->delimiter(',');
  s.revoke->add_option("--out", r.out, "the signed revocation list file to write")->required();

  s.show = keys->add_subcommand("show", "print and check a delegation or revocation list file");
  s.show->add_option("file", s.show_options.file, "the signed file")->required();
  s.show->add_option("--config", s.show_config,
                     "check the root's signature with this configuration's [command.root_keys]");

  auto& p = s.publish_options;
  s.publish = keys->add_subcommand(
      "publish-revocations", "publish a revocation list, retained, to vehicles' revocations topic");
  s.publish->add_option("file", p.file, "the signed revocation list file")->required();
  s.publish->add_option("--vehicle", p.vehicles, "vehicle id (repeat or commas)")
      ->delimiter(',')
      ->required();
  s.publish->add_option("--broker", p.broker, "broker URI")->required();
  s.publish->add_option("--ca-file", p.ca_file, "CA bundle (TLS)");
  s.publish->add_option("--cert-file", p.cert_file, "client certificate (mutual TLS)");
  s.publish->add_option("--key-file", p.key_file, "client key (mutual TLS)");
  s.publish->add_option("--username", p.username, "user name");
  s.publish->add_option("--password", p.password, "password (never logged)");
  s.publish->add_option("--topic-prefix", p.topic_prefix, "topic prefix (default fleet/v1)");
  s.publish->add_option("--timeout-s", s.publish_timeout_s, "connect and acknowledge timeout")
      ->check(CLI::Range(1, 600));
}

KeysCli::~KeysCli() = default;

std::optional<int> KeysCli::run() const {
  const State& s = *state_;
  if (s.root->parsed()) return run_keys_root(s.root_options, std::cout, std::cerr);
  if (s.delegate->parsed()) {
    auto options = s.delegate_options;
    options.now = keys_wall_now();
    return run_keys_delegate(options, std::cout, std::cerr);
  }
  if (s.revoke->parsed()) {
    auto options = s.revoke_options;
    options.now = keys_wall_now();
    return run_keys_revoke(options, std::cout, std::cerr);
  }
  if (s.show->parsed()) {
    auto options = s.show_options;
    options.now = keys_wall_now();
    if (!s.show_config.empty()) {
      options.root_keys = config::load_config(s.show_config).command.root_keys;
      options.check_signature = true;
    }
    return run_keys_show(options, std::cout, std::cerr);
  }
  if (s.publish->parsed()) {
    auto options = s.publish_options;
    options.timeout = std::chrono::seconds(s.publish_timeout_s);
    return run_keys_publish_revocations(options, std::cout, std::cerr);
  }
  return std::nullopt;
}

}  // namespace fleetgw::tools
