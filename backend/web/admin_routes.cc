// Alarm resolution, API tokens and the admin pages (issue 28; route_context.h, api_tokens.h,
// admin_pages.h).
#include "backend/web/admin_pages.h"
#include "backend/web/api_tokens.h"
#include "backend/web/route_context.h"

namespace fleetgw::web {
namespace {

using nlohmann::json;

enum class ResolveResult { Resolved, AlreadyResolved, NoSuchAlarm };

ResolveResult resolve_alarm(PgConnection& c, const AlarmKey& key, std::string_view by,
                            std::string_view note) {
  const PgParam k[] = {key.vehicle_id, key.store_id, std::to_string(key.sequence)};
  if (c.query("SELECT 1 FROM alarms WHERE vehicle_id = $1 AND store_id = $2 AND sequence = $3", k,
              "find alarm to resolve")
          .rows() == 0) {
    return ResolveResult::NoSuchAlarm;
  }
  const PgParam p[] = {
      key.vehicle_id,           key.store_id,     std::to_string(key.sequence), std::string(by),
      std::to_string(now_us()), std::string(note)};
  const PgResult r = c.query(
      "INSERT INTO console_alarm_resolutions (vehicle_id, store_id, sequence, resolved_by, "
      "resolved_at_us, note) VALUES ($1, $2, $3, $4, $5::bigint, $6) ON CONFLICT DO NOTHING",
      p, "resolve alarm");
  return r.affected() == 1 ? ResolveResult::Resolved : ResolveResult::AlreadyResolved;
}

}  // namespace

void add_admin_routes(httplib::Server& s, RouteContext& ctx) {
  // The admin pages (admin_pages.h): revocation lists, zones, operator accounts.
  add_revocation_routes(s, ctx);
  add_zone_routes(s, ctx);
  add_account_routes(s, ctx);
  // Resolve: the incident is over (the bike found, the false alarm explained). The alarm stops
  // counting as active on the map; who and when are kept, with an optional note.
  s.Post(R"(/api/alarms/([^/]+)/resolve)", [&ctx](const httplib::Request& req,
                                                  httplib::Response& res) {
    const auto session = ctx.authorise(req, res, Role::Operator, "alarm_resolve");
    if (!session) return;
    const std::string id = req.matches[1].str();
    const std::optional<AlarmKey> key = parse_alarm_id(id);
    const json body = json::parse(req.body.empty() ? "{}" : req.body, nullptr, false);
    std::string note;
    if (body.is_object() && body.contains("note") && body["note"].is_string()) {
      note = body["note"].get<std::string>().substr(0, 500);
    }
    if (!key || !body.is_object()) {
      ctx.auth.audit(session->operator_name, req.remote_addr, "alarm_resolve", id, "bad_request");
      send_error(res, 400, "malformed alarm id or body");
      return;
    }
    ResolveResult r;
    {
      auto c = ctx.pool.lease();
      r = resolve_alarm(*c, *key, session->operator_name, note);
    }
    const std::string target =
        key->vehicle_id + "/" + key->store_id + "/" + std::to_string(key->sequence);
    switch (r) {
      case ResolveResult::NoSuchAlarm:
        ctx.auth.audit(session->operator_name, req.remote_addr, "alarm_resolve", target,
                       "not_found");
        send_error(res, 404, "no such alarm");
        return;
      case ResolveResult::AlreadyResolved:
        ctx.auth.audit(session->operator_name, req.remote_addr, "alarm_resolve", target,
                       "already_resolved");
        send_json(res, 200, {{"resolved", true}, {"already", true}});
        return;
      case ResolveResult::Resolved:
        ctx.auth.audit(session->operator_name, req.remote_addr, "alarm_resolve", target, "ok",
                       note);
        send_json(res, 200, {{"resolved", true}, {"already", false}});
        return;
    }
  });

  s.Get("/api/tokens", [&ctx](const httplib::Request& req, httplib::Response& res) {
    if (!ctx.authorise(req, res, Role::Admin, "tokens")) return;
    auto c = ctx.pool.lease();
    send_json(res, 200, {{"tokens", list_api_tokens(*c)}});
  });
  // The token is in this answer and nowhere else (only its SHA-256 is stored).
  s.Post("/api/tokens", [&ctx](const httplib::Request& req, httplib::Response& res) {
    const auto session = ctx.authorise(req, res, Role::Admin, "token_create");
    if (!session) return;
    const json body = json::parse(req.body, nullptr, false);
    std::optional<Role> role;
    if (body.is_object() && body.contains("role") && body["role"].is_string()) {
      role = parse_role(body["role"].get<std::string>());
    }
    if (!role || !body.contains("name") || !body["name"].is_string()) {
      ctx.auth.audit(session->operator_name, req.remote_addr, "token_create", "", "bad_request");
      send_error(res, 400,
                 "expected {\"name\": string, \"role\": \"viewer\"|\"operator\"|\"admin\"}");
      return;
    }
    const std::string name = body["name"].get<std::string>();
    try {
      auto c = ctx.pool.lease();
      const CreatedToken t = create_api_token(*c, name, *role, session->operator_name);
      ctx.auth.audit(session->operator_name, req.remote_addr, "token_create",
                     name + "#" + std::to_string(t.id), "ok", std::string(role_name(*role)));
      send_json(res, 201,
                {{"id", t.id}, {"name", name}, {"role", role_name(*role)}, {"token", t.token}});
    } catch (const std::invalid_argument& e) {
      ctx.auth.audit(session->operator_name, req.remote_addr, "token_create", name, "bad_request",
                     e.what());
      send_error(res, 400, e.what());
    }
  });
  s.Post(R"(/api/tokens/(\d{1,18})/revoke)",
         [&ctx](const httplib::Request& req, httplib::Response& res) {
           const auto session = ctx.authorise(req, res, Role::Admin, "token_revoke");
           if (!session) return;
           const std::string id = req.matches[1].str();
           bool revoked = false;
           {
             auto c = ctx.pool.lease();
             revoked = revoke_api_token(*c, std::stoll(id), session->operator_name);
           }
           ctx.auth.audit(session->operator_name, req.remote_addr, "token_revoke", id,
                          revoked ? "ok" : "not_found");
           if (!revoked) {
             send_error(res, 404, "no such token, or already revoked");
             return;
           }
           send_json(res, 200, {{"revoked", true}});
         });
}

}  // namespace fleetgw::web
