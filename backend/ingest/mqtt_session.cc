// One MQTT 5 session in its own process (mqtt_session.h).
#include "backend/ingest/mqtt_session.h"

#include <malloc.h>
#include <mqtt/async_client.h>
#include <spdlog/spdlog.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <csignal>
#include <cstring>
#include <iostream>
#include <mutex>

namespace fleetgw::ingest {
namespace {

using namespace std::chrono_literals;

std::string normalise_uri(const std::string& uri) {
  if (uri.starts_with("mqtt://")) return "tcp://" + uri.substr(7);
  if (uri.starts_with("mqtts://")) return "ssl://" + uri.substr(8);
  return uri;
}

bool send_all(int fd, const char* p, std::size_t n) {
  while (n > 0) {
    const ssize_t w = ::send(fd, p, n, MSG_NOSIGNAL);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) return false;
    p += w;
    n -= static_cast<std::size_t>(w);
  }
  return true;
}

void put_u32(std::string& out, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) out += static_cast<char>((v >> (8 * i)) & 0xFF);
}

mqtt::connect_options connect_options(const IngestOptions& o, const std::string& uri) {
  mqtt::connect_options opts;
  opts.set_mqtt_version(MQTTVERSION_5);
  // A persistent session: what the broker queued while this worker was away is delivered when
  // it comes back (clean start off + a session expiry interval).
  opts.set_clean_start(false);
  // The receive thread waits in the callback while a batch commits or PostgreSQL is away; the
  // broker drops a client silent for 1.5 keep-alives: 60 s carries a 90 s outage.
  opts.set_keep_alive_interval(60);
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
    // Never weakened: the chain and the host name are always verified.
    ssl.set_enable_server_cert_auth(true);
    ssl.set_verify(true);
    ssl.set_ssl_version(MQTT_SSL_VERSION_TLS_1_2);
    opts.set_ssl(ssl);
  }
  // Set on the options object: Paho C++ 1.2.0's connect_options_builder::properties() loses
  // them (seen: session expiry 0, "session present" never set).
  opts.set_properties(mqtt::properties{
      {mqtt::property::SESSION_EXPIRY_INTERVAL, static_cast<int>(o.session_expiry_s)},
      // The broker drops, instead of sending, anything bigger.
      {mqtt::property::MAXIMUM_PACKET_SIZE, static_cast<int>(o.max_packet_bytes)}});
  return opts;
}

}  // namespace

int run_session(const IngestOptions& o, const std::string& client_id, bool first_session, int fd) {
  // The worker's death is a stop request (SIGTERM, blocked like every stop signal and taken
  // by sigwait below); a message in hand sees EOF on fd first.
  ::prctl(PR_SET_PDEATHSIG, SIGTERM);
  const std::string uri = normalise_uri(o.broker);
  const std::string filter = "$share/" + o.group + "/" + o.topic_prefix + "/#";
  // Retained messages (each vehicle's latest status and state) are sent to the first session
  // only, and only when its subscription is new: every session of every restart receiving
  // them all again cost more messages than the fleet's own traffic in a backlog drain.
  const mqtt::subscribe_options retained(false, false,
                                         first_session
                                             ? mqtt::subscribe_options::SEND_RETAINED_ON_NEW
                                             : mqtt::subscribe_options::DONT_SEND_RETAINED);
  std::mutex write_mu;  // frames from the callback and the main thread never interleave
  std::mutex state_mu;
  std::condition_variable idle;
  bool in_callback = false;
  bool parked = false;  // holds a message the worker could not commit: never returns

  auto frame = [&](const std::string& bytes) {
    std::lock_guard lock(write_mu);
    return send_all(fd, bytes.data(), bytes.size());
  };

  mqtt::async_client client(uri, client_id, mqtt::create_options(MQTTVERSION_5));
  client.set_message_callback([&](mqtt::const_message_ptr m) {
    {
      std::lock_guard lock(state_mu);
      in_callback = true;
    }
    const std::string& topic = m->get_topic();
    const std::string& payload = m->get_payload();
    std::string out;
    out.reserve(9 + topic.size() + payload.size());
    out += 'M';
    put_u32(out, static_cast<std::uint32_t>(topic.size()));
    put_u32(out, static_cast<std::uint32_t>(payload.size()));
    out += topic;
    out += payload;
    char reply = 0;
    ssize_t n = -1;
    if (frame(out)) {
      do {
        n = ::read(fd, &reply, 1);
      } while (n < 0 && errno == EINTR);
    }
    // Without the worker's word the rows may not be committed: never return (no PUBACK).
    if (n != 1) ::_exit(4);
    if (reply != 'A') {
      // Not committed, at a stop: returning would let Paho acknowledge it if the connection
      // is still open. Park this thread for good; the main thread ends the process, and the
      // broker keeps the message (and those behind it) in the session.
      std::unique_lock lock(state_mu);
      parked = true;
      idle.notify_all();
      idle.wait(lock, [] { return false; });
    }
    if (out.size() > kLargeMessageBytes) {
      std::string().swap(out);
      ::malloc_trim(0);
    }
    std::lock_guard lock(state_mu);
    in_callback = false;
    idle.notify_all();
  });
  client.set_connected_handler([&](const std::string&) {
    // (Re)subscribe on every connection: a no-op on a resumed session, needed after it expired.
    try {
      client.subscribe(filter, 1, retained);
    } catch (const mqtt::exception& e) {
      spdlog::error("ingest: {} subscribe {} failed: {}", client_id, filter, e.what());
    }
  });
  client.set_connection_lost_handler([&](const std::string& cause) {
    spdlog::warn("ingest: {}: connection to the broker lost ({}); reconnecting", client_id,
                 cause.empty() ? "no reason given" : cause);
  });
  try {
    const mqtt::token_ptr tok = client.connect(connect_options(o, uri));
    tok->wait();
    const bool resumed = tok->get_connect_response().is_session_present();
    // Subscribed before we say so: a shared subscription without members drops what arrives.
    client.subscribe(filter, 1, retained)->wait();
    frame(std::string{'S', static_cast<char>(resumed ? 1 : 0)});
  } catch (const mqtt::exception& e) {
    std::cerr << "fleetgw ingest: cannot connect to " << uri << " as " << client_id << ": "
              << e.what() << '\n';
    return 1;
  }

  sigset_t stop;
  sigemptyset(&stop);
  sigaddset(&stop, SIGINT);
  sigaddset(&stop, SIGTERM);
  int sig = 0;
  sigwait(&stop, &sig);
  try {
    client.disconnect()->wait_for(5s);
  } catch (const mqtt::exception& e) {
    spdlog::debug("ingest: {} disconnect: {}", client_id, e.what());
  }
  frame(std::string{'D'});
  // A message in hand is answered by the worker: committed ('A', the callback returns) or not
  // ('N', the callback parks). Then this process ends; a parked message is not acknowledged.
  std::unique_lock lock(state_mu);
  idle.wait_for(lock, 60s, [&] { return !in_callback || parked; });
  // With a parked callback, Paho's receive thread never comes back, and the client's destructor
  // would wait for it: end the process here (the session's state is the broker's).
  if (parked || in_callback) ::_exit(3);
  return 0;
}

}  // namespace fleetgw::ingest
