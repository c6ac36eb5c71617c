// The fleet list, built once and served many times (issue 28: the list was rebuilt per request,
// ~0.5 s of server CPU and as much of PostgreSQL for 10,000 vehicles).
//
// Contract:
//  * get(view) returns the list's JSON text as built by fleet() (View::Full) or fleet_compact()
//    (View::Compact), with its ETag and a gzip copy. A built list is served again while the
//    change feed's `fleet` counter is the one read before its query AND it is younger than
//    `ttl`; so a list is at most max(ttl, one --poll-ms plus the query) behind the database
//    (telemetry speeds and lock events move no counter: the TTL bounds them).
//  * One build at a time per view: requests arriving during a build wait for it and share its
//    result instead of each querying (a burst of consoles after a change costs one query).
//  * invalidate() forgets the built lists (a write through this instance).
//  * A failed build (database error) throws to the caller; the previous list is kept but not
//    served past its TTL.
//  * ETag: "<view>-<64-bit FNV-1a of the text in hex>", the same on every instance for the same
//    list, so a client's If-None-Match works behind a load balancer. Thread-safe.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>

#include "backend/common/pg.h"
#include "backend/web/change_feed.h"

namespace fleetgw::web {

struct FleetSnapshot {
  std::string json;  // the response body
  std::string gzip;  // the same, gzip-compressed (empty if compression failed)
  std::string etag;  // quoted, as sent in the ETag header
  std::uint64_t cursor = 0;
  std::chrono::steady_clock::time_point built;
};

class FleetCache {
 public:
  enum class View { Full, Compact };
  FleetCache(PgPool& pool, ChangeFeed& feed, std::chrono::milliseconds ttl);

  std::shared_ptr<const FleetSnapshot> get(View view);
  // Drops the built lists: the next get() queries. Called after every state-changing request
  // this instance answered (an acknowledgement or a resolution changes the alarm counts), so an
  // operator reads their own write at once; other instances see it through the feed.
  void invalidate();

 private:
  struct Slot {
    std::mutex build;  // held during a build: the others wait and reuse its result
    std::shared_ptr<const FleetSnapshot> snapshot;
  };
  std::shared_ptr<const FleetSnapshot> fresh(Slot& slot, std::uint64_t cursor);

  PgPool& pool_;
  ChangeFeed& feed_;
  std::chrono::milliseconds ttl_;
  std::mutex mu_;  // guards both slots' snapshot pointers
  Slot full_;
  Slot compact_;
};

// gzip (RFC 1952) of `text`, for a Content-Encoding: gzip body; empty on failure.
std::string gzip_text(std::string_view text);
// Whether an Accept-Encoding header value accepts gzip (a "gzip;q=0" refuses it).
bool accepts_gzip(std::string_view accept_encoding);
// Whether an If-None-Match header value names `etag` (or is "*").
bool etag_matches(std::string_view if_none_match, std::string_view etag);

}  // namespace fleetgw::web
