#include "gateway/runtime/status_provider.h"

#include <chrono>

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

}  // namespace

nlohmann::json make_status_json(const StatusInputs& in) {
  using nlohmann::json;
  const Micros wall_now =
      in.wall_now.count() > 0
          ? in.wall_now
          : std::chrono::duration_cast<Micros>(std::chrono::system_clock::now().time_since_epoch());
  json j;
  j["schema"] = 1;
  j["version"] = FLEETGW_VERSION;
  j["vehicle_id"] = in.config.vehicle.id;
  j["uptime_s"] = seconds(in.now - in.started);

  const auto& h = in.transport.health();
  json frame_errors = json::object();
  const auto& bus = in.core.bus_stats();
  for (std::size_t k = 0; k < motinova::kReassemblyErrorKinds; ++k) {
    frame_errors[std::string(motinova::reassembly_error_name(
        static_cast<motinova::ReassemblyError>(k)))] = bus.errors[k];
  }
  j["bus"] = {{"transport", in.config.can.transport},
              {"interface", std::string(in.transport.name())},
              {"state", std::string(can::controller_state_name(h.state))},
              {"rx_frames", h.rx_frames},
              {"tx_frames", h.tx_frames},
              {"tx_failures", h.tx_failures},
              {"error_frames", h.error_frames},
              {"reopens", h.reopens},
              {"frame_errors", frame_errors},
              {"detail", h.detail}};

  // Every node a standard bike has, plus the fitted locks.
  std::vector<motinova::Node> expected{motinova::Node::kMc, motinova::Node::kBms,
                                       motinova::Node::kObc};
  for (int k = 0; k < motinova::kLockCount; ++k) {
    if (!in.config.protocol.lock_kinds[static_cast<std::size_t>(k)].empty()) {
      expected.push_back(motinova::lock_node(k));
    }
  }
  json nodes = json::array();
  const auto& registry = in.core.node().registry();
  for (const auto n : expected) {
    const auto& s = registry.node(n);
    json node = {{"name", std::string(motinova::node_name(n))}, {"online", s.online}};
    node["last_heard_age_s"] = s.present ? json(seconds(in.now - s.last_heard)) : json(nullptr);
    node["firmware"] = s.model ? json(s.model->fw) : json(nullptr);
    node["model"] = s.model ? json(s.model->model) : json(nullptr);
    node["fault_word"] = std::string(node::fault_state_name(registry.fault_word(n, in.now).state));
    nodes.push_back(std::move(node));
  }
  j["nodes"] = std::move(nodes);

  json faults = json::array();
  for (const auto& f : in.core.live().faults) {
    faults.push_back({{"node", f.node},
                      {"code", f.code >= 0 ? json(f.code) : json(nullptr)},
                      {"name", f.name},
                      {"severity", f.severity}});
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

  json broker = {
      {"enabled", in.uplink != nullptr}, {"connected", false}, {"uri", ""}, {"last_error", ""}};
  if (in.uplink) {
    const auto s = in.uplink->stats();
    broker["connected"] = s.state == uplink::UplinkState::kConnected;
    broker["state"] = std::string(uplink::to_string(s.state));
    broker["uri"] = uplink::redact_uri(in.config.mqtt.uri);
    broker["acked_records"] = s.acked_records;
    broker["reconnects"] = s.reconnects;
    broker["last_publish_ok_us"] = s.last_publish_ok_us;
    if (s.state != uplink::UplinkState::kConnected && s.connect_failures > 0) {
      broker["last_error"] = "connect failed " + std::to_string(s.connect_failures) + " time(s)";
    }
    broker["connect_failures"] = s.connect_failures;
    // MQTT 5: publishes the broker refused (docs/uplink.md "MQTT 5"); the records stay queued.
    broker["protocol"] = in.config.mqtt.protocol;
    broker["publish_refusals"] = s.publish_refusals;
    broker["last_publish_refusal"] = s.last_publish_refusal;
    broker["last_publish_refusal_code"] = s.last_publish_refusal_code;
    broker["last_publish_refusal_us"] = s.last_publish_refusal_us;
    broker["refused_records"] = s.refused_records;
  }
  if (in.uplink && in.uplink_failure) {
    const auto& f = *in.uplink_failure;
    broker["last_connect_error"] = f.last_connect_error;
    broker["last_connect_error_us"] = f.last_connect_error_us;
    broker["last_connect_error_age_s"] =
        f.last_connect_error_us > 0
            ? json(std::max(0.0, seconds(wall_now - Micros(f.last_connect_error_us))))
            : json(nullptr);
    broker["tls_failures"] = f.tls_failures;
    if (!broker["connected"].get<bool>() && !f.last_connect_error.empty()) {
      // The reason, not only a count: "TLS: certificate verify failed (...)".
      broker["last_error"] = f.last_connect_error;
    }
  }
  j["broker"] = std::move(broker);
  if (in.uplink) {
    // Every command payload the uplink did not hand on, by class (docs/commands.md "Bursts and
    // floods"); `busy` ones were answered.
    const auto s = in.uplink->stats();
    j["commands"] = {{"received", s.commands_received},
                     {"unauthenticated", s.commands_unauthenticated},
                     {"busy", s.commands_busy},
                     {"dropped", s.commands_dropped},
                     {"dropped_by_reason",
                      {{"oversized", s.commands_dropped_oversized},
                       {"undecodable", s.commands_dropped_undecodable},
                       {"unauthenticated", s.commands_dropped_unauthenticated},
                       {"queue_full", s.commands_dropped_queue_full}}}};
  }

  uint64_t depth = 0;
  for (const auto& d : in.store.outbox_depth()) depth += d.entries;
  const auto oldest = in.store.oldest_unsent_us();
  j["outbox"] = {{"depth", depth},
                 {"oldest_unsent_age_s",
                  oldest ? json(std::max(0.0, seconds(in.now - Micros(*oldest)))) : json(nullptr)}};
  const uint64_t configured = static_cast<uint64_t>(in.config.storage.max_mb) * 1024 * 1024;
  j["disk"] = {{"used_bytes", in.store.live_bytes()}, {"budget_bytes", configured}};
  if (in.storage_health) {
    const auto& h = *in.storage_health;
    const uint64_t effective = h.effective_budget_bytes > 0 ? h.effective_budget_bytes : configured;
    j["disk"]["budget_bytes"] = effective;
    j["storage"] = {
        {"failing", h.failing},
        {"last_error", h.last_error},
        {"failed_writes", h.failed_writes},
        {"failing_since_us", h.failing_since_us},
        {"failing_for_s", h.failing && h.failing_since_us > 0
                              ? json(std::max(0.0, seconds(wall_now - Micros(h.failing_since_us))))
                              : json(nullptr)},
        {"configured_budget_bytes",
         h.configured_budget_bytes > 0 ? h.configured_budget_bytes : configured},
        {"effective_budget_bytes", effective},
        {"dropped_records", h.dropped_records}};
  }
  if (in.gnss) {
    // Judged on the feed's own (wall) clock, like the fix itself.
    const Micros gnss_now = in.gnss->wall_now();
    const auto& state = in.gnss->state();
    json g = {{"enabled", true},
              {"gpsd", in.gnss->endpoint()},
              {"connected", in.gnss->connected()},
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
