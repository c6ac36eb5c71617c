// The cached fleet list (fleet_cache.h).
#include "backend/web/fleet_cache.h"

#include <zlib.h>

#include <array>
#include <cstdio>

#include "backend/web/fleet_api.h"

namespace fleetgw::web {
namespace {

std::uint64_t fnv1a64(std::string_view s) {
  std::uint64_t h = 14695981039346656037ULL;
  for (const char ch : s) {
    h ^= static_cast<unsigned char>(ch);
    h *= 1099511628211ULL;
  }
  return h;
}

std::string_view trim_spaces(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

}  // namespace

std::string gzip_text(std::string_view text) {
  z_stream z{};
  // windowBits 15 + 16: a gzip header and trailer instead of zlib's.
  if (deflateInit2(&z, Z_DEFAULT_COMPRESSION, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY) != Z_OK) {
    return "";
  }
  std::string out(deflateBound(&z, static_cast<uLong>(text.size())) + 32, '\0');
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(text.data()));
  z.avail_in = static_cast<uInt>(text.size());
  z.next_out = reinterpret_cast<Bytef*>(out.data());
  z.avail_out = static_cast<uInt>(out.size());
  const int rc = deflate(&z, Z_FINISH);
  const std::size_t n = z.total_out;
  deflateEnd(&z);
  if (rc != Z_STREAM_END) return "";
  out.resize(n);
  return out;
}

bool accepts_gzip(std::string_view header) {
  while (!header.empty()) {
    const std::size_t comma = header.find(',');
    std::string_view item = trim_spaces(header.substr(0, comma));
    header = comma == std::string_view::npos ? std::string_view() : header.substr(comma + 1);
    const std::size_t semi = item.find(';');
    const std::string_view coding = trim_spaces(item.substr(0, semi));
    if (coding != "gzip" && coding != "*") continue;
    if (semi == std::string_view::npos) return true;
    const std::string_view param = trim_spaces(item.substr(semi + 1));
    // q=0, q=0.0, q=0.00...: refused; any other weight accepts.
    if (!param.starts_with("q=")) return true;
    return param.substr(2).find_first_not_of("0.") != std::string_view::npos;
  }
  return false;
}

bool etag_matches(std::string_view header, std::string_view etag) {
  while (!header.empty()) {
    const std::size_t comma = header.find(',');
    std::string_view item = trim_spaces(header.substr(0, comma));
    header = comma == std::string_view::npos ? std::string_view() : header.substr(comma + 1);
    if (item.starts_with("W/")) item.remove_prefix(2);  // weak comparison (RFC 9110 13.1.2)
    if (item == "*" || item == etag) return true;
  }
  return false;
}

FleetCache::FleetCache(PgPool& pool, ChangeFeed& feed, std::chrono::milliseconds ttl)
    : pool_(pool), feed_(feed), ttl_(ttl) {}

std::shared_ptr<const FleetSnapshot> FleetCache::fresh(Slot& slot, std::uint64_t cursor) {
  const std::lock_guard lock(mu_);
  if (slot.snapshot && slot.snapshot->cursor == cursor &&
      std::chrono::steady_clock::now() - slot.snapshot->built < ttl_) {
    return slot.snapshot;
  }
  return nullptr;
}

void FleetCache::invalidate() {
  const std::lock_guard lock(mu_);
  full_.snapshot.reset();
  compact_.snapshot.reset();
}

std::shared_ptr<const FleetSnapshot> FleetCache::get(View view) {
  Slot& slot = view == View::Full ? full_ : compact_;
  // Read before the query: a change during the query moves the counter, and the next request
  // builds again rather than serving a list older than the change.
  const std::uint64_t cursor = feed_.current().fleet;
  if (auto s = fresh(slot, cursor)) return s;
  const std::lock_guard build(slot.build);
  if (auto s = fresh(slot, feed_.current().fleet)) return s;  // built while we waited
  auto snap = std::make_shared<FleetSnapshot>();
  snap->cursor = feed_.current().fleet;
  {
    auto c = pool_.lease();
    snap->json = view == View::Full ? to_json_text({{"vehicles", fleet(*c)}})
                                    : to_json_text(fleet_compact(*c));
  }
  snap->gzip = gzip_text(snap->json);
  std::array<char, 17> hex{};
  std::snprintf(hex.data(), hex.size(), "%016llx",
                static_cast<unsigned long long>(fnv1a64(snap->json)));
  snap->etag = std::string("\"") + (view == View::Full ? "f-" : "c-") + hex.data() + "\"";
  snap->built = std::chrono::steady_clock::now();
  const std::lock_guard lock(mu_);
  slot.snapshot = snap;
  return snap;
}

}  // namespace fleetgw::web
