// Publishing signed commands and storing their results (command_hub.h).
#include "backend/web/command_hub.h"

#include <mqtt/async_client.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <stdexcept>

#include "backend/web/secrets.h"
#include "fleetgw/v1/command.pb.h"
#include "fleetgw/v1/envelope.pb.h"

namespace fleetgw::web {
namespace {

using namespace std::chrono_literals;

std::string hub_uri(const std::string& uri) {
  if (uri.starts_with("mqtt://")) return "tcp://" + uri.substr(7);
  if (uri.starts_with("mqtts://")) return "ssl://" + uri.substr(8);
  return uri;
}

mqtt::connect_options hub_connect_options(const ServeOptions& o, const std::string& uri) {
  mqtt::connect_options opts;
  opts.set_mqtt_version(MQTTVERSION_5);
  // Nothing to resume: a result that arrives while this instance is away is stored by another
  // instance, or the command shows "no answer" once it expired.
  opts.set_clean_start(true);
  opts.set_keep_alive_interval(30);
  opts.set_connect_timeout(10);
  opts.set_automatic_reconnect(1s, 30s);
  if (!o.username.empty()) opts.set_user_name(o.username);
  if (!o.password.empty()) opts.set_password(o.password);
  if (!o.ca_file.empty() || !o.cert_file.empty() || uri.starts_with("ssl://") ||
      uri.starts_with("wss://")) {
    mqtt::ssl_options ssl;
    if (!o.ca_file.empty()) ssl.set_trust_store(o.ca_file);
    if (!o.cert_file.empty()) {
      ssl.set_key_store(o.cert_file);
      ssl.set_private_key(o.key_file);
    }
    ssl.set_enable_server_cert_auth(true);
    ssl.set_verify(true);
    ssl.set_ssl_version(MQTT_SSL_VERSION_TLS_1_2);
    opts.set_ssl(ssl);
  }
  return opts;
}

}  // namespace

std::string command_result_name(int code) {
  switch (code) {
    case v1::COMMAND_RESULT_CODE_SUCCEEDED:
      return "succeeded";
    case v1::COMMAND_RESULT_CODE_FAILED:
      return "failed";
    case v1::COMMAND_RESULT_CODE_TIMEOUT:
      return "timeout";
    case v1::COMMAND_RESULT_CODE_REJECTED:
      return "rejected";
    default:
      return "unspecified";
  }
}

struct CommandHub::Impl {
  const ServeOptions& o;
  PgPool& pool;
  Auth& auth;
  std::function<void()> on_result;
  std::string filter;
  std::unique_ptr<mqtt::async_client> client;

  Impl(const ServeOptions& options, PgPool& p, Auth& a, std::function<void()> cb)
      : o(options), pool(p), auth(a), on_result(std::move(cb)) {}

  void on_message(const mqtt::const_message_ptr& m);
};

void CommandHub::Impl::on_message(const mqtt::const_message_ptr& m) {
  // <prefix>/<vehicle>/cmd/result
  const std::string& topic = m->get_topic();
  const std::string head = o.topic_prefix + "/";
  constexpr std::string_view kTail = "/cmd/result";
  if (!topic.starts_with(head) || !topic.ends_with(kTail) ||
      topic.size() <= head.size() + kTail.size()) {
    return;
  }
  const std::string vehicle = topic.substr(head.size(), topic.size() - head.size() - kTail.size());
  v1::Envelope env;
  if (!env.ParseFromString(m->get_payload()) || !env.has_command_result()) return;
  const v1::CommandResult& r = env.command_result();
  const std::string command_sha = r.command_sha256().empty() ? "" : hex_bytes(r.command_sha256());
  const std::string payload_sha = r.payload_sha256().empty() ? "" : hex_bytes(r.payload_sha256());
  if (command_sha.empty() && payload_sha.empty()) return;  // bound to nothing we can check
  const std::string result = command_result_name(r.result());
  const PgParam p[] = {vehicle,
                       r.command_id(),
                       command_sha,
                       payload_sha,
                       result,
                       r.reason(),
                       r.operator_id(),
                       std::to_string(r.duration_ms()),
                       r.final_lock_state_name(),
                       r.has_mc() ? r.mc().limit_in_force() : std::string(),
                       std::to_string(now_us())};
  try {
    auto c = pool.lease();
    const PgResult u = c->query(
        "UPDATE console_commands SET result = $5, reason = $6, result_operator = $7, "
        "duration_ms = $8::bigint, final_state = $9, limit_in_force = $10, "
        "result_at_us = $11::bigint WHERE vehicle_id = $1 AND result IS NULL AND " +
            // By the primary key when the result names the command; a payload the bike could
            // not authenticate may come without an id: then among the vehicle's commands of
            // the last day (the by-vehicle index), by the whole payload's digest.
            std::string(r.command_id().empty()
                            ? "payload_sha256 = $4 AND $4 <> '' AND issued_at_us > $11::bigint - "
                              "86400000000 AND $2 = '' AND $3 = '' "
                            : "command_id = $2 AND (command_sha256 = $3 OR (payload_sha256 = $4 "
                              "AND $4 <> '')) ") +
            "RETURNING command_id, operator, address",
        p, "command result");
    if (u.rows() == 0) return;
    auth.audit(u.str(0, 1), u.str(0, 2), "command_result", vehicle + "/" + u.str(0, 0), result,
               r.reason());
  } catch (const PgError& e) {
    spdlog::warn("serve: storing the result of {} from {}: {}", r.command_id(), vehicle, e.what());
    return;
  }
  if (on_result) on_result();
}

CommandHub::CommandHub(const ServeOptions& o, PgPool& pool, Auth& auth,
                       std::function<void()> on_result)
    : impl_(std::make_unique<Impl>(o, pool, auth, std::move(on_result))) {
  Impl& m = *impl_;
  const std::string uri = hub_uri(o.broker);
  m.filter = o.topic_prefix + "/+/cmd/result";
  m.client = std::make_unique<mqtt::async_client>(uri, "fleetgw-serve-" + random_token(9),
                                                  mqtt::create_options(MQTTVERSION_5));
  m.client->set_message_callback([&m](mqtt::const_message_ptr msg) { m.on_message(msg); });
  m.client->set_connected_handler([&m](const std::string&) {
    try {
      m.client->subscribe(m.filter, 1);
    } catch (const mqtt::exception& e) {
      spdlog::error("serve: subscribe {} failed: {}", m.filter, e.what());
    }
  });
  m.client->set_connection_lost_handler([](const std::string& cause) {
    spdlog::warn("serve: connection to the broker lost ({}); reconnecting",
                 cause.empty() ? "no reason given" : cause);
  });
  try {
    m.client->connect(hub_connect_options(o, uri))->wait_for(15s);
    if (!m.client->is_connected()) throw std::runtime_error("no answer within 15 s");
    m.client->subscribe(m.filter, 1)->wait_for(10s);
  } catch (const std::exception& e) {
    throw std::runtime_error("--broker " + o.broker + ": cannot connect: " + e.what());
  }
}

CommandHub::~CommandHub() {
  try {
    if (impl_->client->is_connected()) impl_->client->disconnect()->wait_for(2s);
  } catch (const mqtt::exception&) {
    // Going away anyway.
  }
}

bool CommandHub::connected() const {
  return impl_->client->is_connected();
}

void CommandHub::send(const CommandRequest& r, const std::string& vehicle_id,
                      const std::string& key_id, std::optional<std::uint64_t> delegation_serial,
                      const SignedCommandBytes& cmd, const CommandOrigin& origin) {
  Impl& m = *impl_;
  {
    const PgParam p[] = {
        cmd.command_id,
        vehicle_id,
        origin.operator_name,
        origin.address,
        r.action,
        r.summary(),
        key_id,
        delegation_serial ? PgParam(std::to_string(*delegation_serial)) : PgParam(std::nullopt),
        cmd.command_sha256,
        cmd.payload_sha256,
        std::to_string(cmd.issued_at_us),
        std::to_string(cmd.expires_at_us),
        origin.batch_id.empty() ? PgParam(std::nullopt) : PgParam(origin.batch_id)};
    auto c = m.pool.lease();
    c->query(
        "INSERT INTO console_commands (command_id, vehicle_id, operator, address, action, "
        "params, key_id, delegation_serial, command_sha256, payload_sha256, issued_at_us, "
        "expires_at_us, batch_id) VALUES ($1, $2, $3, $4, $5, $6, $7, $8::bigint, $9, $10, "
        "$11::bigint, $12::bigint, $13)",
        p, "record command");
  }
  try {
    auto tok =
        m.client->publish(o_topic(vehicle_id), cmd.payload.data(), cmd.payload.size(), 1, false);
    if (!tok->wait_for(5s)) throw std::runtime_error("the broker did not acknowledge it in 5 s");
  } catch (const std::exception& e) {
    const PgParam p[] = {cmd.command_id, std::string("not_published: ") + e.what(),
                         std::to_string(now_us())};
    try {
      auto c = m.pool.lease();
      c->query(
          "UPDATE console_commands SET result = 'not_published', reason = $2, "
          "result_at_us = $3::bigint WHERE command_id = $1 AND result IS NULL",
          p, "command not published");
    } catch (const PgError& pe) {
      spdlog::warn("serve: marking {} unpublished: {}", cmd.command_id, pe.what());
    }
    throw std::runtime_error(std::string("broker: ") + e.what());
  }
}

void CommandHub::publish_retained(const std::vector<std::string>& topics,
                                  const std::string& payload) {
  std::vector<std::pair<std::string, mqtt::delivery_token_ptr>> pending;
  pending.reserve(topics.size());
  try {
    for (const std::string& t : topics) {
      pending.emplace_back(
          t, impl_->client->publish(t, payload.data(), payload.size(), 1, /*retained=*/true));
    }
    const auto deadline = std::chrono::steady_clock::now() + 10s;
    for (auto& [topic, tok] : pending) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
          deadline - std::chrono::steady_clock::now());
      if (!tok->wait_for(std::max(left, std::chrono::milliseconds(1)))) {
        throw std::runtime_error(topic + ": the broker did not acknowledge it in time");
      }
    }
  } catch (const mqtt::exception& e) {
    throw std::runtime_error(std::string("broker: ") + e.what());
  }
}

std::string CommandHub::o_topic(const std::string& vehicle_id) const {
  return impl_->o.topic_prefix + "/" + vehicle_id + "/cmd";
}

}  // namespace fleetgw::web
