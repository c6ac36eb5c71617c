// Operator accounts from the console's admin page (issue 28): list, add with a role, change the
// role, reset the password, remove. Admin-only (the server enforces it: 403 otherwise),
// CSRF-protected like every POST, audited (`operator_add`, `operator_role`,
// `operator_password`, `operator_remove`). The same rules as `fleetgw serve --add-operator`
// (auth.h): names 1-64 printable ASCII without spaces, passwords 8..1024 bytes, Argon2id; a
// new role or password ends the account's sessions. The fleet never loses its last admin: the
// last one cannot be demoted or removed, from the console or by itself.
#include "backend/web/admin_pages.h"

namespace fleetgw::web {
namespace {

using nlohmann::json;

json operator_list(PgConnection& c) {
  const PgResult r = c.exec(
      "SELECT o.name, o.role, o.created_at_us, o.disabled, "
      "(SELECT count(*) FROM console_sessions s WHERE s.operator = o.name AND "
      "s.expires_at_us > (extract(epoch FROM now()) * 1000000)::bigint), "
      "(SELECT max(s.last_seen_us) FROM console_sessions s WHERE s.operator = o.name) "
      "FROM console_operators o ORDER BY o.name",
      "operators");
  json out = json::array();
  for (int i = 0; i < r.rows(); ++i) {
    out.push_back(
        {{"name", r.str(i, 0)},
         {"role", r.str(i, 1)},
         {"created_at_us", r.int64(i, 2)},
         {"disabled", r.boolean(i, 3)},
         {"sessions", r.int64(i, 4)},
         {"last_seen_us", r.int64_or_null(i, 5) ? json(*r.int64_or_null(i, 5)) : json(nullptr)}});
  }
  return out;
}

std::optional<Role> role_of(PgConnection& c, const std::string& name) {
  const PgParam p[] = {name};
  const PgResult r = c.query("SELECT role FROM console_operators WHERE name = $1", p, "role of");
  if (r.rows() == 0) return std::nullopt;
  return parse_role(r.text(0, 0));
}

std::int64_t admin_count(PgConnection& c) {
  return c
      .exec("SELECT count(*) FROM console_operators WHERE role = 'admin' AND NOT disabled",
            "admins")
      .int64(0, 0);
}

std::optional<std::string> string_field(const json& body, const char* key) {
  if (!body.is_object() || !body.contains(key) || !body[key].is_string()) return std::nullopt;
  return body[key].get<std::string>();
}

}  // namespace

void add_account_routes(httplib::Server& s, RouteContext& ctx) {
  s.Get("/api/operators", [&ctx](const httplib::Request& req, httplib::Response& res) {
    if (!ctx.authorise(req, res, Role::Admin, "operators")) return;
    auto c = ctx.pool.lease();
    send_json(res, 200, {{"operators", operator_list(*c)}});
  });

  // {name, role, password}: a new account (an existing name is 409: reset its password or
  // change its role instead, so a typo cannot silently take over someone's account).
  s.Post("/api/operators", [&ctx](const httplib::Request& req, httplib::Response& res) {
    const auto session = ctx.authorise(req, res, Role::Admin, "operator_add");
    if (!session) return;
    const json body = json::parse(req.body, nullptr, false);
    const auto name = string_field(body, "name");
    const auto role_text = string_field(body, "role");
    const auto password = string_field(body, "password");
    // Assigned, not a conditional copy of an optional: gcc 12 at -O3 warns maybe-uninitialized
    // on the latter (-Werror in the product tree).
    std::optional<Role> role;
    if (role_text) role = parse_role(*role_text);
    auto refuse = [&](int status, const std::string& result, const std::string& why) {
      ctx.auth.audit(session->operator_name, req.remote_addr, "operator_add", name.value_or(""),
                     result, why);
      send_error(res, status, why);
    };
    if (!name || !role || !password) {
      refuse(400, "bad_request",
             "expected {\"name\": string, \"role\": \"viewer\"|\"operator\"|\"admin\", "
             "\"password\": string}");
      return;
    }
    {
      auto c = ctx.pool.lease();
      if (role_of(*c, *name)) {
        refuse(409, "exists", "an operator named '" + *name + "' exists");
        return;
      }
    }
    try {
      ctx.auth.add_operator(*name, *role, *password);
    } catch (const std::invalid_argument& e) {
      refuse(400, "bad_request", e.what());
      return;
    }
    ctx.auth.audit(session->operator_name, req.remote_addr, "operator_add", *name, "ok",
                   std::string(role_name(*role)));
    send_json(res, 201, {{"name", *name}, {"role", role_name(*role)}});
  });

  s.Post(R"(/api/operators/([^/]+)/(role|password|remove))", [&ctx](const httplib::Request& req,
                                                                    httplib::Response& res) {
    const std::string what = req.matches[2].str();
    const std::string action = "operator_" + what;
    const auto session = ctx.authorise(req, res, Role::Admin, action);
    if (!session) return;
    const std::string name = req.matches[1].str();
    const json body = json::parse(req.body.empty() ? "{}" : req.body, nullptr, false);
    auto refuse = [&](int status, const std::string& result, const std::string& why) {
      ctx.auth.audit(session->operator_name, req.remote_addr, action, name, result, why);
      send_error(res, status, why);
    };
    std::optional<Role> current;
    std::int64_t admins = 0;
    {
      auto c = ctx.pool.lease();
      current = role_of(*c, name);
      admins = admin_count(*c);
    }
    if (!current) {
      refuse(404, "not_found", "no operator named '" + name + "'");
      return;
    }
    if (what == "remove") {
      if (*current == Role::Admin && admins <= 1) {
        refuse(409, "last_admin", "'" + name + "' is the last admin: add another admin first");
        return;
      }
      ctx.auth.remove_operator(name);
      ctx.auth.audit(session->operator_name, req.remote_addr, action, name, "ok");
      send_json(res, 200, {{"removed", name}});
      return;
    }
    if (what == "role") {
      const auto text = string_field(body, "role");
      std::optional<Role> role;
      if (text) role = parse_role(*text);
      if (!role) {
        refuse(400, "bad_request", "expected {\"role\": \"viewer\"|\"operator\"|\"admin\"}");
        return;
      }
      if (*current == Role::Admin && *role != Role::Admin && admins <= 1) {
        refuse(409, "last_admin", "'" + name + "' is the last admin: add another admin first");
        return;
      }
      {
        auto c = ctx.pool.lease();
        PgTransaction tx(*c);
        const PgParam p[] = {name, std::string(role_name(*role))};
        c->query("UPDATE console_operators SET role = $2 WHERE name = $1", p, "set role");
        // Sessions opened under the old role end (as with --add-operator).
        c->query("DELETE FROM console_sessions WHERE operator = $1", std::span(p, 1),
                 "end operator sessions");
        tx.commit();
      }
      ctx.auth.audit(session->operator_name, req.remote_addr, action, name, "ok",
                     std::string(role_name(*current)) + " -> " + std::string(role_name(*role)));
      send_json(res, 200, {{"name", name}, {"role", role_name(*role)}});
      return;
    }
    const auto password = string_field(body, "password");
    if (!password) {
      refuse(400, "bad_request", "expected {\"password\": string}");
      return;
    }
    try {
      ctx.auth.add_operator(name, *current, *password);  // same role; ends its sessions
    } catch (const std::invalid_argument& e) {
      refuse(400, "bad_request", e.what());
      return;
    }
    ctx.auth.audit(session->operator_name, req.remote_addr, action, name, "ok");
    send_json(res, 200, {{"name", name}, {"password_reset", true}});
  });
}

}  // namespace fleetgw::web
