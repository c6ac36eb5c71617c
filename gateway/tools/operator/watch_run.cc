// run_watch: linked into fleetgw-watch only (protobuf reflection; see watch_command.h).
#include <google/protobuf/stubs/logging.h>
#include <mqtt/async_client.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <iostream>
#include <random>
#include <thread>

#include "fleetgw/v1/command.pb.h"
#include "fleetgw/v1/envelope.pb.h"
#include "fleetgw/v1/status.pb.h"
#include "gateway/tools/operator/watch_command.h"
#include "gateway/uplink/mqtt_connection.h"
#include "proto/schema_reflection.h"

namespace fleetgw::tools {
namespace {

// Set from the signal handler only; a watch is a one-shot command-line tool.
volatile std::sig_atomic_t g_stop = 0;
void on_signal(int) {
  g_stop = 1;
}

// The generated classes are lite (no reflection); JSON comes from the compiled-in schema.
std::string to_json(const proto::SchemaReflection& schema, std::string_view type,
                    const std::string& bytes) {
  const auto message = schema.parse(type, bytes);
  return message ? proto::SchemaReflection::to_json(*message) : "null";
}

}  // namespace

int run_watch(const WatchOptions& options, std::ostream& out) {
  // Undecodable payloads are reported as JSON lines; protobuf's own stderr log would only
  // duplicate them.
  google::protobuf::SetLogHandler(
      [](google::protobuf::LogLevel, const char*, int, const std::string&) {});
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  const proto::SchemaReflection schema;
  std::mt19937_64 rng(std::random_device{}());
  const std::string client_id = "fleetgw-watch-" + std::to_string(rng() % 1'000'000);
  // The uplink's connection builder: TLS verification on, mqtts:// spelled as Paho wants.
  uplink::ConnectionSettings settings;
  settings.broker_uri = uplink::normalise_broker_uri(options.broker);
  if (uplink::uses_tls(options.broker)) {
    settings.tls = uplink::TlsConfig{options.ca_file, options.cert_file, options.key_file, true};
  }
  settings.username = options.username;
  settings.password = options.password;
  mqtt::async_client client(settings.broker_uri, client_id,
                            mqtt::create_options(MQTTVERSION_3_1_1));
  try {
    client.start_consuming();
    client.connect(uplink::make_connect_options(settings))->wait();
    client.subscribe(options.topic, 1)->wait();
  } catch (const mqtt::exception& e) {
    std::cerr << "watch: cannot subscribe to " << options.topic << " at " << options.broker << ": "
              << e.what() << '\n';
    return 1;
  }
  const auto deadline = std::chrono::steady_clock::now() +
                        std::chrono::milliseconds(static_cast<int64_t>(options.duration_s * 1000));
  long seen = 0;
  while (!g_stop) {
    if (options.duration_s > 0 && std::chrono::steady_clock::now() >= deadline) break;
    mqtt::const_message_ptr msg;
    if (!client.try_consume_message_for(&msg, std::chrono::milliseconds(200)) || !msg) continue;
    const std::string& payload = msg->get_payload();
    fleetgw::v1::Envelope envelope;
    fleetgw::v1::SignedCommand signed_command;
    fleetgw::v1::Command command;
    const bool is_command_topic =
        msg->get_topic().size() >= 4 &&
        msg->get_topic().compare(msg->get_topic().size() - 4, 4, "/cmd") == 0;
    if (is_command_topic && signed_command.ParseFromString(payload) &&
        command.ParseFromString(signed_command.command())) {
      // Commands travel the other way (backend to bike); show what was asked and by which key.
      out << R"({"topic":")" << msg->get_topic() << R"(","key_id":")" << signed_command.key_id()
          << R"(","command":)" << to_json(schema, "fleetgw.v1.Command", signed_command.command())
          << "}" << std::endl;
    } else if (payload.size() > (1u << 20) || !envelope.ParseFromString(payload)) {
      // Retained status messages may be published bare by older gateways; show both forms.
      out << R"({"topic":")" << msg->get_topic() << R"(","error":"not a fleetgw.v1.Envelope ()"
          << payload.size() << " bytes)\"}" << std::endl;
    } else {
      out << R"({"topic":")" << msg->get_topic() << R"(","envelope":)"
          << to_json(schema, "fleetgw.v1.Envelope", payload) << "}" << std::endl;
    }
    if (options.max_messages > 0 && ++seen >= options.max_messages) break;
  }
  try {
    client.disconnect()->wait_for(std::chrono::seconds(2));
  } catch (const mqtt::exception&) {
  }
  return 0;
}

}  // namespace fleetgw::tools
