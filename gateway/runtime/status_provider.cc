#include "gateway/runtime/status_provider.h"

#include <algorithm>
#include <chrono>

#include "gateway/status/status_message.h"
#include "gateway/uplink/uplink_status.h"

namespace fleetgw::runtime {
namespace {

double seconds(Micros d) {
  return static_cast<double>(d.count()) / 1e6;
}

template <typename T>
nlohmann::json or_null(const std::optional<T>& v) {
  return v ? nlohmann::json(*v) : nlohmann::json(nullptr);
}

// What the bike is doing: the latest decoded values (null until heard; the speed limit in force
// once the MC's settings were read, by a speed-limit command or a zone) and the open ride, its
// distance as `fleetgw db rides` reports it (odometer when known, else integrated speed).
nlohmann::json vehicle_json(const LiveState& live, const std::optional<storage::RideRow>& ride,
                            std::optional<bool> parked) {
  nlohmann::json v = {{"speed_kmh", or_null(live.speed_kmh)},
                      {"soc_pct", or_null(live.soc_pct)},
                      {"odo_km", or_null(live.odo_km)},
                      {"assist", or_null(live.assist)},
                      {"speed_limit_kmh", or_null(live.speed_limit_kmh)},
                      {"riding", ride.has_value()},
                      {"ride", nullptr}};
  v["mode"] = parked ? nlohmann::json(*parked ? "parked" : "riding") : nlohmann::json(nullptr);
  if (ride) {
    const bool odometer = ride->start_odo_km && ride->end_odo_km;
    v["ride"] = {{"ride_id", ride->ride_id},
                 {"start_us", ride->start_us},
                 {"duration_s", ride->duration_s},
                 {"moving_s", ride->moving_s},
                 {"distance_km", odometer ? ride->distance_km : ride->distance_integrated_km},
                 {"max_speed_kmh", ride->max_speed_kmh},
                 {"soc_start_pct", or_null(ride->soc_start_pct)}};
  }
  return v;
}

// The bundle in force and the latest refusal, with its reason and where it came from.
nlohmann::json geofence_json(const GeofenceStatus& g, Micros wall_now) {
  using nlohmann::json;
  json out = {{"enabled", true},
              {"version", g.version > 0 ? json(g.version) : json(nullptr)},
              {"zones", g.zones},
              {"vertices", g.vertices},
              {"key_id", g.key_id},
              {"issued_at_us", g.issued_at_us},
              {"bundle_file", g.bundle_file},
              {"topics", g.topics},
              {"bundles_received", g.counters.offered},
              {"bundles_accepted", g.counters.accepted},
              {"bundles_refused", g.counters.refused},
              {"bundles_dropped", g.dropped},
              {"last_refusal", ""},
              {"last_refusal_reason", ""},
              {"last_refusal_topic", ""},
              {"last_refusal_age_s", nullptr},
              {"outside_operating_area", g.outside_operating_area}};
  if (const auto& r = g.counters.last_refusal) {
    out["last_refusal_reason"] = std::string(geofence::bundle_refusal_name(r->reason));
    out["last_refusal"] = out["last_refusal_reason"].get<std::string>() + ": " + r->detail;
    out["last_refusal_topic"] = g.last_refusal_topic;
    out["last_refusal_age_s"] = std::max(0.0, seconds(wall_now - g.counters.last_refusal_at));
  }
  return out;
}

Micros wall_clock(const StatusInputs& in) {
  return in.wall_now.count() > 0 ? in.wall_now
                                 : std::chrono::duration_cast<Micros>(
                                       std::chrono::system_clock::now().time_since_epoch());
}

// The outbox as the uplink counts it (records acked but not yet deleted are not waiting), or
// the store's own count without an uplink.
uplink::OutboxStats outbox_figures(const StatusInputs& in) {
  if (in.uplink) return {in.uplink->outbox_depth, in.uplink->oldest_unsent_created_us};
  uplink::OutboxStats o;
  for (const auto& d : in.store.outbox_depth()) o.depth += d.entries;
  o.oldest_created_us = in.store.oldest_unsent_us().value_or(0);
  return o;
}

// Every node a standard bike has, plus the fitted locks.
std::vector<motinova::Node> expected_nodes(const config::Config& config) {
  std::vector<motinova::Node> expected{motinova::Node::kMc, motinova::Node::kBms,
                                       motinova::Node::kObc};
  for (int k = 0; k < motinova::kLockCount; ++k) {
    if (!config.protocol.lock_kinds[static_cast<std::size_t>(k)].empty()) {
      expected.push_back(motinova::lock_node(k));
    }
  }
  return expected;
}

status::Health health_of(const StatusInputs& in, const uplink::OutboxStats& outbox,
                         Micros wall_now) {
  status::Health h;
  const auto& bus = in.transport.health();
  h.bus = status::BusFacts{std::string(in.transport.name()),
                           std::string(can::controller_state_name(bus.state)), bus.detail};
  const auto& registry = in.core.node().registry();
  h.nodes.emplace();
  for (const auto n : expected_nodes(in.config)) {
    const auto& s = registry.node(n);
    status::NodeFacts facts{std::string(motinova::node_name(n)), s.online, std::nullopt};
    if (s.present) facts.last_heard_age_s = seconds(in.now - s.last_heard);
    h.nodes->push_back(std::move(facts));
  }
  h.faults.emplace();
  for (const auto& f : in.core.live().faults) {
    std::optional<std::int64_t> code;
    if (f.code >= 0) code = f.code;
    h.faults->push_back({f.node, code, f.name, f.severity});
  }
  h.has_locks = true;
  status::BrokerFacts b;
  b.enabled = in.uplink.has_value();
  if (const auto& s = in.uplink) {
    b.connected = s->state == uplink::UplinkState::kConnected;
    b.uri = uplink::redact_uri(in.config.mqtt.uri);
    if (!b.connected && !s->last_connect_error.empty()) {
      // The reason, not only a count: "TLS: certificate verify failed (...)".
      b.last_error = s->last_connect_error;
    } else if (!b.connected && s->connect_failures > 0) {
      b.last_error = "connect failed " + std::to_string(s->connect_failures) + " time(s)";
    }
    b.last_publish_refusal = s->last_publish_refusal;
    b.refused_records = s->refused_records;
  }
  h.broker = std::move(b);
  if (in.gnss) h.gnss = status::GnssFacts{true, in.gnss->connected(), in.gnss->endpoint()};
  const std::uint64_t configured = static_cast<std::uint64_t>(in.config.storage.max_mb) << 20;
  std::uint64_t budget = configured;
  if (const auto& sh = in.storage_health) {
    status::StorageFacts f;
    f.failing = sh->failing;
    f.last_error = sh->last_error;
    f.failed_writes = sh->failed_writes;
    f.failing_since_us = sh->failing_since_us;
    if (sh->failing && sh->failing_since_us > 0) {
      f.failing_for_s = std::max(0.0, seconds(wall_now - Micros(sh->failing_since_us)));
    }
    f.configured_budget_bytes =
        sh->configured_budget_bytes > 0 ? sh->configured_budget_bytes : configured;
    f.effective_budget_bytes =
        sh->effective_budget_bytes > 0 ? sh->effective_budget_bytes : configured;
    f.dropped_records = sh->dropped_records;
    budget = f.effective_budget_bytes;
    h.storage = std::move(f);
  }
  h.disk = status::DiskFacts{in.store.live_bytes(), budget};
  status::OutboxFacts o{outbox.depth, std::nullopt};
  if (outbox.oldest_created_us != 0) {
    o.oldest_unsent_age_s = std::max(0.0, seconds(in.now - Micros(outbox.oldest_created_us)));
  }
  h.outbox = o;
  return h;
}

}  // namespace

status::Health make_status_health(const StatusInputs& in) {
  return health_of(in, outbox_figures(in), wall_clock(in));
}

v1::Status make_status_message(const StatusInputs& in) {
  const uplink::OutboxStats outbox = outbox_figures(in);
  v1::Status s;
  s.set_firmware_version(FLEETGW_VERSION);
  s.set_bus_state(in.bus_state);
  s.set_outbox_depth(outbox.depth);
  s.set_oldest_unsent_created_at_us(outbox.oldest_created_us);
  if (in.uplink) uplink::fill_status(s, *in.uplink);
  status::fill_status(s, health_of(in, outbox, wall_clock(in)));
  return s;
}

nlohmann::json make_status_json(const StatusInputs& in) {
  using nlohmann::json;
  const Micros wall_now = wall_clock(in);
  const uplink::OutboxStats outbox = outbox_figures(in);
  // The judged keys come from the same facts as the published Status's verdict.
  const status::Health h = health_of(in, outbox, wall_now);
  json j;
  j["schema"] = 1;
  j["version"] = FLEETGW_VERSION;
  j["vehicle_id"] = in.config.vehicle.id;
  j["uptime_s"] = seconds(in.now - in.started);

  const auto& bh = in.transport.health();
  json frame_errors = json::object();
  const auto& bus = in.core.bus_stats();
  for (std::size_t k = 0; k < motinova::kReassemblyErrorKinds; ++k) {
    frame_errors[std::string(motinova::reassembly_error_name(
        static_cast<motinova::ReassemblyError>(k)))] = bus.errors[k];
  }
  j["bus"] = {{"transport", in.config.can.transport},
              {"interface", h.bus->interface},
              {"state", h.bus->state},
              {"rx_frames", bh.rx_frames},
              {"tx_frames", bh.tx_frames},
              {"tx_failures", bh.tx_failures},
              {"error_frames", bh.error_frames},
              {"reopens", bh.reopens},
              {"frame_errors", frame_errors},
              {"detail", h.bus->detail}};

  json nodes = json::array();
  const auto& registry = in.core.node().registry();
  const auto expected = expected_nodes(in.config);
  for (std::size_t i = 0; i < expected.size(); ++i) {
    const auto n = expected[i];
    const auto& facts = (*h.nodes)[i];
    const auto& s = registry.node(n);
    json node = {{"name", facts.name}, {"online", facts.online}};
    node["last_heard_age_s"] = or_null(facts.last_heard_age_s);
    node["firmware"] = s.model ? json(s.model->fw) : json(nullptr);
    node["model"] = s.model ? json(s.model->model) : json(nullptr);
    node["fault_word"] = std::string(node::fault_state_name(registry.fault_word(n, in.now).state));
    nodes.push_back(std::move(node));
  }
  j["nodes"] = std::move(nodes);

  json faults = json::array();
  for (const auto& f : *h.faults) {
    faults.push_back(
        {{"node", f.node}, {"code", or_null(f.code)}, {"name", f.name}, {"severity", f.severity}});
  }
  j["faults"] = std::move(faults);
  json locks = json::array();
  for (std::size_t k = 0; k < in.core.live().locks.size(); ++k) {
    const auto& kind = in.config.protocol.lock_kinds[k];
    if (kind.empty()) continue;  // not fitted
    const auto& l = in.core.live().locks[k];
    locks.push_back({{"kind", kind}, {"state", l.state_raw < 0 ? "unknown" : l.state}});
  }
  j["locks"] = std::move(locks);
  j["vehicle"] = vehicle_json(in.core.live(), in.open_ride, in.parked);

  const status::BrokerFacts& b = *h.broker;
  json broker = {{"enabled", b.enabled},
                 {"connected", b.connected},
                 {"uri", b.uri},
                 {"last_error", b.last_error}};
  if (const auto& s = in.uplink) {
    broker["state"] = std::string(uplink::to_string(s->state));
    broker["acked_records"] = s->acked_records;
    broker["reconnects"] = s->reconnects;
    broker["last_publish_ok_us"] = s->last_publish_ok_us;
    broker["connect_failures"] = s->connect_failures;
    // MQTT 5: publishes the broker refused (docs/uplink.md "MQTT 5"); the records stay queued.
    broker["protocol"] = in.config.mqtt.protocol;
    broker["publish_refusals"] = s->publish_refusals;
    broker["last_publish_refusal"] = b.last_publish_refusal;
    broker["last_publish_refusal_code"] = s->last_publish_refusal_code;
    broker["last_publish_refusal_us"] = s->last_publish_refusal_us;
    broker["refused_records"] = b.refused_records;
    broker["last_connect_error"] = s->last_connect_error;
    broker["last_connect_error_us"] = s->last_connect_error_us;
    broker["last_connect_error_age_s"] =
        s->last_connect_error_us > 0
            ? json(std::max(0.0, seconds(wall_now - Micros(s->last_connect_error_us))))
            : json(nullptr);
    broker["tls_failures"] = s->tls_failures;
    // Every command payload the uplink did not hand on, by class (docs/commands.md "Bursts and
    // floods"); `busy` ones were answered.
    j["commands"] = {{"received", s->commands_received},
                     {"unauthenticated", s->commands_unauthenticated},
                     {"busy", s->commands_busy},
                     {"dropped", s->commands_dropped},
                     {"dropped_by_reason",
                      {{"oversized", s->commands_dropped_oversized},
                       {"undecodable", s->commands_dropped_undecodable},
                       {"unauthenticated", s->commands_dropped_unauthenticated},
                       {"queue_full", s->commands_dropped_queue_full}}}};
  }
  j["broker"] = std::move(broker);

  j["outbox"] = {{"depth", h.outbox->depth},
                 {"oldest_unsent_age_s", or_null(h.outbox->oldest_unsent_age_s)}};
  j["disk"] = {{"used_bytes", h.disk->used_bytes}, {"budget_bytes", h.disk->budget_bytes}};
  if (const auto& st = h.storage) {
    j["storage"] = {{"failing", st->failing},
                    {"last_error", st->last_error},
                    {"failed_writes", st->failed_writes},
                    {"failing_since_us", st->failing_since_us},
                    {"failing_for_s", or_null(st->failing_for_s)},
                    {"configured_budget_bytes", st->configured_budget_bytes},
                    {"effective_budget_bytes", st->effective_budget_bytes},
                    {"dropped_records", st->dropped_records}};
  }
  if (in.gnss) {
    // Judged on the feed's own (wall) clock, like the fix itself.
    const Micros gnss_now = in.gnss->wall_now();
    const auto& state = in.gnss->state();
    json g = {{"enabled", h.gnss->enabled},
              {"gpsd", h.gnss->gpsd},
              {"connected", h.gnss->connected},
              {"fix", false},
              {"reason", std::string(state.reason(gnss_now))},
              {"fixes", state.fixes()}};
    if (const auto p = state.current(gnss_now)) {
      g["fix"] = true;
      g["lat"] = p->lat_deg;
      g["lon"] = p->lon_deg;
      g["hdop"] = p->hdop ? json(*p->hdop) : json(nullptr);
      g["horizontal_error_m"] =
          p->horizontal_error_m ? json(*p->horizontal_error_m) : json(nullptr);
      g["satellites"] = p->satellites;
    }
    if (const auto& last = state.last_fix()) {
      g["last_fix_age_s"] = std::max(0.0, seconds(gnss_now - last->received_at));
    }
    j["gnss"] = std::move(g);
  }
  if (in.geofence) j["geofence"] = geofence_json(*in.geofence, wall_now);
  if (in.campaigns) j["campaigns"] = *in.campaigns;
  if (const auto v = in.revocation_version) {
    j["revocations"] = {{"version", *v > 0 ? json(*v) : json(nullptr)}};
  }
  return j;
}

}  // namespace fleetgw::runtime
