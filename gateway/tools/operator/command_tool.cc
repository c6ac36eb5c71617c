#include "gateway/tools/operator/command_tool.h"

#include <mqtt/async_client.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <condition_variable>
#include <deque>
#include <iostream>
#include <mutex>

#include "fleetgw/v1/command.pb.h"
#include "fleetgw/v1/envelope.pb.h"
#include "gateway/command/diag_blocks.h"
#include "gateway/command/sha256.h"
#include "gateway/command/verifier.h"
#include "gateway/common/untrusted_text.h"
#include "gateway/tools/common/time_arg.h"
#include "gateway/tools/operator/operator_inputs.h"
#include "gateway/uplink/connect_diagnosis.h"
#include "gateway/uplink/mqtt5.h"
#include "gateway/uplink/mqtt_connection.h"
#include "gateway/uplink/tcp_nodelay.h"

namespace fleetgw::command {
namespace {

constexpr std::string_view kSignedCommandContentType =
    "application/x-protobuf; proto=fleetgw.v1.SignedCommand";

std::string hex(std::span<const std::uint8_t> bytes) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string s;
  for (const auto b : bytes) {
    s += kDigits[b >> 4];
    s += kDigits[b & 0xF];
  }
  return s;
}

Micros system_now() {
  return std::chrono::duration_cast<Micros>(std::chrono::system_clock::now().time_since_epoch());
}

std::string_view state_name(v1::LockState s) {
  switch (s) {
    case v1::LOCK_STATE_LOCKED:
      return "locked";
    case v1::LOCK_STATE_UNLOCKED:
      return "unlocked";
    case v1::LOCK_STATE_FAULT:
      return "fault";
    case v1::LOCK_STATE_LOCKING:
      return "locking";
    case v1::LOCK_STATE_UNLOCKING:
      return "unlocking";
    default:
      return "unspecified";
  }
}

std::string hex_id(std::uint32_t v, int digits) {
  static constexpr char kDigits[] = "0123456789ABCDEF";
  std::string s = "0x";
  for (int i = digits - 1; i >= 0; --i) s += kDigits[(v >> (4 * i)) & 0xF];
  return s;
}

// A diagnostic read's decoded block (issue 29): every received string escaped.
nlohmann::json diagnostic_json(const v1::DiagnosticResult& d) {
  nlohmann::json messages = nlohmann::json::array();
  for (const auto& m : d.messages()) {
    nlohmann::json values = nlohmann::json::array();
    for (const auto& v : m.values()) {
      nlohmann::json value = nullptr;
      if (v.valid() && v.has_value_e6()) {
        value = static_cast<double>(v.value_e6()) / 1e6;
      } else if (v.valid()) {
        value = common::untrusted_excerpt(v.text(), 128);
      }
      nlohmann::json one{{"name", common::untrusted_excerpt(v.name(), 128)}, {"value", value}};
      if (!v.unit().empty()) one["unit"] = common::valid_utf8(v.unit());
      values.push_back(std::move(one));
    }
    const auto* data = reinterpret_cast<const std::uint8_t*>(m.data().data());
    messages.push_back({{"message", common::untrusted_excerpt(m.message(), 64)},
                        {"can_id", hex_id(m.can_id(), 3)},
                        {"command", hex_id(m.command(), 4)},
                        {"data", hex({data, m.data().size()})},
                        {"heard_at", m.heard_at_us() > 0 ? tools::iso_utc(m.heard_at_us()) : ""},
                        {"values", std::move(values)}});
  }
  nlohmann::json j{{"block", common::untrusted_excerpt(d.block(), 64)},
                   {"node", common::untrusted_excerpt(d.node(), 64)},
                   {"source", common::untrusted_excerpt(d.source(), 64)},
                   {"requests_sent", d.requests_sent()},
                   {"messages", std::move(messages)}};
  if (!d.note().empty()) j["note"] = common::untrusted_excerpt(d.note(), 256);
  return j;
}

nlohmann::json to_json(const v1::CommandResult& r, std::string_view vehicle, Micros round_trip) {
  nlohmann::json j;
  j["command_id"] = r.command_id();
  j["vehicle_id"] = vehicle;
  j["result"] = command_result_name(r.result());
  j["reason"] = r.reason();
  j["final_lock_state"] = state_name(r.final_lock_state());
  j["final_lock_state_name"] = r.final_lock_state_name();
  j["duration_ms"] = r.duration_ms();
  j["command_sha256"] = to_hex(r.command_sha256());
  j["stored"] = r.stored();
  // Issue 28: who the gateway says asked (escaped by the gateway; only for a delegated or
  // console-signed command that named an operator).
  if (!r.operator_id().empty()) j["operator_id"] = common::valid_utf8(r.operator_id());
  j["round_trip_ms"] = round_trip.count() / 1000;
  nlohmann::json locks = nlohmann::json::array();
  for (const auto& l : r.locks()) {
    locks.push_back({{"lock_kind", l.lock_kind()},
                     {"result", command_result_name(l.result())},
                     {"reason", l.reason()},
                     {"final_lock_state_name", l.final_lock_state_name()},
                     {"duration_ms", l.duration_ms()},
                     {"commands_sent", l.commands_sent()}});
  }
  j["locks"] = std::move(locks);
  if (r.has_mc()) {
    const auto& m = r.mc();
    nlohmann::json mc{{"action", m.action()}, {"writes_sent", m.writes_sent()}};
    if (m.has_speed_limit_kmh()) mc["speed_limit_kmh"] = m.speed_limit_kmh();
    if (m.has_factory_speed_limit_kmh())
      mc["factory_speed_limit_kmh"] = m.factory_speed_limit_kmh();
    if (m.has_operator_cap_kmh()) mc["operator_cap_kmh"] = m.operator_cap_kmh();
    if (!m.limit_in_force().empty()) mc["limit_in_force"] = m.limit_in_force();
    if (!m.assist_level().empty()) mc["assist_level"] = m.assist_level();
    if (m.has_headlight_on()) mc["headlight_on"] = m.headlight_on();
    if (m.has_trip_m()) mc["trip_m"] = m.trip_m();
    if (m.has_mc_ready()) mc["mc_ready"] = m.mc_ready();
    if (m.has_obc_ready()) mc["obc_ready"] = m.obc_ready();
    j["mc"] = std::move(mc);
  }
  if (r.has_diagnostic()) j["diagnostic"] = diagnostic_json(r.diagnostic());
  return j;
}

// What the retained status says about a vehicle that gave no answer (see the header).
std::string liveness(const std::string& vehicle, const std::string& status_topic,
                     const std::optional<v1::Envelope>& status) {
  using tools::iso_utc;
  if (!status)
    return "vehicle " + vehicle + " never seen (no retained status on " + status_topic + ")";
  if (!status->has_status()) {
    return "vehicle " + vehicle + ": the retained message on " + status_topic +
           " is not a fleetgw status";
  }
  const v1::Status& s = status->status();
  const std::int64_t at = status->created_at_us();
  if (s.state() == v1::ONLINE_STATE_OFFLINE) {
    if (at > 0) return "vehicle " + vehicle + " offline since " + iso_utc(at);
    // The last will carries no time: the broker published it when the connection was lost.
    std::string text = "vehicle " + vehicle + " offline: its connection was lost (last will)";
    if (s.connected_at_us() > 0) text += "; it had connected at " + iso_utc(s.connected_at_us());
    return text;
  }
  if (s.state() == v1::ONLINE_STATE_ONLINE) {
    return "vehicle " + vehicle + " online (status of " + (at > 0 ? iso_utc(at) : "unknown time") +
           ") but it did not answer";
  }
  return "vehicle " + vehicle + ": the retained status on " + status_topic + " has no online state";
}

// Messages arriving on Paho's thread, handed to the tool's thread.
class Inbox {
 public:
  void push(mqtt::const_message_ptr m) {
    {
      std::lock_guard lock(mu_);
      queue_.push_back(std::move(m));
    }
    cv_.notify_one();
  }
  mqtt::const_message_ptr pop_until(std::chrono::steady_clock::time_point deadline) {
    std::unique_lock lock(mu_);
    if (!cv_.wait_until(lock, deadline, [this] { return !queue_.empty(); })) return nullptr;
    auto m = std::move(queue_.front());
    queue_.pop_front();
    return m;
  }

 private:
  std::mutex mu_;
  std::condition_variable cv_;
  std::deque<mqtt::const_message_ptr> queue_;
};

// ": <reason>" for a failed connect, found by repeating its steps (host lookup, TCP, TLS
// handshake with the same CA, client certificate and host-name check) as the gateway's uplink
// does; "" when every step succeeds (the cause lies beyond TLS) or nothing can be probed. The
// probe is bounded by `budget` (at least 1 s, at most 5 s: a tool waiting on a dead network
// should not wait again for long).
std::string connect_failure_reason(const uplink::ConnectionSettings& settings,
                                   std::chrono::milliseconds budget) {
  const auto target = uplink::probe_target(settings.broker_uri, settings.tls);
  if (!target) return "";
  const auto timeout =
      std::clamp(budget, std::chrono::milliseconds(1000), std::chrono::milliseconds(5000));
  const std::string reason = uplink::diagnose_connect(*target, timeout);
  return reason.empty() ? "" : ": " + reason;
}

}  // namespace

int run_command_tool(const CommandToolOptions& o) {
  std::ostream& out = o.out != nullptr ? *o.out : std::cout;
  std::ostream& err = o.err != nullptr ? *o.err : std::cerr;
  const auto clock = o.wall_clock ? o.wall_clock : system_now;
  auto usage = [&](const std::string& what) {
    err << "command: " << what << '\n';
    return kExitUsage;
  };

  if (!is_valid_tool_id(o.vehicle)) return usage("--vehicle: 1..64 characters of [A-Za-z0-9._-]");
  // Exactly one action: lock/unlock, one MC action, or one diagnostic read (whose --lock names
  // the lock of lock_model).
  const bool diag = !o.diag.empty();
  const bool lock_action = (!diag && !o.lock.empty()) || !o.action.empty();
  const int actions = int{lock_action} + int{o.speed_limit_kmh.has_value()} +
                      int{!o.assist.empty()} + int{!o.lights.empty()} + int{o.clear_trip} +
                      int{o.power_off} + int{diag};
  if (actions != 1) {
    return usage(
        "give exactly one action: --lock with --action, --speed-limit, --assist, --lights, "
        "--clear-trip, --power-off or --diag");
  }
  if (o.captured && !diag) return usage("--captured goes with --diag mc_lifetime|pack_lifetime");
  std::string mc_action, mc_value;
  const DiagBlockSpec* diag_spec = nullptr;
  if (diag) {
    diag_spec = find_diag_block(o.diag);
    if (diag_spec == nullptr) return usage("--diag: one of " + diag_block_names());
    const bool lock_model = diag_spec->block == v1::DIAGNOSTIC_BLOCK_LOCK_MODEL;
    if (lock_model && (o.lock.empty() || o.lock.size() > 64 || o.lock == "vehicle")) {
      return usage("--diag lock_model: name the lock with --lock (seat, battery, ...)");
    }
    if (!lock_model && !o.lock.empty()) return usage("--lock goes with --diag lock_model only");
    if (o.captured && !diag_spec->capturable) {
      return usage("--captured: only for --diag mc_lifetime or pack_lifetime");
    }
  } else if (lock_action) {
    if (o.action != "lock" && o.action != "unlock") return usage("--action: lock or unlock");
    if (o.lock.empty() || o.lock.size() > 64) return usage("--lock: a lock kind or 'vehicle'");
  } else if (o.speed_limit_kmh) {
    // 0 is not a limit (the gateway refuses it as a speed_limit without value).
    if (*o.speed_limit_kmh < 1 || *o.speed_limit_kmh > 255) return usage("--speed-limit: 1..255");
    mc_action = "speed_limit";
    mc_value = std::to_string(*o.speed_limit_kmh);
  } else if (!o.assist.empty()) {
    const bool name_ok =
        o.assist.size() <= 32 && std::all_of(o.assist.begin(), o.assist.end(), [](char c) {
          return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_';
        });
    if (!name_ok)
      return usage("--assist: an assist level name (off, eco, norm, sport, turbo, walk...)");
    mc_action = "assist_level";
    mc_value = o.assist;
  } else if (!o.lights.empty()) {
    if (o.lights != "on" && o.lights != "off") return usage("--lights: on or off");
    mc_action = "headlight";
    mc_value = o.lights;
  } else {
    mc_action = o.clear_trip ? "clear_trip" : "power_off";
  }
  if (const auto error = tools::broker_option_error(o.broker, o.username, o.password,
                                                    o.allow_plaintext_credentials)) {
    return usage(*error);
  }
  const bool tls = uplink::uses_tls(o.broker);
  if (o.cert_file.empty() != o.key_file.empty()) {
    return usage("--cert-file and --key-file go together");
  }
  if (o.timeout.count() <= 0 || o.expires_in.count() <= 0) {
    return usage("--timeout-s and --expires-in-s must be > 0");
  }
  if (o.topic_prefix.empty() || o.topic_prefix.find_first_of("#+") != std::string::npos) {
    return usage("--topic-prefix: no wildcards");
  }
  if (o.mqtt_version != "5" && o.mqtt_version != "3.1.1") {
    return usage("--mqtt-version: 5 or 3.1.1");
  }
  const auto protocol =
      o.mqtt_version == "5" ? uplink::MqttProtocol::kV5 : uplink::MqttProtocol::kV311;
  std::string delegation;  // serialized SignedDelegation, or empty
  std::string delegated_key_id;
  if (!o.delegation.empty()) {
    constexpr std::string_view kWhat = "a signed delegation (fleetgw keys delegate)";
    std::string error;
    auto file = tools::read_signed_file<v1::SignedDelegation, v1::Delegation>(
        o.delegation,
        [](const v1::SignedDelegation& sd) -> const std::string& { return sd.delegation(); }, kWhat,
        error);
    if (!file) return usage("--delegation: " + error);
    if (file->document.key_id().empty()) {
      return usage("--delegation: " + o.delegation.string() + " is not " + std::string(kWhat));
    }
    delegation = std::move(file->bytes);
    delegated_key_id = file->document.key_id();
  }
  std::string key_id = !o.key_id.empty()           ? o.key_id
                       : !delegated_key_id.empty() ? delegated_key_id
                                                   : o.key.stem().string();
  if (!is_valid_tool_id(key_id)) return usage("--key-id: 1..64 characters of [A-Za-z0-9._-]");
  if (!delegated_key_id.empty() && delegated_key_id != key_id) {
    return usage("--delegation: it delegates key '" +
                 common::untrusted_excerpt(delegated_key_id, 64) + "', not the signing key '" +
                 key_id + "'");
  }
  const bool operator_ok =
      o.operator_id.size() <= 64 && std::all_of(o.operator_id.begin(), o.operator_id.end(),
                                                [](char c) { return c > ' ' && c <= '~'; });
  if (!operator_ok) return usage("--operator: 1..64 printable ASCII characters, no space");
  std::optional<Ed25519PrivateKey> key;
  try {
    key = Ed25519PrivateKey::load_pem(o.key);
  } catch (const std::exception& e) {
    return usage(std::string("--key: ") + e.what());
  }
  const std::string id = o.command_id.empty() ? random_command_id() : o.command_id;
  if (!is_valid_command_id(id)) return usage("command id: 1..128 printable characters");

  const std::string base = o.topic_prefix + "/" + o.vehicle;
  const std::string cmd_topic = base + "/cmd";
  const std::string result_topic = base + "/cmd/result";
  const std::string status_topic = base + "/status";  // retained by the gateway's uplink

  try {
    const auto client_ptr = uplink::make_client(uplink::normalise_broker_uri(o.broker),
                                                "fleetgw-cmd-" + hex(random_bytes(6)), protocol);
    mqtt::async_client& client = *client_ptr;
    Inbox inbox;
    client.set_message_callback([&inbox](mqtt::const_message_ptr m) { inbox.push(std::move(m)); });
    uplink::ConnectionSettings settings;  // the uplink's builder: TLS verification on
    settings.broker_uri = uplink::normalise_broker_uri(o.broker);
    if (tls) settings.tls = uplink::TlsConfig{o.ca_file, o.cert_file, o.key_file, true};
    settings.username = o.username;
    settings.password = o.password;
    settings.connect_timeout = std::chrono::seconds(std::max<std::int64_t>(1, o.timeout.count()));
    settings.protocol = protocol;
    const mqtt::connect_options opts = uplink::make_connect_options(settings);
    const auto t0 = std::chrono::steady_clock::now();
    const auto deadline = t0 + o.timeout;
    auto remaining = [&] {
      return std::max(std::chrono::milliseconds(1),
                      std::chrono::duration_cast<std::chrono::milliseconds>(
                          deadline - std::chrono::steady_clock::now()));
    };
    try {
      bool connected = false;
      try {
        connected = client.connect(opts)->wait_for(remaining());
      } catch (const mqtt::exception& e) {
        // Paho says only "TCP/TLS connect failure"; the uplink's diagnosis names the cause
        // ("TLS: certificate verify failed (certificate has expired)", "connection refused"...).
        err << "command: broker " << o.broker << ": " << e.what()
            << connect_failure_reason(settings, remaining()) << '\n';
        return kExitNoAnswer;
      }
      if (!connected) {
        err << "command: no connection to the broker within " << o.timeout.count() << " s\n";
        return kExitNoAnswer;
      }
      // The result arrives right after our command's PUBACK; see uplink/tcp_nodelay.h.
      if (const auto port = uplink::broker_port(o.broker))
        uplink::enable_tcp_nodelay_to_port(*port);
      // Subscribe first: a result published before our subscription existed would be lost.
      if (!client.subscribe(result_topic, 1)->wait_for(remaining())) {
        err << "command: subscribe to " << result_topic << " timed out\n";
        return kExitNoAnswer;
      }
      // The retained status says, if no result comes, whether the vehicle is offline or was
      // never seen. Only a diagnosis: its absence changes nothing else.
      if (!client.subscribe(status_topic, 1)->wait_for(remaining())) {
        err << "command: subscribe to " << status_topic << " timed out\n";
      }
    } catch (const mqtt::exception& e) {
      err << "command: broker " << o.broker << ": " << e.what() << '\n';
      return kExitNoAnswer;
    }

    const Micros now = clock();
    const Micros expires = now + std::chrono::duration_cast<Micros>(o.expires_in);
    std::optional<v1::Command> cmd;
    if (diag_spec != nullptr) {
      cmd.emplace();
      auto* read = cmd->mutable_diagnostic_read();
      read->set_block(diag_spec->block);
      if (diag_spec->block == v1::DIAGNOSTIC_BLOCK_LOCK_MODEL) read->set_lock_kind(o.lock);
      read->set_last_captured(o.captured);
      cmd->set_command_id(id);
      cmd->set_vehicle_id(o.vehicle);
      cmd->set_issued_at_us(now.count());
      cmd->set_expires_at_us(expires.count());
    } else if (mc_action.empty()) {
      cmd = make_command(o.vehicle, o.lock, o.action, now, expires, id);
    } else {
      cmd = make_mc_command(o.vehicle, mc_action, mc_value, now, expires, id);
    }
    auto signed_cmd = *cmd;
    if (!o.operator_id.empty()) signed_cmd.set_operator_id(o.operator_id);
    const SentCommand sent = sign_for_sending(signed_cmd, *key, key_id, delegation);
    const std::string& payload = sent.payload;
    auto msg = mqtt::make_message(cmd_topic, payload.data(), payload.size(), 1, false);
    if (protocol == uplink::MqttProtocol::kV5) {
      // The broker drops the command once it is no longer valid (a vehicle offline for longer
      // would refuse it as expired anyway); the gateway still checks expires_at itself.
      mqtt::properties props;
      props.add(mqtt::property(mqtt::property::MESSAGE_EXPIRY_INTERVAL,
                               static_cast<std::int32_t>(o.expires_in.count())));
      props.add(
          mqtt::property(mqtt::property::CONTENT_TYPE, std::string(kSignedCommandContentType)));
      msg->set_properties(std::move(props));
    }
    const auto sent_at = std::chrono::steady_clock::now();
    try {
      if (!client.publish(msg)->wait_for(remaining())) {
        err << "command: publish to " << cmd_topic << " not acknowledged in time\n";
        client.disconnect()->wait_for(std::chrono::seconds(1));
        return kExitNoAnswer;
      }
    } catch (const mqtt::exception& e) {
      // MQTT 5: the broker answered the publish with a refusal (e.g. an ACL's 0x87).
      const int reason = e.get_reason_code();
      err << "command: the broker refused the command on " << cmd_topic << ": "
          << (uplink::is_refusal(reason) ? uplink::reason_text(reason) : std::string(e.what()))
          << '\n';
      return kExitNoAnswer;
    }
    err << "command: " << id << " published to " << cmd_topic << "; waiting for the result\n";

    std::size_t unbound = 0;
    std::optional<v1::Envelope> last_status;  // the latest message on the status topic
    while (auto m = inbox.pop_until(deadline)) {
      const auto& p = m->get_payload_ref();
      if (m->get_topic() == status_topic) {
        last_status.emplace();
        if (!last_status->ParseFromArray(p.data(), static_cast<int>(p.size()))) {
          last_status->Clear();
        }
        continue;
      }
      if (m->get_topic() != result_topic) continue;
      v1::Envelope env;
      if (!env.ParseFromArray(p.data(), static_cast<int>(p.size())) || !env.has_command_result() ||
          env.command_result().command_id() != id) {
        continue;  // someone else's result, or a re-sent one of an older command
      }
      if (!result_answers(env.command_result(), id, sent)) {
        // Our id, but not bound to what we sent: the answer to a forged payload that copied the
        // id (or a gateway too old to bind its results), never ours.
        ++unbound;
        err << "command: ignored a result for " << id << " not bound to the command sent ("
            << command_result_name(env.command_result().result()) << ": "
            << common::untrusted_excerpt(env.command_result().reason(), 120) << ")\n";
        continue;
      }
      const auto rtt =
          std::chrono::duration_cast<Micros>(std::chrono::steady_clock::now() - sent_at);
      out << to_json(env.command_result(), o.vehicle, rtt).dump() << std::endl;
      try {
        client.disconnect()->wait_for(std::chrono::seconds(1));
      } catch (const mqtt::exception&) {
        // The answer is in; a failing disconnect changes nothing for the caller.
      }
      return env.command_result().result() == v1::COMMAND_RESULT_CODE_SUCCEEDED ? kExitSucceeded
                                                                                : kExitNotSucceeded;
    }
    err << "command: no result for " << id << " within " << o.timeout.count()
        << " s: " << liveness(o.vehicle, status_topic, last_status);
    if (unbound > 0) err << " (" << unbound << " result(s) with this id but other bytes ignored)";
    err << '\n';
    try {
      client.disconnect()->wait_for(std::chrono::seconds(1));
    } catch (const mqtt::exception&) {
    }
    return kExitNoAnswer;
  } catch (const std::exception& e) {
    err << "command: " << e.what() << '\n';
    return kExitNoAnswer;
  }
}

}  // namespace fleetgw::command
