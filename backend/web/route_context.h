// What the route files of `fleetgw serve` share with the server (http_server.cc): the pool, the
// authentication, the live-update feed, the command signer and broker link (null when commands
// are off), and the one authorise() that enforces sessions or API tokens, roles, CSRF and
// origin (http_server.h says how). JSON replies go through send_json()/send_error().
#pragma once

#include <httplib.h>

#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <string_view>

#include "backend/common/pg.h"
#include "backend/web/auth.h"
#include "backend/web/change_feed.h"
#include "backend/web/command_hub.h"
#include "backend/web/command_signer.h"
#include "backend/web/fleet_api.h"
#include "backend/web/serve_options.h"

namespace fleetgw::web {

struct RouteContext {
  const ServeOptions& options;
  PgPool& pool;
  Auth& auth;
  ChangeFeed& feed;
  const CommandSigner* signer = nullptr;
  CommandHub* hub = nullptr;
  std::function<std::optional<Session>(const httplib::Request&, httplib::Response&, Role,
                                       std::string_view)>
      authorise;
};

inline void send_json(httplib::Response& res, int status, const nlohmann::json& body) {
  res.status = status;
  res.set_header("Cache-Control", "no-store");
  res.set_content(to_json_text(body), "application/json; charset=utf-8");
}

inline void send_error(httplib::Response& res, int status, std::string_view message) {
  send_json(res, status, {{"error", message}});
}

// POST /api/vehicles/{id}/commands, POST /api/commands (several vehicles), GET /api/commands.
void add_command_routes(httplib::Server& s, RouteContext& ctx);
// Alarm resolve, API tokens.
void add_admin_routes(httplib::Server& s, RouteContext& ctx);
// GET /api/fleet (cached, ETag, compact view) and GET /api/rides (fleet_routes.cc).
void add_fleet_routes(httplib::Server& s, RouteContext& ctx);
// GET /api/campaigns... (campaign_routes.cc): the campaign page.
void add_campaign_routes(httplib::Server& s, RouteContext& ctx);

}  // namespace fleetgw::web
