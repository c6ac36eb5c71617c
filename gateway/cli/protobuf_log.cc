#include "gateway/cli/protobuf_log.h"

#include <google/protobuf/stubs/common.h>
#include <google/protobuf/stubs/logging.h>
#include <spdlog/spdlog.h>

#include <mutex>
#include <optional>
#include <string>

#include "gateway/common/untrusted_text.h"
#include "storage/rate_limited_log.h"

namespace fleetgw::cli {
namespace {

namespace pb = google::protobuf;

// The state behind protobuf's plain function pointer (see the header).
struct Route {
  std::mutex mu;
  std::chrono::steady_clock::duration window{};
  std::optional<storage::RateLimitedLog> log;  // made at the first message (configured logger)
  pb::LogHandler* previous = nullptr;          // restored on destruction
};

Route& route() {
  static Route r;
  return r;
}

void on_protobuf_log(pb::LogLevel level, const char* /*file*/, int /*line*/,
                     const std::string& message) {
  if (level == pb::LOGLEVEL_INFO) return;
  // protobuf may quote the bytes it refused: one escaped, bounded line.
  const std::string text = "protobuf: " + common::untrusted_excerpt(message, 300);
  if (level == pb::LOGLEVEL_FATAL) {
    spdlog::critical("{}", text);  // protobuf aborts or throws right after
    return;
  }
  Route& r = route();
  std::lock_guard lock(r.mu);
  if (!r.log) r.log.emplace(spdlog::default_logger(), r.window);
  r.log->report(text);
}

}  // namespace

ProtobufLogRoute::ProtobufLogRoute(std::chrono::steady_clock::duration window) {
  {
    Route& r = route();
    std::lock_guard lock(r.mu);
    r.window = window;
    r.log.reset();
    r.previous = pb::SetLogHandler(on_protobuf_log);
  }
}

ProtobufLogRoute::~ProtobufLogRoute() {
  Route& r = route();
  std::lock_guard lock(r.mu);
  // What was there before (protobuf returns its default handler, or nullptr for the silent one).
  pb::SetLogHandler(r.previous);
  if (r.log && r.log->suppressed() > 0) r.log->resolved("protobuf: end of run");
  r.log.reset();
}

}  // namespace fleetgw::cli
