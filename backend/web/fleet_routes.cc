// GET /api/fleet (the cached fleet list, fleet_cache.h) and GET /api/rides (one ride's track and
// plot, ride_api.h): the console's map, list and vehicle page.
#include <memory>

#include "backend/web/fleet_cache.h"
#include "backend/web/ride_api.h"
#include "backend/web/route_context.h"

namespace fleetgw::web {
namespace {

// How long a built fleet list is served while the change feed says nothing changed: bounds
// how stale the telemetry speeds and lock states in it can be (no change counter moves for
// them). Two seconds of staleness against 0.5 s of server CPU per rebuild at 10,000 vehicles.
constexpr std::chrono::milliseconds kFleetListTtl{2000};

void send_fleet(const httplib::Request& req, httplib::Response& res, const FleetSnapshot& snap) {
  // Not stored by the browser (no-store, as every API answer: it names the fleet), but a client
  // that kept the ETag itself (the console does) revalidates with If-None-Match and gets 304.
  res.set_header("Cache-Control", "no-store");
  res.set_header("ETag", snap.etag);
  res.set_header("Vary", "Accept-Encoding");
  if (etag_matches(req.get_header_value("If-None-Match"), snap.etag)) {
    res.status = 304;
    return;
  }
  res.status = 200;
  if (!snap.gzip.empty() && accepts_gzip(req.get_header_value("Accept-Encoding"))) {
    res.set_header("Content-Encoding", "gzip");
    res.set_content(snap.gzip, "application/json; charset=utf-8");
    return;
  }
  res.set_content(snap.json, "application/json; charset=utf-8");
}

}  // namespace

void add_fleet_routes(httplib::Server& s, RouteContext& ctx) {
  auto cache = std::make_shared<FleetCache>(ctx.pool, ctx.feed, kFleetListTtl);
  // Read-your-writes on this instance: any state-changing request it answered with success
  // (acknowledge, resolve, a command...) drops the cached list. httplib has one such hook; it is
  // this file's.
  s.set_post_routing_handler([cache](const httplib::Request& req, httplib::Response& res) {
    if (req.method != "GET" && req.method != "HEAD" && res.status >= 200 && res.status < 300) {
      cache->invalidate();
    }
  });
  s.Get("/api/fleet", [&ctx, cache](const httplib::Request& req, httplib::Response& res) {
    if (!ctx.authorise(req, res, Role::Viewer, "fleet")) return;
    const std::string view = req.has_param("view") ? req.get_param_value("view") : "full";
    if (view != "full" && view != "compact") {
      send_error(res, 400, "view must be full or compact");
      return;
    }
    send_fleet(req, res,
               *cache->get(view == "compact" ? FleetCache::View::Compact : FleetCache::View::Full));
  });
  // Query parameters, not path segments: vehicle and ride ids are the bikes' own strings and
  // may hold '/' (the path is decoded before it is matched).
  s.Get("/api/rides", [&ctx](const httplib::Request& req, httplib::Response& res) {
    if (!ctx.authorise(req, res, Role::Viewer, "ride")) return;
    if (!req.has_param("vehicle") || !req.has_param("ride")) {
      send_error(res, 400, "expected ?vehicle=ID&ride=RIDE_ID");
      return;
    }
    auto c = ctx.pool.lease();
    const auto ride = ride_detail(*c, req.get_param_value("vehicle"), req.get_param_value("ride"));
    if (!ride) {
      send_error(res, 404, "no such ride");
      return;
    }
    send_json(res, 200, *ride);
  });
}

}  // namespace fleetgw::web
