// The HTTP(S) server of `fleetgw serve`: the operator API under /api/, the console's static
// files at /, Leaflet at /vendor/leaflet/. Stateless: everything an instance knows is in
// PostgreSQL, so several run behind a load balancer.
//
// Contract:
//  * WebServer binds in its constructor (throws std::runtime_error naming the address, or the
//    TLS file that cannot be loaded) and serves on run() until stop() (any thread).
//  * Every response carries the security headers (CSP without inline scripts or styles,
//    frame-ancestors 'none', nosniff, no referrer; HSTS under TLS); API responses are JSON and
//    never cached.
//  * Limits: request bodies above max_body_bytes are refused (413); a connection is read and
//    written with 5 s timeouts and closed after 5 s idle or 100 requests; headers and URI are
//    limited to 8 KiB each (cpp-httplib); at most max_event_streams /api/events streams (503).
//  * Authentication and authorisation as in auth.h: no session 401, role too low 403, and every
//    state-changing request (POST) needs the session's CSRF token in X-CSRF-Token (403
//    otherwise) and, when the browser sends Origin, the server's own origin. Every
//    state-changing request is audited, refused ones included.
#pragma once

#include <memory>

#include "backend/web/serve_options.h"

namespace fleetgw::web {

class WebServer {
 public:
  explicit WebServer(const ServeOptions& options);
  ~WebServer();
  WebServer(const WebServer&) = delete;
  WebServer& operator=(const WebServer&) = delete;

  int port() const;
  void run();
  void stop();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Whether HOST (of --listen) is a loopback address, where plain HTTP is allowed by default.
bool is_loopback_host(std::string_view host);

}  // namespace fleetgw::web
