#include "gateway/cli/cli.h"

#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <unistd.h>

#include <iostream>
#include <optional>
#include <sstream>

#include "backend/app/ingest_command.h"
#include "gateway/campaign/campaign_cli.h"
#include "gateway/cli/check_config.h"
#include "gateway/cli/completion.h"
#include "gateway/cli/logging.h"
#include "gateway/cli/sibling_program.h"
#include "gateway/common/untrusted_text.h"
#include "gateway/config/config.h"
#include "gateway/decode/decode_command.h"
#include "gateway/geofence/zone_tool.h"
#include "gateway/runtime/recorder.h"
#include "gateway/runtime/service.h"
#include "gateway/sim/sim_bus.h"
#include "gateway/sim/sim_command.h"
#include "gateway/status/status_command.h"
#include "gateway/tools/common/table_format.h"
#include "gateway/tools/operator/command_tool.h"
#include "gateway/tools/operator/keys_cli.h"
#include "gateway/tools/operator/watch_command.h"
#include "gateway/tools/store/db_command.h"
#include "gateway/tools/store/ride_command.h"

namespace fleetgw::cli {
namespace {

// Protocol options shared by every subcommand that decodes: flags override the config file.
struct ProtocolFlags {
  std::string config_file;
  std::string crc_order, byte_order, mc_fault_layout, bms_fault_layout, other_fault_layout,
      mc_vi_order, bms_current_sign, lock_kinds, mc_answer_id, wheel_size_unit, wheel_adjust_unit,
      pack_stats_currents, pack_stats_time_unit, pack_stats_counter_order;
  std::vector<std::string> assist_names, fault_names;
  bool mc_current_signed = false;

  void add_to(CLI::App& cmd) {
    cmd.add_option("--config", config_file, "take the [protocol] options from this config file");
    cmd.add_option("--crc-order", crc_order, "U1: CRC byte order")
        ->check(CLI::IsMember({"be", "le", "auto"}));
    cmd.add_option("--byte-order", byte_order, "U2: data byte order")
        ->check(CLI::IsMember({"be", "le"}));
    const auto layouts = CLI::IsMember({"documented", "swapped", "two_words_low_first"});
    cmd.add_option("--mc-fault-layout", mc_fault_layout, "U3: MC fault word layout")
        ->check(layouts);
    cmd.add_option("--bms-fault-layout", bms_fault_layout, "U3: BMS fault word layout")
        ->check(layouts);
    cmd.add_option("--other-fault-layout", other_fault_layout, "U3: OBC/IOT/lock fault words")
        ->check(layouts);
    cmd.add_option("--mc-voltage-current", mc_vi_order, "U9: MC voltage/current order")
        ->check(CLI::IsMember({"voltage_first", "current_first", "auto"}));
    cmd.add_option("--bms-current-sign", bms_current_sign, "U4: which BMS current is positive")
        ->check(CLI::IsMember({"charge_positive", "discharge_positive"}));
    cmd.add_flag("--mc-current-signed", mc_current_signed, "U4: MC bus current is signed");
    cmd.add_option(
        "--lock-kinds", lock_kinds,
        "U21: comma-separated lock kinds of LOCK 1..5, e.g. seat,frame,steering,battery,other");
    add_uncertain_to(cmd);
  }

  void add_uncertain_to(CLI::App& cmd) {
    cmd.add_option("--mc-answer-id", mc_answer_id, "U14: ID the MC answers reads on")
        ->check(CLI::IsMember({"0x713", "0x716", "0x710", "auto"}));
    cmd.add_option("--wheel-size-unit", wheel_size_unit, "U11: what MC settings byte 0 counts")
        ->check(CLI::IsMember({"circumference_cm", "diameter_cm", "diameter_inch"}));
    cmd.add_option("--wheel-adjust-unit", wheel_adjust_unit, "U11: unit of the wheel adjust")
        ->check(CLI::IsMember({"cm", "mm"}));
    cmd.add_option("--pack-stats-currents", pack_stats_currents,
                   "U17: which maximum current comes first in 0x725/0x5028")
        ->check(CLI::IsMember({"discharge_first", "charge_first"}));
    cmd.add_option("--pack-stats-time-unit", pack_stats_time_unit,
                   "U17: unit of the charging-time statistics")
        ->check(CLI::IsMember({"h", "min"}));
    cmd.add_option("--pack-stats-counter-order", pack_stats_counter_order,
                   "U17: comma-separated names of the nine 0x5028 counters in wire order");
    cmd.add_option("--assist-name", assist_names, "U7: VALUE=NAME, e.g. 0x33=smart (repeatable)");
    cmd.add_option("--fault-name", fault_names,
                   "U6/U18/U20/U22: SOURCE:BIT=NAME, SOURCE mc|bms|iot|lock, e.g. "
                   "mc:high_0x0020=te_comm_fault (repeatable)");
  }

  static std::vector<std::string> split(const std::string& text, char sep) {
    std::vector<std::string> out;
    std::size_t start = 0;
    while (true) {
      const auto at = text.find(sep, start);
      out.push_back(text.substr(start, at == std::string::npos ? std::string::npos : at - start));
      if (at == std::string::npos) return out;
      start = at + 1;
    }
  }

  void resolve_uncertain(motinova::DecodeOptions& p) const {
    if (!mc_answer_id.empty()) p.mc_answer_id = config::parse_mc_answer_id(mc_answer_id);
    if (!wheel_size_unit.empty()) {
      p.wheel_size_unit = config::parse_wheel_size_unit(wheel_size_unit);
    }
    if (!wheel_adjust_unit.empty()) {
      p.wheel_adjust_unit = config::parse_wheel_adjust_unit(wheel_adjust_unit);
    }
    if (!pack_stats_currents.empty()) {
      p.pack_stats_discharge_current_first = pack_stats_currents == "discharge_first";
    }
    if (!pack_stats_time_unit.empty()) {
      p.pack_stats_time_unit = pack_stats_time_unit == "min" ? motinova::PackTimeUnit::kMinutes
                                                             : motinova::PackTimeUnit::kHours;
    }
    if (!pack_stats_counter_order.empty()) {
      const auto why =
          config::set_pack_stats_counter_order(p, split(pack_stats_counter_order, ','));
      if (!why.empty()) throw CLI::ValidationError("--pack-stats-counter-order", why);
    }
    for (const auto& a : assist_names) {
      const auto eq = a.find('=');
      const auto why = eq == std::string::npos
                           ? std::string("expected VALUE=NAME")
                           : config::set_assist_name(p, a.substr(0, eq), a.substr(eq + 1));
      if (!why.empty()) throw CLI::ValidationError("--assist-name", why);
    }
    for (const auto& f : fault_names) {
      const auto colon = f.find(':');
      const auto eq = f.find('=');
      std::string why = "expected SOURCE:BIT=NAME with SOURCE mc, bms, iot or lock";
      if (colon != std::string::npos && eq != std::string::npos && colon < eq) {
        const std::string source = f.substr(0, colon);
        const std::pair<const char*, motinova::FaultSource> sources[] = {
            {"mc", motinova::FaultSource::kMc},
            {"bms", motinova::FaultSource::kBms},
            {"iot", motinova::FaultSource::kIot},
            {"lock", motinova::FaultSource::kLock}};
        for (const auto& [name, s] : sources) {
          if (source == name) {
            why =
                config::set_fault_name(p, s, f.substr(colon + 1, eq - colon - 1), f.substr(eq + 1));
          }
        }
      }
      if (!why.empty()) throw CLI::ValidationError("--fault-name", why);
    }
  }

  motinova::DecodeOptions resolve() const {
    motinova::DecodeOptions p =
        config_file.empty() ? motinova::DecodeOptions{} : config::load_config(config_file).protocol;
    if (!crc_order.empty()) p.crc_order = config::parse_crc_order(crc_order);
    if (!byte_order.empty()) p.data_order = config::parse_byte_order(byte_order);
    if (!mc_fault_layout.empty()) p.mc_fault_layout = config::parse_fault_layout(mc_fault_layout);
    if (!bms_fault_layout.empty())
      p.bms_fault_layout = config::parse_fault_layout(bms_fault_layout);
    if (!other_fault_layout.empty()) {
      p.other_fault_layout = config::parse_fault_layout(other_fault_layout);
    }
    if (!mc_vi_order.empty()) p.mc_voltage_current_order = config::parse_mc_vi_order(mc_vi_order);
    if (!bms_current_sign.empty())
      p.bms_current_charge_positive = bms_current_sign == "charge_positive";
    if (mc_current_signed) p.mc_current_signed = true;
    if (!lock_kinds.empty()) {
      std::array<std::string, 5> kinds{};
      std::size_t i = 0, start = 0;
      while (start <= lock_kinds.size()) {
        const auto comma = lock_kinds.find(',', start);
        const auto end = comma == std::string::npos ? lock_kinds.size() : comma;
        if (i >= kinds.size()) throw CLI::ValidationError("--lock-kinds", "at most 5 lock kinds");
        kinds[i++] = lock_kinds.substr(start, end - start);
        if (comma == std::string::npos) break;
        start = comma + 1;
      }
      p.lock_kinds = kinds;
    }
    resolve_uncertain(p);
    return p;
  }
};

// `fleetgw status --format`: the summary, the raw document, or the document as key,value CSV
// (same exit codes whatever the form).
int run_status(status::StatusCommandOptions options, const std::string& format, std::ostream& out,
               std::ostream& err) {
  if (format == "json") options.json = true;
  if (format != "csv") return status::run_status_command(options, out, err);
  options.json = true;
  std::ostringstream doc;
  const int rc = status::run_status_command(options, doc, err);
  if (rc != status::kStatusUnreachable) {
    tools::write_csv(tools::flatten(nlohmann::json::parse(doc.str(), nullptr, false)), out);
  }
  return rc;
}

// The command path of argv checked against the command tree before CLI11 parses it: CLI11
// takes a mistyped command for an extra argument and reports the missing subcommand instead ("A
// subcommand is required"), and with --help after it prints the top-level help and exits 0, so
// a script's typo would pass for success. Returns the error text for the first word that names
// no command where one is required (argv is untrusted: shown escaped), or nothing. An option
// ends the check: CLI11 handles options (the command groups take none of their own).
std::optional<std::string> unknown_command(const CLI::App& app, int argc, char** argv) {
  const CLI::App* level = &app;
  std::string path = "fleetgw";
  std::string words;
  for (int i = 1; i < argc && level->get_require_subcommand_min() > 0; ++i) {
    const std::string word = argv[i];
    if (word.starts_with('-')) return std::nullopt;
    const auto found =
        level->get_subcommands([&word](const CLI::App* s) { return s->check_name(word); });
    words += (words.empty() ? "" : " ") + common::escape_controls(word);
    if (found.empty()) return "unknown command '" + words + "'; see " + path + " --help";
    level = found.front();
    path += " " + level->get_name();
  }
  return std::nullopt;
}

}  // namespace

int run_cli(int argc, char** argv) {
  CLI::App app{"fleetgw: MOTINOVA e-bike fleet telemetry gateway"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("fleetgw ") + FLEETGW_VERSION);

  // decode
  auto* decode_cmd = app.add_subcommand("decode", "decode a candump -L log into JSON lines");
  decode::DecodeCommandOptions decode_options;
  ProtocolFlags decode_flags;
  int gap_ms = 100;
  decode_cmd->add_option("file", decode_options.input, "candump -L log, or - for stdin");
  decode_cmd->add_flag("--errors", decode_options.print_errors,
                       "also print one JSON line per error");
  decode_cmd->add_option("--gap-ms", gap_ms, "drop a partial message after this gap (U15)")
      ->check(CLI::Range(1, 60'000));
  decode_flags.add_to(*decode_cmd);
  std::string decode_format;
  decode_cmd
      ->add_option("--format", decode_format,
                   "the summary on stderr: table (one line for people, the default), json (one "
                   "object) or csv (key,value rows)")
      ->check(CLI::IsMember({"table", "json", "csv"}));

  // check-config
  auto* check_cmd = app.add_subcommand("check-config", "validate a configuration file");
  std::string check_file;
  check_cmd->add_option("file", check_file, "configuration file")->required();

  // run
  auto* run_cmd = app.add_subcommand("run", "run the gateway service");
  std::string run_config;
  double run_duration = 0;
  bool run_live = false;
  std::string run_transport, run_scenario, run_replay;
  double run_sim_speed = 0;
  run_cmd->add_option("--config", run_config, "configuration file (TOML)")->required();
  run_cmd->add_option("--duration", run_duration, "stop after this many seconds")
      ->check(CLI::PositiveNumber);
  double run_bus_duration = 0;
  run_cmd
      ->add_option("--bus-duration", run_bus_duration,
                   "stop after this many seconds of bus time (simulated or replayed)")
      ->check(CLI::PositiveNumber);
  run_cmd->add_flag("--live", run_live, "print a live view of the bike every second");
  run_cmd->add_option("--transport", run_transport, "override can.transport")
      ->check(CLI::IsMember({"socketcan", "replay", "udp", "sim"}));
  run_cmd->add_option("--scenario", run_scenario, "override sim.scenario");
  run_cmd->add_option("--sim-speed", run_sim_speed, "override sim.speed (time acceleration)")
      ->check(CLI::PositiveNumber);
  run_cmd->add_option("--replay", run_replay, "replay this candump -L log (sets transport)");

  // sim
  auto* sim_cmd = app.add_subcommand("sim", "run the simulated e-bike on a bus or into a log");
  sim::SimCliOptions sim_options;
  double sim_duration = 0;
  uint64_t sim_seed = 0;
  sim_cmd->add_option("--scenario", sim_options.scenario, "scenario file (TOML)")->required();
  sim_cmd->add_option("--speed", sim_options.speed, "time acceleration (1 = real time)")
      ->check(CLI::PositiveNumber);
  sim_cmd->add_option("--seed", sim_seed, "override the scenario's seed");
  sim_cmd->add_option("--duration", sim_duration, "seconds of scenario time to run")
      ->check(CLI::PositiveNumber);
  sim_cmd->add_option("--bus", sim_options.bus,
                      "udp:<local port>:<remote port>, udp:<laddr>:<lport>:<raddr>:<rport> or "
                      "socketcan:<ifname>");
  sim_cmd->add_option("--record", sim_options.record, "write a candump -L log instead");
  sim_cmd->add_option("--nmea-pty", sim_options.nmea_pty,
                      "serve the scenario's [[route]] as NMEA (GGA+RMC, 1 Hz of bus time) on a "
                      "pty linked at PATH, for gpsd");

  // db
  auto db = tools::add_db_command(app);

  // ride
  auto ride = tools::add_ride_command(app);

  // watch
  // Options are validated here (so `fleetgw watch --help` and typos behave like every other
  // subcommand), then the same arguments go to fleetgw-watch.
  auto* watch_cmd = app.add_subcommand("watch", "print the Envelopes a broker receives, as JSON");
  tools::WatchOptions watch_options;
  tools::add_watch_options(*watch_cmd, watch_options);

  // ingest: validated here, run by fleetgw-ingest (libpq stays out of this binary)
  auto* ingest_cmd = app.add_subcommand(
      "ingest", "write the fleet's Envelopes from an MQTT 5 shared subscription into PostgreSQL");
  ingest::IngestOptions ingest_options;
  app::add_ingest_options(*ingest_cmd, ingest_options);  // backend/app, the ingest program

  // fleet-sim: every argument (--help too) goes to fleetgw-fleet-sim, a backend program
  auto* fleet_sim_cmd = app.add_subcommand(
      "fleet-sim", "N simulated vehicles, each with its own MQTT 5 session, against a broker");
  fleet_sim_cmd->prefix_command()->set_help_flag();

  // serve: every argument (--help too) goes to fleetgw-serve, the backend's web server
  auto* serve_cmd = app.add_subcommand(
      "serve", "the operator console and API over the ingest's PostgreSQL (fleetgw-serve)");
  serve_cmd->prefix_command()->set_help_flag();

  // status
  auto* status_cmd = app.add_subcommand(
      "status", "health of the running service (exit 1: needs attention, 3: no answer)");
  status::StatusCommandOptions status_options;
  std::string status_config;
  auto* status_socket_opt =
      status_cmd->add_option("--socket", status_options.socket_path, "status socket")
          ->capture_default_str();
  status_cmd
      ->add_option("--config", status_config,
                   "take the socket from this configuration file (status.socket)")
      ->excludes(status_socket_opt);
  std::string status_format;
  auto* status_format_opt =
      status_cmd
          ->add_option("--format", status_format,
                       "table: the summary (default); json: the raw document; csv: the document "
                       "flattened to key,value rows")
          ->check(CLI::IsMember({"table", "json", "csv"}));
  status_cmd->add_flag("--json", status_options.json, "print the raw JSON document (--format json)")
      ->excludes(status_format_opt);

  // keygen
  auto* keygen_cmd = app.add_subcommand("keygen", "write an Ed25519 key pair for signing commands");
  std::string keygen_prefix;
  keygen_cmd
      ->add_option("prefix", keygen_prefix, "writes PREFIX.pem (private, 0600) and PREFIX.pub")
      ->required();

  // zones (issue 14): signed geofence bundles from GeoJSON, and their check
  auto* zones_cmd = app.add_subcommand(
      "zones", "sign a geofence bundle from GeoJSON or GBFS, check one, export one as GBFS");
  zones_cmd->require_subcommand(1);
  auto* zones_sign_cmd =
      zones_cmd->add_subcommand("sign", "GeoJSON or GBFS zones -> a signed zone bundle file");
  geofence::ZonesSignOptions zones_sign;
  zones_sign_cmd
      ->add_option("geojson", zones_sign.geojson,
                   "GeoJSON FeatureCollection of zones, or GBFS geofencing_zones.json")
      ->required();
  zones_sign_cmd->add_option("--version", zones_sign.version, "bundle version (> the one in force)")
      ->required();
  zones_sign_cmd->add_option("--key", zones_sign.key_pem, "Ed25519 private key (PEM)")->required();
  zones_sign_cmd->add_option("--key-id", zones_sign.key_id,
                             "key id (default: the key file's stem)");
  zones_sign_cmd->add_option("--out", zones_sign.out, "signed bundle file to write")->required();
  zones_sign_cmd->add_option("--vehicle", zones_sign.vehicle_id,
                             "sign for this vehicle only (default: fleet-wide)");
  zones_sign_cmd->add_option("--delegation", zones_sign.delegation,
                             "the key's signed delegation (fleetgw keys delegate, action zones)");
  zones_sign_cmd->add_option("--mds-geography", zones_sign.mds_geography,
                             "the input is an MDS 2.0 Policy (speed rules); this its Geography");
  auto* zones_check_cmd = zones_cmd->add_subcommand(
      "check", "judge a signed zone bundle as a gateway would (keys from --config)");
  geofence::ZonesCheckOptions zones_check;
  std::string zones_config, zones_in_force;
  zones_check_cmd->add_option("bundle", zones_check.bundle, "signed zone bundle file")->required();
  zones_check_cmd->add_option("--config", zones_config, "configuration with [command.trusted_keys]")
      ->required();
  zones_check_cmd->add_option("--in-force", zones_in_force,
                              "the bundle in force (a gateway's stored file) to compare with");
  zones_check_cmd->add_option("--vehicle", zones_check.vehicle_id,
                              "judge as this vehicle's gateway (a bundle for another is refused)");
  // issue 27: the bundle in force (or a signed file) back as GBFS v3.0 geofencing_zones.json
  auto* zones_export_cmd = zones_cmd->add_subcommand(
      "export", "a signed zone bundle (default: the one in force) as GBFS geofencing_zones.json");
  geofence::ZonesExportOptions zones_export;
  std::string zones_export_config;
  zones_export_cmd->add_option("bundle", zones_export.bundle,
                               "signed zone bundle file (default: --config's bundle_file)");
  zones_export_cmd->add_option("--config", zones_export_config,
                               "configuration: [command.trusted_keys] to check the signature, "
                               "[geofence] bundle_file, [vehicle] id");
  zones_export_cmd->add_option("--out", zones_export.out_file, "write here (default: stdout)");
  zones_export_cmd->add_option("--ttl", zones_export.ttl_s, "the feed's ttl, seconds (default 0)");

  // command
  campaign::CampaignCli campaign_cli(app);  // signals, campaign sign|check (issue 29)
  tools::KeysCli keys_cli(app);             // keys root|delegate|revoke|show|... (issue 28)
  auto* command_cmd = app.add_subcommand(
      "command",
      "sign and send a remote command (lock/unlock, speed limit, assist, lights, "
      "clear trip, power off), wait for its result");
  command::CommandToolOptions cmd_options;
  int64_t cmd_timeout_s = 10, cmd_expires_s = 60;
  command_cmd->add_option("--vehicle", cmd_options.vehicle, "vehicle id")->required();
  command_cmd->add_option("--lock", cmd_options.lock,
                          "lock kind (seat, battery, frame...) or vehicle; with --action");
  command_cmd->add_option("--action", cmd_options.action, "lock or unlock (with --lock)")
      ->check(CLI::IsMember({"lock", "unlock"}));
  // MC actions (issue 13): one action per command; run_command_tool() checks there is one.
  int cmd_speed_limit = 0;
  command_cmd->add_option("--speed-limit", cmd_speed_limit, "set the speed limit, km/h")
      ->check(CLI::Range(0, 255));
  // Names are the gateway's [protocol.assist_names] (U7), so any well-formed name goes.
  command_cmd->add_option("--assist", cmd_options.assist,
                          "set the assist level (off, eco, norm, sport, turbo, walk...)");
  command_cmd->add_option("--lights", cmd_options.lights, "switch the headlight")
      ->check(CLI::IsMember({"on", "off"}));
  command_cmd->add_flag("--clear-trip", cmd_options.clear_trip, "reset the trip distance and time");
  command_cmd->add_flag("--power-off", cmd_options.power_off,
                        "power the bike off (refused while it or a lock moves)");
  // Diagnostic reads (issue 29): the block names are checked by run_command_tool().
  command_cmd->add_option("--diag", cmd_options.diag,
                          "read a diagnostic block (mc_settings, bms_cells, mc_lifetime, ...; "
                          "lock_model with --lock)");
  command_cmd->add_flag("--captured", cmd_options.captured,
                        "with --diag mc_lifetime|pack_lifetime: the record last seen on the bus");
  command_cmd->add_option("--key", cmd_options.key, "Ed25519 private key (PEM)")->required();
  command_cmd->add_option("--key-id", cmd_options.key_id,
                          "key id (default: the delegation's, else the key file's stem)");
  command_cmd->add_option("--delegation", cmd_options.delegation,
                          "the key's signed delegation (fleetgw keys delegate), sent along");
  command_cmd->add_option("--operator", cmd_options.operator_id,
                          "who asks: Command.operator_id, echoed in the result");
  command_cmd->add_option("--broker", cmd_options.broker, "broker URI")->required();
  command_cmd->add_option("--ca-file", cmd_options.ca_file, "CA bundle (TLS)");
  command_cmd->add_option("--cert-file", cmd_options.cert_file, "client certificate (mutual TLS)");
  command_cmd->add_option("--key-file", cmd_options.key_file, "client key (mutual TLS)");
  command_cmd->add_option("--username", cmd_options.username, "user name");
  command_cmd->add_option("--password", cmd_options.password, "password (never logged)");
  command_cmd->add_option("--topic-prefix", cmd_options.topic_prefix, "topic prefix");
  command_cmd->add_option("--timeout-s", cmd_timeout_s, "wait this long for the result")
      ->check(CLI::Range(1, 3600));
  command_cmd->add_option("--expires-in-s", cmd_expires_s, "command validity")
      ->check(CLI::Range(1, 86400));
  command_cmd
      ->add_option("--mqtt-version", cmd_options.mqtt_version,
                   "MQTT protocol: 5 (the broker drops the command when it expires) or 3.1.1")
      ->check(CLI::IsMember({"5", "3.1.1"}));

  // completion (hidden): the bash completion script, from every definition above
  auto* completion_cmd = add_completion_command(app);

  if (const auto unknown = unknown_command(app, argc, argv)) {
    std::cerr << "fleetgw: " << *unknown << '\n';
    return 2;
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help and --version are "errors" with code 0; every usage error is exit 2, the usual
    // convention (CLI11's own codes, 104-109, mean nothing to a shell script).
    return app.exit(e) == 0 ? 0 : 2;
  }

  try {
    if (decode_cmd->parsed()) {
      // Waiting silently for a log typed at the keyboard looks like a hang: show the usage.
      if (decode_cmd->count("file") == 0 && ::isatty(STDIN_FILENO)) {
        std::cerr << decode_cmd->help()
                  << "\nno log given: pass a candump -L file, or pipe one "
                     "in (candump -L can0 | fleetgw decode)\n";
        return 2;
      }
      decode_options.protocol = decode_flags.resolve();
      decode_options.gap_timeout = motinova::Micros(int64_t{gap_ms} * 1000);
      decode_options.summary_format =
          tools::parse_output_format(decode_format).value_or(tools::OutputFormat::kTable);
      return decode::run_decode(decode_options, std::cout, std::cerr);
    }
    if (run_cmd->parsed()) {
      // The same checks as check-config, after the command line's overrides.
      const config::Config cfg = load_runnable_config(run_config, [&](config::Config& c) {
        if (!run_transport.empty()) c.can.transport = run_transport;
        if (!run_scenario.empty()) c.sim.scenario = run_scenario;
        if (run_sim_speed > 0) c.sim.speed = run_sim_speed;
        if (!run_replay.empty()) {
          c.can.transport = "replay";
          c.can.replay_file = run_replay;
        }
      });
      setup_logging(cfg.log.level);
      runtime::ServiceOptions opts;
      if (run_duration > 0) {
        opts.duration = std::chrono::milliseconds(static_cast<int64_t>(run_duration * 1000));
      }
      if (run_bus_duration > 0) {
        opts.bus_duration = motinova::Micros(static_cast<int64_t>(run_bus_duration * 1e6));
      }
      opts.live_view = run_live;
      opts.open_sim = sim::open_sim_bus;
      return runtime::run_service(cfg, opts);
    }
    if (sim_cmd->parsed()) {
      if (sim_seed) sim_options.seed = sim_seed;
      if (sim_duration > 0) sim_options.duration_s = sim_duration;
      setup_logging("info");
      return sim::run_sim(sim_options);
    }
    if (db->command->parsed()) {
      // stdout is the data (JSON, CSV): the store's log lines go to stderr.
      setup_logging("warn");
      db->stdout_is_terminal = ::isatty(STDOUT_FILENO) != 0;
      return tools::run_db_command(*db, std::cout, std::cerr);
    }
    if (ride->command->parsed()) {
      setup_logging("warn");  // the store's log lines on stderr
      return tools::run_ride_command(*ride, std::cout, std::cerr);
    }
    if (watch_cmd->parsed()) {
      return exec_subcommand_program("fleetgw-watch", "watch", argc, argv);
    }
    if (fleet_sim_cmd->parsed()) {
      return exec_subcommand_program("fleetgw-fleet-sim", "fleet-sim", argc, argv);
    }
    if (ingest_cmd->parsed()) {
      return exec_subcommand_program("fleetgw-ingest", "ingest", argc, argv);
    }
    if (serve_cmd->parsed()) {
      return exec_subcommand_program("fleetgw-serve", "serve", argc, argv);
    }
    if (status_cmd->parsed()) {
      if (!status_config.empty()) {
        status_options.socket_path = config::load_config(status_config).status.socket;
        if (status_options.socket_path.empty()) {
          std::cerr << "fleetgw status: " << status_config
                    << " turns the status socket off (status.socket = \"\")\n";
          return status::kStatusUnreachable;
        }
      }
      return run_status(status_options, status_format, std::cout, std::cerr);
    }
    if (const auto status = campaign_cli.run()) return *status;
    if (const auto status = keys_cli.run()) return *status;
    if (keygen_cmd->parsed()) return command::run_keygen(keygen_prefix, std::cout);
    if (zones_sign_cmd->parsed()) {
      zones_sign.issued_at = std::chrono::duration_cast<std::chrono::microseconds>(
          std::chrono::system_clock::now().time_since_epoch());
      return geofence::run_zones_sign(zones_sign, std::cout, std::cerr);
    }
    if (zones_check_cmd->parsed()) {
      zones_check.trusted_keys = config::load_config(zones_config).command.trusted_keys;
      if (!zones_in_force.empty()) zones_check.in_force = zones_in_force;
      return geofence::run_zones_check(zones_check, std::cout, std::cerr);
    }
    if (zones_export_cmd->parsed()) {
      if (!zones_export_config.empty()) {
        const auto c = config::load_config(zones_export_config);
        zones_export.trusted_keys = c.command.trusted_keys;
        zones_export.vehicle_id = c.vehicle.id;
        if (zones_export.bundle.empty()) zones_export.bundle = c.geofence.bundle_file;
      }
      if (zones_export.bundle.empty()) {
        std::cerr << "fleetgw zones export: name a bundle file or --config\n";
        return 2;
      }
      return geofence::run_zones_export(zones_export, std::cout, std::cerr);
    }
    if (command_cmd->parsed()) {
      cmd_options.timeout = std::chrono::seconds(cmd_timeout_s);
      cmd_options.expires_in = std::chrono::seconds(cmd_expires_s);
      if (command_cmd->count("--speed-limit") > 0) cmd_options.speed_limit_kmh = cmd_speed_limit;
      return command::run_command_tool(cmd_options);
    }
    if (check_cmd->parsed()) return run_check_config(check_file, std::cout, std::cerr);
    if (completion_cmd->parsed()) {
      write_bash_completion(app, std::cout);
      return 0;
    }
  } catch (const config::ConfigError& e) {
    print_config_error(e, std::cerr);
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "fleetgw: " << e.what() << '\n';
    return 1;
  }
  return 0;
}

}  // namespace fleetgw::cli
