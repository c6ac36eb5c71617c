// Store's lifecycle, health and the queries the gateway restores its state from at start-up
// (open rides, the command journal, meta). See storage/store.h and storage/store_impl.h.
#include "storage/store.h"

#include <spdlog/spdlog.h>

#include <chrono>
#include <filesystem>
#include <stdexcept>

#include "storage/store_impl.h"

namespace fleetgw::storage {
namespace fs = std::filesystem;
namespace {

constexpr std::string_view kRideColumns =
    "id, ride_id, state, partial, start_us, end_us, duration_s, moving_s, start_odo_km, "
    "end_odo_km, distance_km, distance_integrated_km, max_speed_kmh, avg_speed_kmh, energy_wh, "
    "energy_mah, soc_start_pct, soc_end_pct, assist_time_json, fault_count, start_lat_deg, "
    "start_lon_deg, end_lat_deg, end_lon_deg, gnss_distance_m, track";

RideRow read_ride(const Statement& st) {
  RideRow r;
  r.id = st.column_int64(0);
  r.ride_id = st.column_text(1);
  r.state = st.column_text(2) == "closed" ? RideState::kClosed : RideState::kOpen;
  r.partial = st.column_int64(3) != 0;
  r.start_us = st.column_int64(4);
  r.end_us = st.column_opt_int64(5);
  r.duration_s = st.column_double(6);
  r.moving_s = st.column_double(7);
  r.start_odo_km = st.column_opt_double(8);
  r.end_odo_km = st.column_opt_double(9);
  r.distance_km = st.column_double(10);
  r.distance_integrated_km = st.column_double(11);
  r.max_speed_kmh = st.column_double(12);
  r.avg_speed_kmh = st.column_double(13);
  r.energy_wh = st.column_double(14);
  r.energy_mah = st.column_double(15);
  if (auto v = st.column_opt_int64(16)) r.soc_start_pct = static_cast<int>(*v);
  if (auto v = st.column_opt_int64(17)) r.soc_end_pct = static_cast<int>(*v);
  auto assist = nlohmann::json::parse(st.column_text(18), nullptr, false);
  if (assist.is_object()) {
    for (const auto& [mode, secs] : assist.items()) {
      if (secs.is_number()) r.assist_time_s[mode] = secs.get<double>();
    }
  }
  r.fault_count = static_cast<int>(st.column_int64(19));
  r.start_lat_deg = st.column_opt_double(20);
  r.start_lon_deg = st.column_opt_double(21);
  r.end_lat_deg = st.column_opt_double(22);
  r.end_lon_deg = st.column_opt_double(23);
  r.gnss_distance_m = st.column_opt_double(24);
  if (!st.column_is_null(25)) r.track = st.column_text(25);
  return r;
}

}  // namespace

Status to_status(const std::exception& e) {
  if (const auto* sq = dynamic_cast<const SqliteError*>(&e)) {
    switch (sq->code()) {
      case SQLITE_FULL:
        return {StatusCode::kFull, std::string("disk full (SQLITE_FULL): ") + e.what()};
      case SQLITE_IOERR:
        return {StatusCode::kIo, std::string("I/O error (SQLITE_IOERR): ") + e.what()};
      case SQLITE_CONSTRAINT:
      case SQLITE_MISMATCH:
      case SQLITE_TOOBIG:
        return {StatusCode::kInvalid, e.what()};
      default:
        return {StatusCode::kOther, e.what()};
    }
  }
  if (dynamic_cast<const std::invalid_argument*>(&e) != nullptr) {
    return {StatusCode::kInvalid, e.what()};
  }
  return {StatusCode::kOther, e.what()};
}

std::size_t Batch::size() const {
  return telemetry.size() + rides.size() + faults.size() + packs.size() + locks.size() +
         alarms.size() + zone_events.size() + command_results.size() + commands.size() +
         messages.size() + meta.size();
}

void Batch::clear() {
  telemetry.clear();
  rides.clear();
  faults.clear();
  packs.clear();
  locks.clear();
  alarms.clear();
  zone_events.clear();
  command_results.clear();
  commands.clear();
  messages.clear();
  meta.clear();
}

Store::Store(StoreOptions options) {
  if (options.path.empty()) throw std::invalid_argument("storage: StoreOptions.path is empty");
  if (!(options.low_water > 0.0 && options.low_water <= 1.0)) {
    throw std::invalid_argument("storage: StoreOptions.low_water " +
                                std::to_string(options.low_water) + " outside (0, 1]");
  }
  if (options.wal_autocheckpoint_pages < 0) {
    throw std::invalid_argument("storage: StoreOptions.wal_autocheckpoint_pages is negative");
  }
  if (!options.read_only) {
    const fs::path p(options.path);
    const fs::path dir = p.has_parent_path() ? p.parent_path() : fs::path(".");
    std::error_code ec;
    if (!fs::is_directory(dir, ec)) {
      throw std::invalid_argument("storage: the directory '" + dir.string() +
                                  "' of storage.path '" + options.path +
                                  "' does not exist (it is never created: create it or fix "
                                  "storage.path)");
    }
  }
  impl_ = std::make_unique<Impl>(std::move(options));
}

Store::Store(Store&&) noexcept = default;
Store& Store::operator=(Store&&) noexcept = default;
Store::~Store() = default;

Result<Written> Store::write(const Batch& batch) {
  return impl_->write(batch);
}

std::uint64_t Store::next_seq() const {
  return impl_->next_seq;
}

const std::string& Store::store_id() const {
  return impl_->store_id;
}

StorageHealth Store::health() const {
  return impl_->health;
}

std::uint64_t Store::effective_budget() const {
  return impl_->budget.effective;
}

bool Store::read_only() const {
  return impl_->options.read_only;
}

void Store::Impl::record_success() {
  if (health.failing) {
    // A disk that is nearly full may flip between failing and working at every retry: the
    // recovery is logged at most once per 10 s (the failures are counted meanwhile).
    const auto now = options.env->steady_now();
    if (!last_recovery_logged || now - *last_recovery_logged >= std::chrono::seconds(10)) {
      error_log.resolved("storage: writing to '" + options.path + "' works again (" +
                         std::to_string(health.failed_writes) + " failed attempts so far)");
      last_recovery_logged = now;
    }
  }
  health.failing = false;
  health.failing_since_us = 0;
}

void Store::Impl::record_failure(const Status& error, std::string_view what) {
  if (!health.failing) {
    health.failing_since_us = options.env->wall_now().count();
  }
  health.failing = true;
  ++health.failed_writes;
  // The health line keeps the reason short; the log has SQLite's whole message.
  switch (error.code) {
    case StatusCode::kFull:
      health.last_error = "disk full (SQLITE_FULL)";
      break;
    case StatusCode::kIo:
      health.last_error = "I/O error (SQLITE_IOERR)";
      break;
    default:
      health.last_error = error.message.substr(0, 200);
  }
  error_log.report("storage: " + std::string(what) + " failed on '" + options.path +
                   "': " + health.last_error);
}

std::vector<RideRow> Store::open_rides() {
  std::vector<RideRow> out;
  auto st = impl_->db.cached("SELECT " + std::string(kRideColumns) +
                             " FROM rides WHERE state = 'open' ORDER BY id");
  while (st->step()) out.push_back(read_ride(*st));
  return out;
}

std::optional<RideRow> Store::ride(std::string_view ride_id) {
  auto st =
      impl_->db.cached("SELECT " + std::string(kRideColumns) + " FROM rides WHERE ride_id = ?");
  st->bind(1, ride_id);
  if (!st->step()) return std::nullopt;
  return read_ride(*st);
}

std::optional<CommandJournalRow> Store::command(std::string_view command_id) {
  auto st = impl_->db.cached(
      "SELECT command_id, received_us, state, expires_at_us, command_sha256 FROM commands "
      "WHERE command_id = ?");
  st->bind(1, command_id);
  if (!st->step()) return std::nullopt;
  const std::vector<std::uint8_t> sha = st->column_blob(4);  // empty for NULL (pre-v3 rows)
  return CommandJournalRow{st->column_text(0), st->column_int64(1), st->column_text(2),
                             st->column_int64(3), std::string(sha.begin(), sha.end())};
}

bool Store::command_seen(std::string_view command_id, std::int64_t now_us) {
  auto st = impl_->db.cached("SELECT expires_at_us FROM seen_command_ids WHERE command_id = ?");
  st->bind(1, command_id);
  return st->step() && st->column_int64(0) > now_us;
}

std::size_t Store::purge_expired_commands(std::int64_t now_us) {
  if (impl_->options.read_only) return 0;
  try {
    return impl_->purge_expired_commands(now_us);
  } catch (const std::exception& e) {
    impl_->record_failure(to_status(e), "purging expired commands");
    return 0;
  }
}

std::size_t Store::Impl::purge_expired_commands(std::int64_t now_us) {
  Transaction tx(db);
  std::size_t n = 0;
  {
    auto st = db.cached("DELETE FROM seen_command_ids WHERE expires_at_us <= ?");
    st->bind(1, now_us);
    st->run();
    n = static_cast<std::size_t>(db.changes());
  }
  {
    auto st = db.cached("DELETE FROM commands WHERE expires_at_us <= ?");
    st->bind(1, now_us);
    st->run();
  }
  tx.commit();
  return n;
}

std::optional<std::string> Store::meta(std::string_view key) {
  auto st = impl_->db.cached("SELECT value FROM meta WHERE key = ?");
  st->bind(1, key);
  if (!st->step()) return std::nullopt;
  return st->column_text(0);
}

std::uint64_t Store::live_bytes() {
  return impl_->live_bytes();
}

int Store::synchronous_mode() {
  return static_cast<int>(impl_->db.query_int64("PRAGMA synchronous").value_or(-1));
}

const std::string& Store::path() const {
  return impl_->options.path;
}

const std::optional<std::string>& Store::moved_aside_path() const {
  return impl_->moved_aside;
}

}  // namespace fleetgw::storage
