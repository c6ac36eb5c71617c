// The GBFS, MDS and registry routes (registry_routes.h).
#include "backend/web/registry_routes.h"

#include <chrono>
#include <ctime>
#include <map>
#include <memory>
#include <mutex>

#include "backend/web/fleet_api.h"
#include "backend/web/gbfs_feeds.h"
#include "backend/web/mds_api.h"
#include "backend/web/registry_reservations.h"
#include "backend/web/registry_store.h"
#include "backend/web/secrets.h"

namespace fleetgw::web {
namespace {

using nlohmann::json;

constexpr std::string_view kMdsType = "application/vnd.mds+json;version=2.0";
constexpr std::int64_t kHourUsR = 3'600'000'000;

void standards_json(httplib::Response& res, int status, const json& body,
                    std::string_view type = "application/json; charset=utf-8") {
  res.status = status;
  res.set_header("Cache-Control", "no-store");
  res.set_content(to_json_text(body), std::string(type).c_str());
}

// One feed's latest build. A request finding it older than the feed's window starts one
// rebuild and is answered from the previous build meanwhile (so is every request during the
// rebuild): the database sees at most one build per feed per window per instance, and a slow
// build never holds requests back. Only the very first requests wait for the first build.
struct FeedSlot {
  std::mutex mu;
  std::shared_ptr<const std::string> body;
  std::string etag;
  std::int64_t built_us = 0;
  bool building = false;
};

struct StandardsState {
  PgPool& pool;
  Auth& auth;
  StandardsOptions o;
  bool tls;
  AuthoriseFn authorise;
  std::map<std::string, std::unique_ptr<FeedSlot>, std::less<>> feeds;
};

// The request's origin for absolute links: --public-url, else scheme and a Host header made only
// of host-name characters (anything else falls back to the loopback name).
std::string feed_base_url(const StandardsState& st, const httplib::Request& req) {
  if (!st.o.public_url.empty()) {
    std::string u = st.o.public_url;
    while (!u.empty() && u.back() == '/') u.pop_back();
    return u;
  }
  std::string host = req.get_header_value("Host");
  for (const char ch : host) {
    const bool ok = (ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') ||
                    (ch >= '0' && ch <= '9') || ch == '.' || ch == '-' || ch == ':' || ch == '[' ||
                    ch == ']';
    if (!ok || host.size() > 255) {
      host = "localhost";
      break;
    }
  }
  if (host.empty()) host = "localhost";
  return std::string(st.tls ? "https://" : "http://") + host;
}

bool etag_matches(const std::string& header, const std::string& etag) {
  const auto strip = [](std::string_view t) {
    while (!t.empty() && t.front() == ' ') t.remove_prefix(1);
    while (!t.empty() && t.back() == ' ') t.remove_suffix(1);
    if (t.starts_with("W/")) t.remove_prefix(2);
    return t;
  };
  std::string_view rest = header;
  while (!rest.empty()) {
    const std::size_t comma = rest.find(',');
    const std::string_view tag = strip(rest.substr(0, comma));
    if (tag == "*" || tag == strip(etag)) return true;
    rest = comma == std::string_view::npos ? std::string_view() : rest.substr(comma + 1);
  }
  return false;
}

// The feed's body and its ETag, built now.
std::pair<std::string, std::string> build_feed(StandardsState& st, const std::string& name,
                                               int ttl_s, std::int64_t t) {
  json data;
  if (name == "system_information") {
    data = gbfs_system_information_data(st.o);
  } else {
    auto c = st.pool.lease();
    if (name == "vehicle_types") data = gbfs_vehicle_types_data(*c, st.o);
    if (name == "vehicle_status") data = gbfs_vehicle_status_data(*c, st.o, t);
    if (name == "geofencing_zones") data = gbfs_geofencing_zones_data(*c, st.o);
  }
  // Weak: equal data is the same feed whatever its last_updated says.
  std::string etag = "W/\"" + sha256_hex(to_json_text(data)).substr(0, 32) + "\"";
  return {to_json_text(gbfs_document(data, ttl_s, t)), std::move(etag)};
}

void serve_feed(StandardsState& st, const std::string& name, int ttl_s, std::int64_t window_us,
                const httplib::Request& req, httplib::Response& res) {
  FeedSlot& slot = *st.feeds.at(name);
  std::shared_ptr<const std::string> body;
  std::string etag;
  bool rebuild = false;
  {
    std::unique_lock lock(slot.mu);
    const std::int64_t t = now_us();
    if (!slot.body) {
      // The first build: every request waits for it (under the lock).
      auto [b, e] = build_feed(st, name, ttl_s, t);
      slot.body = std::make_shared<const std::string>(std::move(b));
      slot.etag = std::move(e);
      slot.built_us = t;
    } else if (t - slot.built_us >= window_us && !slot.building) {
      slot.building = true;
      rebuild = true;
    }
    body = slot.body;
    etag = slot.etag;
  }
  if (rebuild) {
    // This request builds (it waits for it; everyone else is answered from the old build).
    struct Done {
      FeedSlot& s;
      ~Done() {
        std::lock_guard l(s.mu);
        s.building = false;
      }
    } done{slot};
    const std::int64_t t = now_us();
    auto [b, e] = build_feed(st, name, ttl_s, t);
    auto fresh = std::make_shared<const std::string>(std::move(b));
    std::lock_guard lock(slot.mu);
    slot.body = fresh;
    slot.etag = e;
    slot.built_us = t;
    body = std::move(fresh);
    etag = std::move(e);
  }
  res.set_header("ETag", etag);
  res.set_header("Cache-Control", "public, max-age=" + std::to_string(ttl_s));
  res.set_header("Access-Control-Allow-Origin", "*");
  if (req.has_header("If-None-Match") &&
      etag_matches(req.get_header_value("If-None-Match"), etag)) {
    res.status = 304;
    return;
  }
  res.status = 200;
  res.set_content(*body, "application/json");
}

// Accept negotiation: true when 2.0 may be served.
bool accepts_mds_2(const std::string& accept) {
  if (accept.empty()) return true;
  std::string_view rest = accept;
  while (!rest.empty()) {
    const std::size_t comma = rest.find(',');
    std::string item(rest.substr(0, comma));
    rest = comma == std::string_view::npos ? std::string_view() : rest.substr(comma + 1);
    std::string compact;
    for (const char ch : item) {
      if (ch != ' ' && ch != '\t')
        compact += static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
    }
    const std::size_t semi = compact.find(';');
    const std::string type = compact.substr(0, semi);
    const std::string params = semi == std::string::npos ? "" : compact.substr(semi);
    if (type == "*/*" || type == "application/*" || type == "application/json") return true;
    if (type != "application/vnd.mds+json") continue;
    const std::size_t v = params.find("version=");
    if (v == std::string::npos) return true;
    std::string version = params.substr(v + 8);
    version = version.substr(0, version.find(';'));
    if (version == "2.0" || version == "\"2.0\"" || version.starts_with("2.0.")) return true;
  }
  return false;
}

// "YYYY-MM-DDTHH" as µs since the epoch (UTC), nullopt when malformed.
std::optional<std::int64_t> parse_hour(const std::string& s) {
  if (s.size() != 13 || s[4] != '-' || s[7] != '-' || s[10] != 'T') return std::nullopt;
  for (const int i : {0, 1, 2, 3, 5, 6, 8, 9, 11, 12}) {
    if (s[i] < '0' || s[i] > '9') return std::nullopt;
  }
  std::tm tm{};
  tm.tm_year = std::stoi(s.substr(0, 4)) - 1900;
  tm.tm_mon = std::stoi(s.substr(5, 2)) - 1;
  tm.tm_mday = std::stoi(s.substr(8, 2));
  tm.tm_hour = std::stoi(s.substr(11, 2));
  if (tm.tm_mon > 11 || tm.tm_mday < 1 || tm.tm_mday > 31 || tm.tm_hour > 23) return std::nullopt;
  const std::tm asked = tm;
  const std::time_t t = timegm(&tm);
  if (tm.tm_mday != asked.tm_mday) return std::nullopt;  // 2026-02-30 normalised away
  return static_cast<std::int64_t>(t) * 1'000'000;
}

std::optional<std::int64_t> parse_ms_param(const std::string& s) {
  if (s.empty() || s.size() > 18) return std::nullopt;
  std::int64_t v = 0;
  for (const char ch : s) {
    if (ch < '0' || ch > '9') return std::nullopt;
    v = v * 10 + (ch - '0');
  }
  return v;
}

std::string url_encode(const std::string& s) {
  static constexpr char kHex[] = "0123456789ABCDEF";
  std::string out;
  for (const char ch : s) {
    const auto b = static_cast<unsigned char>(ch);
    if ((b >= 'a' && b <= 'z') || (b >= 'A' && b <= 'Z') || (b >= '0' && b <= '9') || b == '-' ||
        b == '_' || b == '.' || b == '~') {
      out += ch;
    } else {
      out += '%';
      out += kHex[b >> 4];
      out += kHex[b & 15];
    }
  }
  return out;
}

struct MdsCall {
  std::string key;        // the payload's name: "trips", "vehicles_status", ...
  bool realtime = false;  // vehicles, vehicles/status: last_updated and ttl
  std::function<json(PgConnection&, MdsPageRequest, bool*)> fetch;
};

// Auth, negotiation, paging and the envelope around one MDS payload. `prepare` parses the
// request's parameters and returns the call, or nullopt after writing a 400/404.
void serve_mds(StandardsState& st, const httplib::Request& req, httplib::Response& res,
               const std::function<std::optional<MdsCall>()>& prepare) {
  const auto refuse = [&](int status, std::string_view message) {
    standards_json(res, status, {{"error", message}}, "application/json; charset=utf-8");
  };
  if (!accepts_mds_2(req.get_header_value("Accept"))) {
    refuse(406, "only MDS 2.0 is served: Accept application/vnd.mds+json;version=2.0");
    return;
  }
  const std::string authz = req.get_header_value("Authorization");
  std::optional<std::string> agency;
  if (authz.size() > 7 && (authz.starts_with("Bearer ") || authz.starts_with("bearer "))) {
    auto c = st.pool.lease();
    agency = agency_for_token(*c, std::string_view(authz).substr(7));
  }
  if (!agency) {
    res.set_header("WWW-Authenticate", "Bearer realm=\"mds\"");
    refuse(401, "an agency's bearer token is required (Authorization: Bearer ...)");
    return;
  }
  std::int64_t offset = 0;
  if (req.has_param("offset")) {
    const auto v = parse_ms_param(req.get_param_value("offset"));
    if (!v) {
      refuse(400, "offset: a non-negative whole number");
      return;
    }
    offset = *v;
  }
  const std::optional<MdsCall> call = prepare();
  if (!call) return;
  bool more = false;
  json items;
  {
    auto c = st.pool.lease();
    PgTransaction tx(*c);
    // JIT compiles these plans for longer than they run (gbfs_feeds.cc measured it).
    c->exec("SET LOCAL jit = off", "mds jit off");
    items = call->fetch(*c, {offset, st.o.mds_page_size}, &more);
    tx.commit();
  }
  json body = {{"version", "2.0.0"}, {call->key, items}};
  json next = nullptr;
  if (more) {
    std::string url = feed_base_url(st, req) + req.path + "?";
    for (const auto& [k, v] : req.params) {
      if (k != "offset") url += url_encode(k) + "=" + url_encode(v) + "&";
    }
    next = url + "offset=" + std::to_string(offset + st.o.mds_page_size);
  }
  body["links"] = {{"next", next}};
  if (call->realtime) {
    body["last_updated"] = now_us() / 1000;
    body["ttl"] = 0;
  }
  standards_json(res, 200, body, kMdsType);
}

// An hour parameter: the window [hour, hour + 1 h), or nullopt after a 400/404.
std::optional<std::pair<std::int64_t, std::int64_t>> hour_window(const httplib::Request& req,
                                                                 httplib::Response& res,
                                                                 const char* param) {
  if (!req.has_param(param)) {
    standards_json(res, 400, {{"error", std::string(param) + " (YYYY-MM-DDTHH, UTC) is required"}});
    return std::nullopt;
  }
  const auto from = parse_hour(req.get_param_value(param));
  if (!from) {
    standards_json(res, 400, {{"error", std::string(param) + ": expected YYYY-MM-DDTHH (UTC)"}});
    return std::nullopt;
  }
  if (*from + kHourUsR > now_us()) {
    standards_json(res, 404, {{"error", "that hour has not ended"}});
    return std::nullopt;
  }
  return std::pair{*from, *from + kHourUsR};
}

void registry_routes(httplib::Server& s, const std::shared_ptr<StandardsState>& st) {
  s.Get("/api/registry/vehicle-types", [st](const httplib::Request& req, httplib::Response& res) {
    if (!st->authorise(req, res, Role::Admin, "registry")) return;
    auto c = st->pool.lease();
    standards_json(res, 200, {{"vehicle_types", list_vehicle_types(*c)}});
  });
  s.Get("/api/registry/vehicles", [st](const httplib::Request& req, httplib::Response& res) {
    if (!st->authorise(req, res, Role::Admin, "registry")) return;
    auto c = st->pool.lease();
    standards_json(res, 200, {{"vehicles", list_registry_vehicles(*c)}});
  });
  // Each POST: admin, CSRF (authorise), a JSON object, audited with its outcome.
  const auto post = [&s, st](const char* path, const char* action,
                             std::function<json(PgConnection&, const json&, std::string&)> apply) {
    s.Post(path, [st, action, apply](const httplib::Request& req, httplib::Response& res) {
      const std::optional<std::string> who = st->authorise(req, res, Role::Admin, action);
      if (!who) return;
      const json body = json::parse(req.body, nullptr, false);
      std::string target;
      try {
        if (!body.is_object()) throw std::invalid_argument("expected a JSON object");
        json out;
        {
          auto c = st->pool.lease();
          out = apply(*c, body, target);
        }
        st->auth.audit(*who, req.remote_addr, action, target, "ok");
        standards_json(res, 200, out);
      } catch (const std::invalid_argument& e) {
        st->auth.audit(*who, req.remote_addr, action, target, "bad_request", e.what());
        standards_json(res, 400, {{"error", e.what()}});
      }
    });
  };
  post("/api/registry/vehicle-types", "registry_vehicle_type",
       [](PgConnection& c, const json& body, std::string& target) {
         const VehicleType t = vehicle_type_from_json(body);
         target = t.id;
         upsert_vehicle_type(c, t, now_us());
         return json{{"vehicle_type_id", t.id}};
       });
  post("/api/registry/vehicles", "registry_vehicle",
       [st](PgConnection& c, const json& body, std::string& target) {
         RegistryVehicle v = registry_vehicle_from_json(body);
         target = v.vehicle_id;
         if (v.provider_id.empty()) v.provider_id = st->o.provider_id;
         if (v.provider_name.empty()) v.provider_name = st->o.provider_name;
         const std::string device = upsert_vehicle(c, v, now_us());
         return json{{"vehicle_id", v.vehicle_id}, {"device_id", device}};
       });
  post("/api/registry/mds-agencies", "mds_agency_add",
       [](PgConnection& c, const json& body, std::string& target) {
         if (!body.contains("agency") || !body["agency"].is_string()) {
           throw std::invalid_argument("agency: required string");
         }
         target = body["agency"].get<std::string>();
         // Shown once: only its hash is kept.
         return json{{"agency", target}, {"token", add_mds_agency(c, target, now_us())}};
       });
}

void gbfs_routes(httplib::Server& s, const std::shared_ptr<StandardsState>& st) {
  s.Get("/gbfs/gbfs.json", [st](const httplib::Request& req, httplib::Response& res) {
    // Built per request (no database): its links follow the request's Host.
    const json data = gbfs_discovery_data(feed_base_url(*st, req));
    const std::string etag = "W/\"" + sha256_hex(to_json_text(data)).substr(0, 32) + "\"";
    res.set_header("ETag", etag);
    res.set_header("Cache-Control", "public, max-age=300");
    res.set_header("Access-Control-Allow-Origin", "*");
    if (req.has_header("If-None-Match") &&
        etag_matches(req.get_header_value("If-None-Match"), etag)) {
      res.status = 304;
      return;
    }
    res.set_content(to_json_text(gbfs_document(data, 300, now_us())), "application/json");
  });
  for (const GbfsFeed& f : kGbfsFeeds) {
    if (f.name == "gbfs") continue;
    const std::string name(f.name);
    st->feeds.emplace(name, std::make_unique<FeedSlot>());
    const std::int64_t window = name == "vehicle_status" ? 1'000'000 : 10'000'000;
    const int ttl = f.ttl_s;
    s.Get("/gbfs/" + name + ".json",
          [st, name, ttl, window](const httplib::Request& req, httplib::Response& res) {
            serve_feed(*st, name, ttl, window, req, res);
          });
  }
}

void mds_routes(httplib::Server& s, const std::shared_ptr<StandardsState>& st) {
  const StandardsOptions& o = st->o;
  const auto vehicles = [st, &o](bool status) {
    return [st, &o, status](const httplib::Request& req, httplib::Response& res) {
      serve_mds(*st, req, res, [&]() -> std::optional<MdsCall> {
        std::optional<std::string> device;
        if (req.matches.size() > 1) device = req.matches[1].str();
        if (status) {
          return MdsCall{"vehicles_status", true,
                         [&o, device](PgConnection& c, MdsPageRequest p, bool* more) {
                           return mds_vehicles_status(c, o, device, now_us(), p, more);
                         }};
        }
        return MdsCall{"vehicles", true,
                       [&o, device](PgConnection& c, MdsPageRequest p, bool* more) {
                         return mds_vehicles(c, o, device, p, more);
                       }};
      });
    };
  };
  s.Get("/mds/vehicles/status", vehicles(true));
  s.Get(R"(/mds/vehicles/status/([^/]+))", vehicles(true));
  s.Get("/mds/vehicles", vehicles(false));
  s.Get(R"(/mds/vehicles/([^/]+))", vehicles(false));
  const auto hourly = [st, &o](const char* param, const char* key, auto fetch) {
    return [st, &o, param, key, fetch](const httplib::Request& req, httplib::Response& res) {
      serve_mds(*st, req, res, [&]() -> std::optional<MdsCall> {
        const auto w = hour_window(req, res, param);
        if (!w) return std::nullopt;
        return MdsCall{key, false, [&o, w, fetch](PgConnection& c, MdsPageRequest p, bool* more) {
                         return fetch(c, o, w->first, w->second, p, more);
                       }};
      });
    };
  };
  s.Get("/mds/trips", hourly("end_time", "trips", mds_trips));
  s.Get("/mds/telemetry", hourly("telemetry_time", "telemetry", mds_telemetry));
  s.Get("/mds/events/historical", hourly("event_time", "events", mds_events));
  s.Get("/mds/events/recent", [st, &o](const httplib::Request& req, httplib::Response& res) {
    serve_mds(*st, req, res, [&]() -> std::optional<MdsCall> {
      const auto start = parse_ms_param(req.get_param_value("start_time"));
      const auto end = parse_ms_param(req.get_param_value("end_time"));
      const std::int64_t now_ms = now_us() / 1000;
      if (!start || !end || *end <= *start || *end > now_ms ||
          *start < now_ms - 14LL * 24 * 3600 * 1000) {
        standards_json(res, 400,
                       {{"error",
                         "start_time and end_time (ms since the epoch): end after start, "
                         "not in the future, start within the last 2 weeks"}});
        return std::nullopt;
      }
      const std::int64_t from = *start * 1000;
      const std::int64_t to = *end * 1000;
      return MdsCall{"events", false,
                     [&o, from, to](PgConnection& c, MdsPageRequest p, bool* more) {
                       return mds_events(c, o, from, to, p, more);
                     }};
    });
  });
  s.Get(R"(/mds/.*)", [](const httplib::Request&, httplib::Response& res) {
    standards_json(res, 404, {{"error", "no such MDS endpoint"}});
  });
}

}  // namespace

void mount_standards_routes(httplib::Server& server, PgPool& pool, Auth& auth,
                            const StandardsOptions& options, bool tls, AuthoriseFn authorise) {
  auto st = std::make_shared<StandardsState>(
      StandardsState{pool, auth, options, tls, std::move(authorise), {}});
  registry_routes(server, st);
  mount_reservation_routes(server, pool, auth, st->authorise);
  gbfs_routes(server, st);
  mds_routes(server, st);
}

}  // namespace fleetgw::web
