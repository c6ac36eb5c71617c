// The admin pages' routes of `fleetgw serve` (issue 28), registered by add_admin_routes():
// revocation lists (revocation_routes.cc), zone bundles (zone_routes.cc), operator accounts
// (account_routes.cc). All admin-only, CSRF-protected and audited (route_context.h).
#pragma once

#include <httplib.h>

#include <map>
#include <string>
#include <vector>

#include "backend/web/route_context.h"

namespace fleetgw::web {

// Root key id -> raw 32-byte Ed25519 public key, from --root-key ID=BASE64|ID=FILE.pub;
// std::runtime_error names the option and what is wrong.
using RootKeys = std::map<std::string, std::string>;
RootKeys parse_root_keys(const std::vector<std::string>& specs);

// GET/POST /api/revocations, POST /api/revocations/republish.
void add_revocation_routes(httplib::Server& s, RouteContext& ctx);
// GET /api/zones, POST /api/zones/preview, POST /api/zones/publish.
void add_zone_routes(httplib::Server& s, RouteContext& ctx);
// GET/POST /api/operators, POST /api/operators/{name}/{role,password,remove}.
void add_account_routes(httplib::Server& s, RouteContext& ctx);

}  // namespace fleetgw::web
