// Routes, limits and headers of `fleetgw serve` (http_server.h), over cpp-httplib.
#include "backend/web/http_server.h"

#include <httplib.h>
#include <spdlog/spdlog.h>

#include <atomic>
#include <filesystem>
#include <stdexcept>

#include "backend/common/pg.h"
#include "backend/web/api_tokens.h"
#include "backend/web/auth.h"
#include "backend/web/change_feed.h"
#include "backend/web/command_hub.h"
#include "backend/web/command_signer.h"
#include "backend/web/fleet_api.h"
#include "backend/web/registry_routes.h"
#include "backend/web/route_context.h"
#include "backend/web/secrets.h"

namespace fleetgw::web {
namespace {

using nlohmann::json;
constexpr std::string_view kCookie = "fleet_session";

std::pair<std::string, int> split_listen(const std::string& listen) {
  const std::size_t colon = listen.rfind(':');
  if (colon == std::string::npos || colon + 1 == listen.size()) {
    throw std::runtime_error("--listen " + listen + ": expected HOST:PORT");
  }
  std::string host = listen.substr(0, colon);
  if (host.size() >= 2 && host.front() == '[' && host.back() == ']') {
    host = host.substr(1, host.size() - 2);
  }
  int port = -1;
  try {
    port = std::stoi(listen.substr(colon + 1));
  } catch (const std::exception&) {
  }
  if (port < 0 || port > 65535) throw std::runtime_error("--listen " + listen + ": bad port");
  return {host, port};
}

// The origin allowed to send images (map tiles) besides ourselves: the tile URL's scheme and
// host, `{s}` (a subdomain letter) as a wildcard.
std::string tile_origin(const std::string& url) {
  const std::size_t scheme = url.find("://");
  if (scheme == std::string::npos) return "";
  const std::size_t end = url.find('/', scheme + 3);
  std::string origin = url.substr(0, end);
  const std::size_t s = origin.find("{s}");
  if (s != std::string::npos) origin.replace(s, 3, "*");
  for (const char ch : origin) {
    if (ch == ' ' || ch == ';' || ch == '\'' || ch == '"' || ch == ',') return "";  // not a URL
  }
  return origin;
}

std::string cookie_value(const httplib::Request& req, std::string_view name) {
  const std::string header = req.get_header_value("Cookie");
  std::string_view rest = header;
  while (!rest.empty()) {
    const std::size_t semi = rest.find(';');
    std::string_view part = rest.substr(0, semi);
    rest = semi == std::string_view::npos ? std::string_view() : rest.substr(semi + 1);
    while (!part.empty() && part.front() == ' ') part.remove_prefix(1);
    if (part.size() > name.size() && part.substr(0, name.size()) == name &&
        part[name.size()] == '=') {
      return std::string(part.substr(name.size() + 1));
    }
  }
  return "";
}

void reply(httplib::Response& res, int status, const json& body) {
  res.status = status;
  res.set_header("Cache-Control", "no-store");
  res.set_content(to_json_text(body), "application/json; charset=utf-8");
}

void error(httplib::Response& res, int status, std::string_view message) {
  reply(res, status, {{"error", message}});
}

}  // namespace

bool is_loopback_host(std::string_view host) {
  return host == "localhost" || host == "::1" || host.starts_with("127.");
}

struct WebServer::Impl {
  ServeOptions o;
  bool tls = false;
  PgPool pool;
  Auth auth;
  ChangeFeed feed;
  // Commands (command_routes.cc): both or neither; after feed, which their results wake.
  std::unique_ptr<CommandSigner> signer;
  std::unique_ptr<CommandHub> hub;
  RouteContext ctx;
  std::unique_ptr<httplib::Server> server;
  std::atomic<int> streams{0};
  int port = 0;

  explicit Impl(const ServeOptions& options)
      : o(options),
        tls(!options.tls_cert.empty()),
        pool(options.pg, static_cast<std::size_t>(options.db_connections)),
        auth(pool),
        feed(options.pg, std::chrono::milliseconds(options.poll_ms)),
        ctx{o, pool, auth, feed, nullptr, nullptr, {}} {
    if (o.signing_key.empty() != o.broker.empty()) {
      throw std::runtime_error("--broker and --signing-key go together (commands need both)");
    }
    if (!o.delegation.empty() && o.signing_key.empty()) {
      throw std::runtime_error("--delegation needs --signing-key");
    }
    if (!o.signing_key.empty()) {
      signer = std::make_unique<CommandSigner>(
          o.signing_key, o.delegation,
          o.key_id.empty() ? std::filesystem::path(o.signing_key).stem().string() : o.key_id);
      hub = std::make_unique<CommandHub>(o, pool, auth, [this] { feed.notify_commands(); });
      ctx.signer = signer.get();
      ctx.hub = hub.get();
    }
    ctx.authorise = [this](const httplib::Request& req, httplib::Response& res, Role needed,
                           std::string_view action) { return authorise(req, res, needed, action); };
  }

  // The session of the request, enforcing role, CSRF and origin; nullopt once a refusal has
  // been written to `res` (and audited when the request changes state).
  std::optional<Session> authorise(const httplib::Request& req, httplib::Response& res, Role needed,
                                   std::string_view action) {
    const bool changes_state = req.method != "GET" && req.method != "HEAD";
    // A machine client's API token (api_tokens.h), or a browser's session cookie.
    const std::string authz = req.get_header_value("Authorization");
    std::optional<Session> s;
    if (authz.starts_with("Bearer ")) {
      auto c = pool.lease();
      s = token_session(*c, std::string_view(authz).substr(7));
    } else {
      s = auth.session(cookie_value(req, kCookie));
    }
    if (!s) {
      if (changes_state)
        auth.audit(std::nullopt, req.remote_addr, action, req.path, "unauthenticated");
      error(res, 401, "login required");
      return std::nullopt;
    }
    if (changes_state && !s->bearer) {
      if (!same_origin(req)) {
        auth.audit(s->operator_name, req.remote_addr, action, req.path, "refused_origin");
        error(res, 403, "cross-origin request refused");
        return std::nullopt;
      }
      const std::string token = req.get_header_value("X-CSRF-Token");
      if (token.empty() || !same_secret(token, s->csrf_token)) {
        auth.audit(s->operator_name, req.remote_addr, action, req.path, "refused_csrf");
        error(res, 403, "missing or wrong CSRF token (X-CSRF-Token)");
        return std::nullopt;
      }
    }
    if (s->role < needed) {
      if (changes_state)
        auth.audit(s->operator_name, req.remote_addr, action, req.path, "forbidden");
      error(res, 403, std::string("this needs the role ") + std::string(role_name(needed)));
      return std::nullopt;
    }
    return s;
  }

  // A browser sends Origin on every cross-origin POST: it must be ours (scheme and Host).
  bool same_origin(const httplib::Request& req) const {
    if (!req.has_header("Origin")) return true;
    const std::string origin = req.get_header_value("Origin");
    return origin == std::string(tls ? "https://" : "http://") + req.get_header_value("Host");
  }

  std::string session_cookie(const std::string& value, int max_age_s) const {
    std::string c = std::string(kCookie) + "=" + value +
                    "; Path=/; HttpOnly; SameSite=Strict; Max-Age=" + std::to_string(max_age_s);
    if (tls) c += "; Secure";
    return c;
  }

  void routes();
  void login(const httplib::Request& req, httplib::Response& res);
  void events(const httplib::Request& req, httplib::Response& res);
};

void WebServer::Impl::login(const httplib::Request& req, httplib::Response& res) {
  // JSON only: a cross-site HTML form cannot send it without a CORS preflight we never allow.
  if (req.get_header_value("Content-Type").rfind("application/json", 0) != 0) {
    error(res, 415, "send the credentials as application/json");
    return;
  }
  if (!same_origin(req)) {
    error(res, 403, "cross-origin request refused");
    return;
  }
  const json body = json::parse(req.body, nullptr, false);
  if (!body.is_object() || !body.contains("name") || !body["name"].is_string() ||
      !body.contains("password") || !body["password"].is_string()) {
    error(res, 400, "expected {\"name\": string, \"password\": string}");
    return;
  }
  const std::string name = body["name"];
  const std::string password = body["password"];
  const LoginOutcome out = auth.login(name, password, req.remote_addr);
  switch (out.kind) {
    case LoginOutcome::Kind::Throttled:
      auth.audit(name, req.remote_addr, "login", name, "throttled");
      res.set_header("Retry-After", std::to_string(out.retry_after_s));
      reply(res, 429,
            {{"error", "too many failed logins: try again later"},
             {"retry_after_s", out.retry_after_s}});
      return;
    case LoginOutcome::Kind::BadCredentials:
      auth.audit(name, req.remote_addr, "login", name, "bad_credentials");
      error(res, 401, "wrong name or password");
      return;
    case LoginOutcome::Kind::Ok:
      break;
  }
  auth.audit(name, req.remote_addr, "login", name, "ok");
  res.set_header(
      "Set-Cookie",
      session_cookie(out.session_id, static_cast<int>(auth.limits().session_lifetime.count())));
  reply(res, 200,
        {{"name", out.session.operator_name},
         {"role", role_name(out.session.role)},
         {"csrf_token", out.session.csrf_token}});
}

void WebServer::Impl::events(const httplib::Request& req, httplib::Response& res) {
  const std::optional<Session> s = authorise(req, res, Role::Viewer, "events");
  if (!s) return;
  if (++streams > o.max_event_streams) {
    --streams;
    error(res, 503, "too many live-update streams on this instance");
    return;
  }
  const std::string session_id = cookie_value(req, kCookie);
  auto seen = std::make_shared<ChangeFeed::Cursor>(feed.current());
  auto first = std::make_shared<bool>(true);
  res.set_header("Cache-Control", "no-store");
  res.set_chunked_content_provider(
      "text/event-stream",
      [this, seen, first, session_id](std::size_t, httplib::DataSink& sink) {
        std::string msg;
        if (*first) {
          *first = false;
          msg = "retry: 3000\n\n";
        } else {
          const ChangeFeed::Cursor now = feed.wait_change(*seen, std::chrono::seconds(15));
          if (feed.stopped()) {
            sink.done();
            return false;
          }
          if (now.fleet != seen->fleet)
            msg += "event: fleet\ndata: " + std::to_string(now.fleet) + "\n\n";
          if (now.alarms != seen->alarms) {
            msg += "event: alarms\ndata: " + std::to_string(now.alarms) + "\n\n";
          }
          if (now.commands != seen->commands)
            msg += "event: commands\ndata: " + std::to_string(now.commands) + "\n\n";
          *seen = now;
          if (msg.empty()) {
            // Heartbeat; and a stream outlives neither its session nor a logout.
            if (!auth.session(session_id)) {
              sink.done();
              return false;
            }
            msg = ": keep-alive\n\n";
          }
        }
        return sink.write(msg.data(), msg.size());
      },
      [this](bool) { --streams; });
}

void WebServer::Impl::routes() {
  httplib::Server& s = *server;
  s.Get("/api/health", [this](const httplib::Request&, httplib::Response& res) {
    try {
      auto c = pool.lease();
      c->exec("SELECT 1", "health");
      reply(res, 200, {{"status", "ok"}});
    } catch (const PgError&) {
      error(res, 503, "database unreachable");
    }
  });
  s.Post("/api/login",
         [this](const httplib::Request& req, httplib::Response& res) { login(req, res); });
  s.Post("/api/logout", [this](const httplib::Request& req, httplib::Response& res) {
    const auto session = authorise(req, res, Role::Viewer, "logout");
    if (!session) return;
    auth.logout(cookie_value(req, kCookie));
    auth.audit(session->operator_name, req.remote_addr, "logout", session->operator_name, "ok");
    res.set_header("Set-Cookie", session_cookie("", 0));
    reply(res, 200, {{"logged_out", true}});
  });
  s.Get("/api/session", [this](const httplib::Request& req, httplib::Response& res) {
    const auto session = authorise(req, res, Role::Viewer, "session");
    if (!session) return;
    reply(res, 200,
          {{"name", session->operator_name},
           {"role", role_name(session->role)},
           {"csrf_token", session->csrf_token}});
  });
  s.Get("/api/config", [this](const httplib::Request& req, httplib::Response& res) {
    if (!authorise(req, res, Role::Viewer, "config")) return;
    reply(res, 200,
          {{"tile_url", o.tile_url},
           {"tile_attribution", o.tile_attribution},
           {"commands", signer ? signer->describe() : json(nullptr)}});
  });
  add_fleet_routes(s, ctx);  // before /api/vehicles/(.+), which would match its paths
  add_campaign_routes(s, ctx);
  s.Get(R"(/api/vehicles/(.+))", [this](const httplib::Request& req, httplib::Response& res) {
    if (!authorise(req, res, Role::Viewer, "vehicle")) return;
    auto c = pool.lease();
    const std::optional<json> v = vehicle(*c, req.matches[1].str());
    if (!v) {
      error(res, 404, "no such vehicle");
      return;
    }
    reply(res, 200, *v);
  });
  s.Get("/api/alarms", [this](const httplib::Request& req, httplib::Response& res) {
    if (!authorise(req, res, Role::Viewer, "alarms")) return;
    int limit = 200;
    if (req.has_param("limit")) {
      try {
        limit = std::stoi(req.get_param_value("limit"));
      } catch (const std::exception&) {
        limit = -1;
      }
      if (limit < 1 || limit > 1000) {
        error(res, 400, "limit must be 1 to 1000");
        return;
      }
    }
    auto c = pool.lease();
    reply(res, 200, {{"alarms", alarms(*c, limit)}});
  });
  s.Post(R"(/api/alarms/([^/]+)/ack)", [this](const httplib::Request& req, httplib::Response& res) {
    const auto session = authorise(req, res, Role::Operator, "alarm_ack");
    if (!session) return;
    const std::string id = req.matches[1].str();
    const std::optional<AlarmKey> key = parse_alarm_id(id);
    if (!key) {
      auth.audit(session->operator_name, req.remote_addr, "alarm_ack", id, "bad_request");
      error(res, 400, "malformed alarm id");
      return;
    }
    AckResult r;
    {
      auto c = pool.lease();
      r = ack_alarm(*c, *key, session->operator_name, now_us());
    }
    const std::string target =
        key->vehicle_id + "/" + key->store_id + "/" + std::to_string(key->sequence);
    switch (r) {
      case AckResult::NoSuchAlarm:
        auth.audit(session->operator_name, req.remote_addr, "alarm_ack", target, "not_found");
        error(res, 404, "no such alarm");
        return;
      case AckResult::AlreadyAcked:
        auth.audit(session->operator_name, req.remote_addr, "alarm_ack", target, "already_acked");
        reply(res, 200, {{"acked", true}, {"already", true}});
        return;
      case AckResult::Acked:
        auth.audit(session->operator_name, req.remote_addr, "alarm_ack", target, "ok");
        reply(res, 200, {{"acked", true}, {"already", false}});
        return;
    }
  });
  // The audit trail, newest first: admins only (it names who did what from where).
  s.Get("/api/audit", [this](const httplib::Request& req, httplib::Response& res) {
    if (!authorise(req, res, Role::Admin, "audit")) return;
    auto c = pool.lease();
    const PgResult r = c->exec(
        "SELECT at_us, operator, address, action, target, result, detail FROM console_audit "
        "ORDER BY id DESC LIMIT 500",
        "audit trail");
    json rows = json::array();
    for (int i = 0; i < r.rows(); ++i) {
      rows.push_back({{"at_us", r.int64_or_null(i, 0).value_or(0)},
                      {"operator", r.is_null(i, 1) ? json(nullptr) : json(r.str(i, 1))},
                      {"address", r.str(i, 2)},
                      {"action", r.str(i, 3)},
                      {"target", r.str(i, 4)},
                      {"result", r.str(i, 5)},
                      {"detail", r.str(i, 6)}});
    }
    reply(res, 200, {{"audit", rows}});
  });
  s.Get("/api/events",
        [this](const httplib::Request& req, httplib::Response& res) { events(req, res); });
  add_command_routes(s, ctx);
  add_admin_routes(s, ctx);
  // GBFS, MDS and the vehicle registry (issue 27).
  mount_standards_routes(s, pool, auth, o.standards, tls,
                         [this](const httplib::Request& req, httplib::Response& res, Role r,
                                std::string_view action) -> std::optional<std::string> {
                           const auto session = authorise(req, res, r, action);
                           if (!session) return std::nullopt;
                           return session->operator_name;
                         });
  // Anything else under /api/ is a JSON 404, not the static file handler's.
  s.Get(R"(/api/.*)", [](const httplib::Request&, httplib::Response& res) {
    error(res, 404, "no such API path");
  });
  s.Post(R"(/.*)", [](const httplib::Request&, httplib::Response& res) {
    error(res, 404, "no such API path");
  });
}

WebServer::WebServer(const ServeOptions& options) : impl_(std::make_unique<Impl>(options)) {
  Impl& m = *impl_;
  const auto [host, port] = split_listen(options.listen);
  if (options.tls_cert.empty() != options.tls_key.empty()) {
    throw std::runtime_error("--tls-cert and --tls-key go together");
  }
  if (!m.tls && !options.insecure_http && !is_loopback_host(host)) {
    throw std::runtime_error(
        "--listen " + options.listen +
        ": plain HTTP only on a loopback address; give --tls-cert/--tls-key, or "
        "--insecure-http when a TLS proxy in front of this server terminates HTTPS");
  }
  if (m.tls) {
    for (const std::string& f : {options.tls_cert, options.tls_key}) {
      if (!std::filesystem::is_regular_file(f))
        throw std::runtime_error("TLS file " + f + ": not found");
    }
    auto ssl =
        std::make_unique<httplib::SSLServer>(options.tls_cert.c_str(), options.tls_key.c_str());
    if (!ssl->is_valid()) {
      throw std::runtime_error("TLS certificate " + options.tls_cert + " or key " +
                               options.tls_key + " cannot be loaded (PEM, matching pair?)");
    }
    m.server = std::move(ssl);
  } else {
    m.server = std::make_unique<httplib::Server>();
  }
  httplib::Server& s = *m.server;
  const int threads = options.threads;
  // cpp-httplib owns the queue it is given and deletes it: this is its interface.
  s.new_task_queue = [threads] {
    return new httplib::ThreadPool(static_cast<std::size_t>(threads));
  };
  s.set_payload_max_length(options.max_body_bytes);
  s.set_read_timeout(5, 0);
  s.set_write_timeout(5, 0);
  s.set_keep_alive_timeout(5);
  s.set_keep_alive_max_count(100);

  std::string img_src = "'self' data:";
  if (const std::string t = tile_origin(options.tile_url); !t.empty()) img_src += " " + t;
  httplib::Headers headers = {
      {"Content-Security-Policy",
       "default-src 'none'; script-src 'self'; style-src 'self'; img-src " + img_src +
           "; connect-src 'self'; font-src 'self'; base-uri 'none'; form-action 'self'; "
           "frame-ancestors 'none'"},
      {"X-Content-Type-Options", "nosniff"},
      {"X-Frame-Options", "DENY"},
      {"Referrer-Policy", "no-referrer"},
      {"Cross-Origin-Opener-Policy", "same-origin"},
      {"Permissions-Policy", "geolocation=(), camera=(), microphone=()"}};
  if (m.tls) headers.emplace("Strict-Transport-Security", "max-age=31536000");
  s.set_default_headers(headers);

  s.set_exception_handler(
      [](const httplib::Request& req, httplib::Response& res, std::exception_ptr ep) {
        try {
          std::rethrow_exception(ep);
        } catch (const PgError& e) {
          spdlog::warn("serve: {} {}: {}", req.method, req.path, e.what());
          error(res, 503, e.sqlstate() == "53300" ? "busy: try again" : "database error");
        } catch (const std::exception& e) {
          spdlog::error("serve: {} {}: {}", req.method, req.path, e.what());
          error(res, 500, "internal error");
        }
      });
  m.routes();

  if (!s.set_mount_point("/vendor/leaflet", options.leaflet_dir)) {
    throw std::runtime_error("Leaflet directory " + options.leaflet_dir +
                             " not found (Debian package libjs-leaflet)");
  }
  if (!s.set_mount_point("/", options.static_dir)) {
    throw std::runtime_error("console directory " + options.static_dir + " not found");
  }

  if (port == 0) {
    m.port = s.bind_to_any_port(host);
  } else {
    m.port = s.bind_to_port(host, port) ? port : -1;
  }
  if (m.port <= 0) throw std::runtime_error("cannot listen on " + options.listen);
}

WebServer::~WebServer() = default;

int WebServer::port() const {
  return impl_->port;
}

void WebServer::run() {
  impl_->server->listen_after_bind();
}

void WebServer::stop() {
  impl_->feed.stop();  // ends the event streams, which hold request threads
  impl_->server->stop();
}

}  // namespace fleetgw::web
