// The routes of issue 27 on `fleetgw serve`: the public GBFS v3.0 feeds under /gbfs/, the MDS
// 2.0 Provider API under /mds/, and the registry's admin API under /api/registry/.
//
// Contract:
//  * GBFS: GET /gbfs/gbfs.json, system_information.json, vehicle_types.json,
//    vehicle_status.json, geofencing_zones.json; no authentication; application/json;
//    `Access-Control-Allow-Origin: *`; a weak ETag over the feed's data (If-None-Match: 304
//    without a body); Cache-Control public with max-age = the feed's ttl. Each feed is built at
//    most once per second per instance (vehicle_status) or once per 10 s (the others): any
//    request rate costs the database at most that.
//  * MDS: bearer token of an agency (registry_store.h) or 401 (WWW-Authenticate: Bearer);
//    Accept must allow application/vnd.mds+json;version=2.0 (a missing Accept, */*,
//    application/json or application/vnd.mds+json without a version do) or 406; responses are
//    `application/vnd.mds+json;version=2.0` with "version": "2.0.0" and links.next (null on
//    the last page; `offset` in the query). Hour parameters are YYYY-MM-DDTHH (UTC): 400 when
//    missing or malformed, 404 for an hour that has not ended. events/recent takes start_time
//    and end_time (ms), end after start, at most 2 weeks ago, not in the future (400).
//  * /api/registry/: admin role; POSTs need the session's CSRF token (as every console POST)
//    and are audited; bad input 400 naming the field.
#pragma once

#include <httplib.h>

#include <functional>
#include <optional>
#include <string>
#include <string_view>

#include "backend/common/pg.h"
#include "backend/web/auth.h"
#include "backend/web/registry_options.h"

namespace fleetgw::web {

// The server's own check of a request (http_server.cc): the operator's name, or nullopt once a
// refusal has been written to the response.
using AuthoriseFn = std::function<std::optional<std::string>(
    const httplib::Request&, httplib::Response&, Role, std::string_view action)>;

// Registers the routes (before any catch-all); the feeds' cache lives in the handlers.
void mount_standards_routes(httplib::Server& server, PgPool& pool, Auth& auth,
                            const StandardsOptions& options, bool tls, AuthoriseFn authorise);

}  // namespace fleetgw::web
