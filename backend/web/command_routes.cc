// Commands from the console (issue 28): signed by this server under its delegation for the
// authenticated operator, published to the vehicle, audited, their results stored and pushed
// live (route_context.h, command_signer.h, command_hub.h).
#include <spdlog/spdlog.h>

#include <set>

#include "backend/web/route_context.h"
#include "backend/web/secrets.h"

namespace fleetgw::web {
namespace {

using nlohmann::json;

constexpr std::size_t kMaxBulkVehicles = 500;
// A command without a result this long after it expired will get none that counts (the bike
// refuses it as expired): the console then says so.
constexpr std::int64_t kNoAnswerGraceUs = 5'000'000;

struct IssueOutcome {
  int status = 202;
  std::string error;
  std::string command_id;
};

// A vehicle id becomes an MQTT topic level: wildcards, separators and NUL would address
// other topics (or none).
bool topic_safe(std::string_view v) {
  if (v.empty() || v.size() > 128) return false;
  for (const char ch : v) {
    if (ch == '/' || ch == '+' || ch == '#' || ch == '\0') return false;
  }
  return true;
}

bool known_vehicle(PgConnection& c, const std::string& v) {
  const PgParam p[] = {v};
  return c.query(
              "SELECT 1 FROM vehicle_state WHERE vehicle_id = $1 UNION ALL "
              "SELECT 1 FROM status WHERE vehicle_id = $1 LIMIT 1",
              p, "known vehicle")
             .rows() > 0;
}

IssueOutcome issue(RouteContext& ctx, const Session& s, const std::string& address,
                   const std::string& vehicle, const CommandRequest& r,
                   const std::string& batch_id) {
  const std::string target = vehicle;
  if (!topic_safe(vehicle)) {
    ctx.auth.audit(s.operator_name, address, "command", target, "bad_request", r.summary());
    return {400, "vehicle id unusable as a topic level (empty, too long, or / + # NUL)", ""};
  }
  {
    auto c = ctx.pool.lease();
    if (!known_vehicle(*c, vehicle)) {
      ctx.auth.audit(s.operator_name, address, "command", target, "not_found", r.summary());
      return {404, "no such vehicle", ""};
    }
  }
  const std::int64_t now = now_us();
  if (const auto why = ctx.signer->out_of_scope(r, vehicle, now)) {
    ctx.auth.audit(s.operator_name, address, "command", target, "out_of_scope",
                   r.summary() + ": " + *why);
    return {403, "outside this server's delegation: " + *why, ""};
  }
  const SignedCommandBytes cmd = ctx.signer->sign(r, vehicle, s.operator_name, now,
                                                  std::chrono::seconds(ctx.options.command_ttl_s));
  try {
    ctx.hub->send(r, vehicle, ctx.signer->key_id(), ctx.signer->delegation_serial(), cmd,
                  {s.operator_name, address, batch_id});
  } catch (const std::runtime_error& e) {
    ctx.auth.audit(s.operator_name, address, "command", target + "/" + cmd.command_id,
                   "not_published", r.summary() + ": " + e.what());
    return {502, e.what(), cmd.command_id};
  }
  ctx.feed.notify_commands();
  ctx.auth.audit(s.operator_name, address, "command", target + "/" + cmd.command_id, "published",
                 r.summary());
  return {202, "", cmd.command_id};
}

constexpr std::string_view kCommandColumns =
    "command_id, vehicle_id, operator, action, params, key_id, delegation_serial, issued_at_us, "
    "expires_at_us, batch_id, result, reason, result_operator, duration_ms, final_state, "
    "limit_in_force, result_at_us";

json command_json(const PgResult& r, int i, std::int64_t now) {
  auto opt_i = [&](int col) {
    const auto v = r.int64_or_null(i, col);
    return v ? json(*v) : json(nullptr);
  };
  auto opt_s = [&](int col) { return r.is_null(i, col) ? json(nullptr) : json(r.str(i, col)); };
  json result = opt_s(10);
  // No answer and past its expiry: the bike will refuse it if it ever arrives.
  if (result.is_null() && r.int64_or_null(i, 8).value_or(0) + kNoAnswerGraceUs < now) {
    result = "no_answer";
  }
  return {{"command_id", r.str(i, 0)},     {"vehicle_id", r.str(i, 1)}, {"operator", r.str(i, 2)},
          {"action", r.str(i, 3)},         {"params", r.str(i, 4)},     {"key_id", r.str(i, 5)},
          {"delegation_serial", opt_i(6)}, {"issued_at_us", opt_i(7)},  {"expires_at_us", opt_i(8)},
          {"batch_id", opt_s(9)},          {"result", result},          {"reason", opt_s(11)},
          {"result_operator", opt_s(12)},  {"duration_ms", opt_i(13)},  {"final_state", opt_s(14)},
          {"limit_in_force", opt_s(15)},   {"result_at_us", opt_i(16)}};
}

// Commands off: said once, the same way, wherever a command is asked for.
bool commands_available(RouteContext& ctx, const Session& s, const httplib::Request& req,
                        httplib::Response& res) {
  if (ctx.signer != nullptr && ctx.hub != nullptr) return true;
  ctx.auth.audit(s.operator_name, req.remote_addr, "command", req.path, "commands_off");
  send_error(res, 503,
             "commands are off: this fleetgw serve runs without --broker and --signing-key");
  return false;
}

std::optional<json> body_json(const httplib::Request& req) {
  json body = json::parse(req.body, nullptr, false);
  if (body.is_discarded() || !body.is_object()) return std::nullopt;
  return body;
}

}  // namespace

void add_command_routes(httplib::Server& s, RouteContext& ctx) {
  s.Post(R"(/api/vehicles/(.+)/commands)", [&ctx](const httplib::Request& req,
                                                  httplib::Response& res) {
    const auto session = ctx.authorise(req, res, Role::Operator, "command");
    if (!session || !commands_available(ctx, *session, req, res)) return;
    const std::string vehicle = req.matches[1].str();
    const auto body = body_json(req);
    auto parsed = body ? parse_command_request(*body)
                       : std::variant<CommandRequest, std::string>(std::string("expected JSON"));
    if (const auto* e = std::get_if<std::string>(&parsed)) {
      ctx.auth.audit(session->operator_name, req.remote_addr, "command", vehicle, "bad_request",
                     *e);
      send_error(res, 400, *e);
      return;
    }
    const CommandRequest& r = std::get<CommandRequest>(parsed);
    const IssueOutcome out = issue(ctx, *session, req.remote_addr, vehicle, r, "");
    if (out.status != 202) {
      send_json(res, out.status, {{"error", out.error}, {"command_id", out.command_id}});
      return;
    }
    send_json(res, 202,
              {{"command_id", out.command_id},
               {"vehicle_id", vehicle},
               {"action", r.action},
               {"result", nullptr}});
  });

  // Several vehicles at once: one signed command each, one batch id, one answer per vehicle.
  s.Post("/api/commands", [&ctx](const httplib::Request& req, httplib::Response& res) {
    const auto session = ctx.authorise(req, res, Role::Operator, "command");
    if (!session || !commands_available(ctx, *session, req, res)) return;
    const auto body = body_json(req);
    std::string error;
    std::vector<std::string> vehicles;
    if (!body || !body->contains("vehicles") || !(*body)["vehicles"].is_array() ||
        (*body)["vehicles"].empty() || (*body)["vehicles"].size() > kMaxBulkVehicles) {
      error = "expected {\"vehicles\": [1.." + std::to_string(kMaxBulkVehicles) +
              " ids], \"action\": ...}";
    } else {
      std::set<std::string> seen;
      for (const json& v : (*body)["vehicles"]) {
        if (!v.is_string()) {
          error = "vehicles: strings only";
          break;
        }
        if (seen.insert(v.get<std::string>()).second) vehicles.push_back(v.get<std::string>());
      }
    }
    auto parsed = error.empty() ? parse_command_request(*body)
                                : std::variant<CommandRequest, std::string>(error);
    if (const auto* e = std::get_if<std::string>(&parsed)) {
      ctx.auth.audit(session->operator_name, req.remote_addr, "command", "bulk", "bad_request", *e);
      send_error(res, 400, *e);
      return;
    }
    const CommandRequest& r = std::get<CommandRequest>(parsed);
    const std::string batch = "b-" + random_token(9);
    json results = json::array();
    int published = 0;
    for (const std::string& v : vehicles) {
      const IssueOutcome out = issue(ctx, *session, req.remote_addr, v, r, batch);
      json one = {{"vehicle_id", v}, {"status", out.status}};
      if (!out.command_id.empty()) one["command_id"] = out.command_id;
      if (!out.error.empty()) one["error"] = out.error;
      if (out.status == 202) ++published;
      results.push_back(std::move(one));
    }
    send_json(res, 200, {{"batch_id", batch}, {"published", published}, {"commands", results}});
  });

  // GET /api/commands?vehicle=V&limit=N, or ?ids=a,b,c (the console's pending commands).
  s.Get("/api/commands", [&ctx](const httplib::Request& req, httplib::Response& res) {
    if (!ctx.authorise(req, res, Role::Viewer, "commands")) return;
    int limit = 50;
    if (req.has_param("limit")) {
      try {
        limit = std::stoi(req.get_param_value("limit"));
      } catch (const std::exception&) {
        limit = -1;
      }
      if (limit < 1 || limit > 500) {
        send_error(res, 400, "limit must be 1 to 500");
        return;
      }
    }
    std::string sql = "SELECT " + std::string(kCommandColumns) + " FROM console_commands ";
    std::vector<PgParam> p;
    if (req.has_param("ids")) {
      sql += "WHERE command_id = ANY (string_to_array($1, ',')) ";
      p.emplace_back(req.get_param_value("ids"));
    } else if (req.has_param("vehicle")) {
      sql += "WHERE vehicle_id = $1 ";
      p.emplace_back(req.get_param_value("vehicle"));
    } else if (req.has_param("batch")) {
      sql += "WHERE batch_id = $1 ";
      p.emplace_back(req.get_param_value("batch"));
    }
    sql += "ORDER BY issued_at_us DESC LIMIT " + std::to_string(limit);
    auto c = ctx.pool.lease();
    const PgResult r = c->query(sql, p, "commands");
    const std::int64_t now = now_us();
    json out = json::array();
    for (int i = 0; i < r.rows(); ++i) out.push_back(command_json(r, i, now));
    send_json(res, 200, {{"commands", out}});
  });
}

}  // namespace fleetgw::web
