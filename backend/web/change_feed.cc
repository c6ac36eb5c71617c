// The change poller behind the server-sent events (change_feed.h).
#include "backend/web/change_feed.h"

#include <spdlog/spdlog.h>

#include <memory>
#include <optional>

#include "backend/common/pg.h"

namespace fleetgw::web {
namespace {

// Text maxima, compared as opaque strings: any difference is a change.
constexpr std::string_view kPollSql = R"sql(
SELECT (SELECT max(received_at_us) FROM vehicle_state)::text || '/' ||
       coalesce((SELECT max(received_at_us) FROM status)::text, '-'),
       coalesce((SELECT max(committed_at_us) FROM alarms)::text, '-') || '/' ||
       coalesce((SELECT max(acked_at_us) FROM console_alarm_acks)::text, '-') || '/' ||
       coalesce((SELECT max(resolved_at_us) FROM console_alarm_resolutions)::text, '-'),
       coalesce((SELECT max(issued_at_us) FROM console_commands)::text, '-') || '/' ||
       coalesce((SELECT max(result_at_us) FROM console_commands)::text, '-')
)sql";

}  // namespace

ChangeFeed::ChangeFeed(std::string conninfo, std::chrono::milliseconds interval)
    : conninfo_(std::move(conninfo)),
      interval_(interval),
      thread_([this](const std::stop_token& st) { run(st); }) {}

ChangeFeed::~ChangeFeed() {
  stop();
}

void ChangeFeed::stop() {
  {
    const std::lock_guard lock(mu_);
    stopped_ = true;
  }
  thread_.request_stop();
  cv_.notify_all();
}

bool ChangeFeed::stopped() {
  const std::lock_guard lock(mu_);
  return stopped_;
}

ChangeFeed::Cursor ChangeFeed::current() {
  const std::lock_guard lock(mu_);
  return cursor_;
}

void ChangeFeed::notify_commands() {
  {
    const std::lock_guard lock(mu_);
    ++cursor_.commands;
  }
  cv_.notify_all();
}

ChangeFeed::Cursor ChangeFeed::wait_change(Cursor seen, std::chrono::milliseconds timeout) {
  std::unique_lock lock(mu_);
  cv_.wait_for(lock, timeout, [&] { return stopped_ || !(cursor_ == seen); });
  return cursor_;
}

void ChangeFeed::run(const std::stop_token& stop) {
  std::unique_ptr<PgConnection> conn;
  std::string fleet_mark;
  std::string alarm_mark;
  std::string command_mark;
  std::string last_error;
  while (!stop.stop_requested()) {
    try {
      if (!conn || !conn->ok()) conn = std::make_unique<PgConnection>(conninfo_);
      const PgResult r = conn->exec(kPollSql, "change poll");
      const std::string f = r.is_null(0, 0) ? "-" : r.str(0, 0);
      const std::string a = r.str(0, 1);
      const std::string cm = r.str(0, 2);
      const std::lock_guard lock(mu_);
      if (cm != command_mark) ++cursor_.commands;
      command_mark = cm;
      // An alarm or an acknowledgement changes the fleet's colours too.
      if (f != fleet_mark || a != alarm_mark) ++cursor_.fleet;
      if (a != alarm_mark) ++cursor_.alarms;
      fleet_mark = f;
      alarm_mark = a;
      last_error.clear();
      cv_.notify_all();
    } catch (const PgError& e) {
      if (e.what() != last_error) spdlog::warn("serve: live updates: {}", e.what());
      last_error = e.what();
      if (conn && !conn->ok()) conn.reset();
    }
    std::unique_lock lock(mu_);
    cv_.wait_for(lock, stop, interval_, [] { return false; });
  }
}

}  // namespace fleetgw::web
