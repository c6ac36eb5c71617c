// The ingest worker (ingest_worker.h): Paho MQTT 5 client, message callback, PostgreSQL writes.
#include "gateway/ingest/ingest_worker.h"

#include <fmt/format.h>
#include <mqtt/async_client.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <ctime>
#include <iostream>
#include <map>
#include <mutex>
#include <set>
#include <thread>

#include "gateway/common/untrusted_text.h"
#include "gateway/ingest/envelope_rows.h"
#include "gateway/ingest/ingest_store.h"
#include "gateway/uplink/mqtt_connection.h"

namespace fleetgw::ingest {
namespace {

using namespace std::chrono_literals;

struct Counters {
  std::int64_t messages = 0;
  std::int64_t records = 0;
  std::int64_t inserted = 0;
  std::int64_t duplicates = 0;
  std::map<std::string, std::int64_t> rejected;  // by reason code
};

std::string summary(const Counters& c) {
  std::string rejects;
  std::int64_t total = 0;
  for (const auto& [code, n] : c.rejected) {
    rejects += fmt::format("{}{}={}", rejects.empty() ? "" : ",", code, n);
    total += n;
  }
  return fmt::format(
      "ingest: {} messages, {} records, {} rows inserted, {} duplicates ignored, {} rejected{}",
      c.messages, c.records, c.inserted, c.duplicates, total,
      rejects.empty() ? "" : " (" + rejects + ")");
}

std::string default_client_id(const std::string& group) {
  char host[256] = {};
  if (::gethostname(host, sizeof host - 1) != 0) host[0] = '\0';
  return group + "-" + (host[0] != '\0' ? host : "worker");
}

// Handles messages on Paho's receive thread; everything it touches besides the counters is
// used from that thread only.
class Worker {
 public:
  Worker(const IngestOptions& o, IngestStore& store) : o_(o), store_(store) {}

  void on_message(const mqtt::const_message_ptr& m) {
    const std::string& topic = m->get_topic();
    const std::string& payload = m->get_payload();
    auto decoded = decode_message(o_.topic_prefix, topic, payload);
    if (auto* reject = std::get_if<Reject>(&decoded)) {
      rejected(topic, *reject, payload.size());
      return;
    }
    const Decoded& d = std::get<Decoded>(decoded);
    for (std::chrono::milliseconds backoff = 100ms;; backoff = std::min(backoff * 2, 5000ms)) {
      try {
        const WriteStats w = store_.write(d);
        if (db_failing_) spdlog::info("ingest: PostgreSQL writes succeed again");
        db_failing_ = false;
        std::lock_guard lock(mutex_);
        ++counters_.messages;
        counters_.records += static_cast<std::int64_t>(d.records);
        counters_.inserted += w.inserted;
        counters_.duplicates += w.duplicates;
        return;  // Paho sends the PUBACK after this return: the rows are committed.
      } catch (const PgError& e) {
        if (!is_transient(e)) {
          rejected(topic, Reject{"database_refused", e.what()}, payload.size());
          return;
        }
        if (!db_failing_) {
          spdlog::warn("ingest: {} (the message stays unacknowledged; retrying)", e.what());
        }
        db_failing_ = true;
      }
      if (stopping_.load()) {
        spdlog::warn(
            "ingest: stopping with an uncommitted message from {}: not acknowledged, "
            "the broker delivers it again",
            common::untrusted_excerpt(topic, 200));
        std::cerr << summary(counters()) << '\n';
        // Returning would acknowledge it: leave without returning to Paho.
        std::_Exit(3);
      }
      std::this_thread::sleep_for(backoff);
    }
  }

  Counters counters() {
    std::lock_guard lock(mutex_);
    return counters_;
  }
  void stop() { stopping_.store(true); }

 private:
  void rejected(const std::string& topic, const Reject& r, std::size_t bytes) {
    bool first = false;
    {
      std::lock_guard lock(mutex_);
      first = ++counters_.rejected[r.code] == 1;
      ++counters_.messages;
    }
    const std::string where = common::untrusted_excerpt(topic, 200);
    if (first) {
      spdlog::warn(
          "ingest: rejected a message on {}: {} ({}; later ones with this reason are "
          "counted, not logged)",
          where, r.detail, r.code);
    } else {
      spdlog::debug("ingest: rejected a message on {}: {} ({})", where, r.detail, r.code);
    }
    for (std::chrono::milliseconds backoff = 100ms;; backoff = std::min(backoff * 2, 5000ms)) {
      try {
        store_.write_reject(topic, r, bytes);
        return;
      } catch (const PgError& e) {
        if (!is_transient(e)) {
          spdlog::error("ingest: could not record a rejected message: {}", e.what());
          return;
        }
      }
      if (stopping_.load()) std::_Exit(3);
      std::this_thread::sleep_for(backoff);
    }
  }

  const IngestOptions& o_;
  IngestStore& store_;
  bool db_failing_ = false;
  std::atomic<bool> stopping_{false};
  std::mutex mutex_;
  Counters counters_;
};

mqtt::connect_options connect_options(const IngestOptions& o) {
  uplink::ConnectionSettings s;
  s.broker_uri = uplink::normalise_broker_uri(o.broker);
  if (!o.ca_file.empty() || !o.cert_file.empty() || uplink::uses_tls(s.broker_uri)) {
    uplink::TlsConfig tls;
    tls.ca_file = o.ca_file;
    tls.cert_file = o.cert_file;
    tls.key_file = o.key_file;
    s.tls = tls;
  }
  s.username = o.username;
  s.password = o.password;
  mqtt::connect_options opts = uplink::make_connect_options(s);
  opts.set_mqtt_version(MQTTVERSION_5);
  // A persistent session: what the broker queued while this worker was away is delivered when
  // it comes back (clean start off + a session expiry interval).
  opts.set_clean_start(false);
  opts.set_automatic_reconnect(1s, 30s);
  // Set on the options object: Paho C++ 1.2.0's connect_options_builder::properties() loses
  // them (seen: session expiry 0, "session present" never set).
  opts.set_properties(mqtt::properties{
      {mqtt::property::SESSION_EXPIRY_INTERVAL, static_cast<int>(o.session_expiry_s)},
      // The broker drops, instead of sending, anything bigger (the gateway's largest message
      // is a 16 KiB telemetry batch): hostile giants never reach this process's memory.
      {mqtt::property::MAXIMUM_PACKET_SIZE, static_cast<int>(o.max_packet_bytes)}});
  return opts;
}

int print_gaps(IngestStore& store) {
  const std::vector<Gap> gaps = store.gaps();
  for (const Gap& g : gaps) {
    std::cout << fmt::format("{}\t{}\t{}..{}\n", g.vehicle_id, g.store_id, g.first_missing,
                             g.last_missing);
  }
  std::cerr << fmt::format("ingest: {} gap{}\n", gaps.size(), gaps.size() == 1 ? "" : "s");
  return gaps.empty() ? 0 : 1;
}

}  // namespace

int run_ingest(const IngestOptions& o) {
  if (o.pg.empty()) {
    std::cerr << "fleetgw ingest: --pg CONNINFO is required\n";
    return 2;
  }
  IngestStore store(o.pg, o.batch_rows);
  try {
    const int applied = store.connect();
    if (applied > 0) spdlog::info("ingest: applied {} schema migration(s)", applied);
  } catch (const PgError& e) {
    std::cerr << "fleetgw ingest: " << e.what() << '\n';
    return 1;
  }
  if (o.gaps) return print_gaps(store);

  // SIGINT/SIGTERM are taken with sigtimedwait below; blocked before Paho starts its threads,
  // which inherit the mask, so no handler runs anywhere.
  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  sigaddset(&stop_signals, SIGINT);
  sigaddset(&stop_signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);

  const std::string client_id = o.client_id.empty() ? default_client_id(o.group) : o.client_id;
  const std::string uri = uplink::normalise_broker_uri(o.broker);
  mqtt::async_client client(uri, client_id, mqtt::create_options(MQTTVERSION_5));
  Worker worker(o, store);
  const std::string filter = "$share/" + o.group + "/" + o.topic_prefix + "/#";
  client.set_message_callback([&worker](mqtt::const_message_ptr m) { worker.on_message(m); });
  // (Re)subscribe on every connection: a no-op on a resumed session, needed after it expired.
  client.set_connected_handler([&client, &filter](const std::string&) {
    try {
      client.subscribe(filter, 1);
    } catch (const mqtt::exception& e) {
      spdlog::error("ingest: subscribe {} failed: {}", filter, e.what());
    }
  });
  client.set_connection_lost_handler([](const std::string& cause) {
    spdlog::warn("ingest: connection to the broker lost ({}); reconnecting",
                 cause.empty() ? "no reason given" : cause);
  });
  try {
    const mqtt::token_ptr tok = client.connect(connect_options(o));
    tok->wait();
    const bool resumed = tok->get_connect_response().is_session_present();
    // Subscribed before we say so: a shared subscription without members drops what arrives.
    client.subscribe(filter, 1)->wait();
    spdlog::info("ingest: connected to {} as {} (session {}), subscribed to {}", uri, client_id,
                 resumed ? "resumed" : "new", filter);
  } catch (const mqtt::exception& e) {
    std::cerr << "fleetgw ingest: cannot connect to " << uri << ": " << e.what() << '\n';
    return 1;
  }

  const auto start = std::chrono::steady_clock::now();
  auto next_report = start + 60s;
  for (;;) {
    timespec wait{1, 0};
    if (sigtimedwait(&stop_signals, nullptr, &wait) > 0) break;
    const auto now = std::chrono::steady_clock::now();
    if (o.duration_s > 0 && now - start >= std::chrono::duration<double>(o.duration_s)) break;
    if (now >= next_report) {
      spdlog::info("{}", summary(worker.counters()));
      next_report = now + 60s;
    }
  }
  worker.stop();
  try {
    client.disconnect()->wait_for(5s);
  } catch (const mqtt::exception& e) {
    spdlog::debug("ingest: disconnect: {}", e.what());
  }
  std::cerr << summary(worker.counters()) << '\n';
  return 0;
}

}  // namespace fleetgw::ingest
