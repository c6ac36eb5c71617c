#include "storage/store.h"

#include <fcntl.h>
#include <spdlog/spdlog.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <system_error>
#include <unordered_set>

#include "storage/schema.h"
#include "storage/sqlite.h"

namespace fleetgw::storage {
namespace fs = std::filesystem;
namespace {

// Reserved meta key of the persisted sequence counter (the next number to hand out).
constexpr std::string_view kNextSeqKey = "storage.next_seq";
constexpr int kEvictionReportPriority = static_cast<int>(OutboxPriority::kFault);
// After a checkpoint the WAL file is truncated back to this size, so a burst does not leave a
// large WAL behind on a small flash partition.
constexpr std::int64_t kJournalSizeLimit = 4 << 20;

// ---- SQL ------------------------------------------------------------------------------------

constexpr std::string_view kInsertOutbox =
    "INSERT INTO outbox (seq, priority, kind, created_us, payload, source_id) "
    "VALUES (?, ?, ?, ?, ?, ?)";
constexpr std::string_view kInsertTelemetry =
    "INSERT INTO telemetry (ts_us, speed_kmh, assist_level, soc_pct, voltage_v, current_a, "
    "motor_temp_c, controller_temp_c, battery_temp_c, wheel_lock_state, battery_lock_state) "
    "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)";
constexpr std::string_view kUpsertRide =
    "INSERT INTO rides (ride_id, state, partial, start_us, end_us, duration_s, moving_s, "
    "start_odo_km, end_odo_km, distance_km, distance_integrated_km, max_speed_kmh, "
    "avg_speed_kmh, energy_wh, energy_mah, soc_start_pct, soc_end_pct, assist_time_json, "
    "fault_count) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?) "
    "ON CONFLICT (ride_id) DO UPDATE SET state = excluded.state, partial = excluded.partial, "
    "start_us = excluded.start_us, end_us = excluded.end_us, duration_s = excluded.duration_s, "
    "moving_s = excluded.moving_s, start_odo_km = excluded.start_odo_km, "
    "end_odo_km = excluded.end_odo_km, distance_km = excluded.distance_km, "
    "distance_integrated_km = excluded.distance_integrated_km, "
    "max_speed_kmh = excluded.max_speed_kmh, avg_speed_kmh = excluded.avg_speed_kmh, "
    "energy_wh = excluded.energy_wh, energy_mah = excluded.energy_mah, "
    "soc_start_pct = excluded.soc_start_pct, soc_end_pct = excluded.soc_end_pct, "
    "assist_time_json = excluded.assist_time_json, fault_count = excluded.fault_count "
    "RETURNING id";
constexpr std::string_view kInsertFault =
    "INSERT INTO fault_events (node, bit, code, name, severity, event, first_seen_us, "
    "last_seen_us, occurrences) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)";
constexpr std::string_view kInsertPack =
    "INSERT INTO pack_snapshots (ts_us, voltage_v, current_a, soc_pct, soh_pct, cycles, "
    "temps_json, cell_min_mv, cell_max_mv, cell_spread_mv, cell_min_index, cell_max_index, "
    "lifetime_json) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)";
constexpr std::string_view kInsertLock =
    "INSERT INTO lock_events (ts_us, lock_node, kind, old_state, new_state, cause) "
    "VALUES (?, ?, ?, ?, ?, ?)";
constexpr std::string_view kInsertCommandResult =
    "INSERT INTO command_results (command_id, ts_us, result, reason, final_state, duration_ms) "
    "VALUES (?, ?, ?, ?, ?, ?)";
constexpr std::string_view kUpsertCommand =
    "INSERT INTO commands (command_id, received_us, state, expires_at_us) VALUES (?, ?, ?, ?) "
    "ON CONFLICT (command_id) DO UPDATE SET received_us = excluded.received_us, "
    "state = excluded.state, expires_at_us = excluded.expires_at_us";
constexpr std::string_view kUpsertSeen =
    "INSERT INTO seen_command_ids (command_id, expires_at_us) VALUES (?, ?) "
    "ON CONFLICT (command_id) DO UPDATE SET "
    "expires_at_us = max(expires_at_us, excluded.expires_at_us)";
constexpr std::string_view kUpsertMeta =
    "INSERT INTO meta (key, value) VALUES (?, ?) "
    "ON CONFLICT (key) DO UPDATE SET value = excluded.value";
constexpr std::string_view kRideColumns =
    "id, ride_id, state, partial, start_us, end_us, duration_s, moving_s, start_odo_km, "
    "end_odo_km, distance_km, distance_integrated_km, max_speed_kmh, avg_speed_kmh, energy_wh, "
    "energy_mah, soc_start_pct, soc_end_pct, assist_time_json, fault_count";

struct EvictableTable {
  std::string_view table;
  OutboxKind kind;
};
// Eviction order: cheapest loss first.
constexpr std::array<EvictableTable, 2> kEvictionOrder = {{
    {"telemetry", OutboxKind::kTelemetry},
    {"pack_snapshots", OutboxKind::kPack},
}};

struct ExportSpec {
  std::string_view table;
  std::string_view time_column;  // empty: the table has no time column
};
constexpr std::array<ExportSpec, 11> kExportSpecs = {{
    {"rides", "start_us"},
    {"fault_events", "first_seen_us"},
    {"pack_snapshots", "ts_us"},
    {"telemetry", "ts_us"},
    {"lock_events", "ts_us"},
    {"command_results", "ts_us"},
    {"commands", "received_us"},
    {"seen_command_ids", "expires_at_us"},
    {"outbox", "created_us"},
    {"meta", ""},
    {"eviction_counters", ""},
}};
constexpr std::array<std::string_view, kExportSpecs.size()> kExportNames = [] {
  std::array<std::string_view, kExportSpecs.size()> names{};
  for (std::size_t i = 0; i < kExportSpecs.size(); ++i) names[i] = kExportSpecs[i].table;
  return names;
}();

// ---- small helpers --------------------------------------------------------------------------

// flock()-based exclusive lock on "<db>.lock": one writer per database, across processes.
// A separate file is used because closing any descriptor of the database file itself would
// drop SQLite's POSIX locks (fcntl semantics).
class LockFile {
 public:
  explicit LockFile(const std::string& path) : path_(path) {
    fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd_ < 0) {
      throw std::system_error(errno, std::generic_category(),
                              "storage: cannot open lock file '" + path + "'");
    }
    if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
      int err = errno;
      ::close(fd_);
      fd_ = -1;
      if (err == EWOULDBLOCK) {
        throw std::runtime_error("storage: database lock '" + path +
                                 "' is held by another store (another fleetgw process, or a "
                                 "second Store on the same file); only one writer is allowed");
      }
      throw std::system_error(err, std::generic_category(), "storage: cannot lock '" + path + "'");
    }
  }
  LockFile(LockFile&& other) noexcept
      : fd_(std::exchange(other.fd_, -1)), path_(std::move(other.path_)) {}
  LockFile& operator=(LockFile&&) = delete;
  LockFile(const LockFile&) = delete;
  LockFile& operator=(const LockFile&) = delete;
  ~LockFile() {
    if (fd_ >= 0) ::close(fd_);  // releases the flock
  }

 private:
  int fd_ = -1;
  std::string path_;
};

std::int64_t system_now_us() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

std::string utc_stamp(std::int64_t us) {
  std::time_t secs = static_cast<std::time_t>(us / 1'000'000);
  std::tm tm{};
  gmtime_r(&secs, &tm);
  std::array<char, 32> buf{};
  std::strftime(buf.data(), buf.size(), "%Y%m%dT%H%M%SZ", &tm);
  return buf.data();
}

// Describes why the file at `path` cannot be an SQLite database, or nullopt if its header looks
// right (or it is absent/empty, which SQLite treats as a new database).
std::optional<std::string> header_problem(const std::string& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) return std::nullopt;
  auto size = fs::file_size(path, ec);
  if (ec) return std::nullopt;  // let SQLite report why it cannot read it
  if (size == 0) return std::nullopt;
  std::ifstream in(path, std::ios::binary);
  std::array<char, 16> header{};
  in.read(header.data(), header.size());
  if (!in) return "file of " + std::to_string(size) + " bytes is too short for an SQLite header";
  static constexpr char kMagic[16] = "SQLite format 3";  // 15 chars + NUL, as on disk
  if (std::memcmp(header.data(), kMagic, sizeof kMagic) != 0) {
    return "header is not 'SQLite format 3' (not an SQLite database)";
  }
  return std::nullopt;
}

bool is_corruption(const SqliteError& e) {
  return e.code() == SQLITE_CORRUPT || e.code() == SQLITE_NOTADB;
}

std::string quick_check(Database& db) {
  Statement st = db.prepare("PRAGMA quick_check(20)");
  std::string out;
  while (st.step()) {
    if (!out.empty()) out += "; ";
    out += st.column_text(0);
  }
  return out;
}

std::string hex(std::span<const std::uint8_t> bytes) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string s;
  s.reserve(bytes.size() * 2);
  for (auto b : bytes) {
    s += kDigits[b >> 4];
    s += kDigits[b & 0xf];
  }
  return s;
}

std::string json_text(const std::map<std::string, double>& m) {
  return nlohmann::json(m).dump();
}
std::string json_text(const std::vector<double>& v) {
  return nlohmann::json(v).dump();
}

Ride read_ride(const Statement& st) {
  Ride r;
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
  return r;
}

// ---- batch validation -----------------------------------------------------------------------

[[noreturn]] void reject(std::string_view field, std::size_t index, std::string_view member,
                         std::string_view problem) {
  throw std::invalid_argument("storage: Batch." + std::string(field) + "[" + std::to_string(index) +
                              "]." + std::string(member) + ": " + std::string(problem));
}

template <typename T>
void check_uplink(const std::vector<Pending<T>>& items, std::string_view field) {
  for (std::size_t i = 0; i < items.size(); ++i) {
    if (items[i].uplink && items[i].uplink->size() > Store::kMaxPayloadBytes) {
      reject(field, i, "uplink",
             "payload of " + std::to_string(items[i].uplink->size()) + " bytes exceeds " +
                 std::to_string(Store::kMaxPayloadBytes));
    }
  }
}

void check_time(std::int64_t us, std::string_view field, std::size_t i, std::string_view member) {
  if (us < 0) reject(field, i, member, "negative timestamp " + std::to_string(us));
}

void validate(const Batch& b) {
  if (b.now_us < 0) {
    throw std::invalid_argument("storage: Batch.now_us: negative timestamp " +
                                std::to_string(b.now_us));
  }
  check_uplink(b.telemetry, "telemetry");
  check_uplink(b.rides, "rides");
  check_uplink(b.faults, "faults");
  check_uplink(b.packs, "packs");
  check_uplink(b.locks, "locks");
  check_uplink(b.command_results, "command_results");
  for (std::size_t i = 0; i < b.telemetry.size(); ++i) {
    check_time(b.telemetry[i].record.ts_us, "telemetry", i, "ts_us");
  }
  for (std::size_t i = 0; i < b.rides.size(); ++i) {
    const Ride& r = b.rides[i].record;
    if (r.ride_id.empty()) reject("rides", i, "ride_id", "empty");
    if (r.state != RideState::kOpen && r.state != RideState::kClosed) {
      reject("rides", i, "state", "invalid value");
    }
    check_time(r.start_us, "rides", i, "start_us");
    if (r.end_us && *r.end_us < r.start_us) reject("rides", i, "end_us", "before start_us");
  }
  for (std::size_t i = 0; i < b.faults.size(); ++i) {
    const FaultEvent& f = b.faults[i].record;
    if (to_string(f.event) == "invalid") reject("faults", i, "event", "invalid value");
    check_time(f.first_seen_us, "faults", i, "first_seen_us");
    if (f.last_seen_us < f.first_seen_us) {
      reject("faults", i, "last_seen_us", "before first_seen_us");
    }
  }
  for (std::size_t i = 0; i < b.packs.size(); ++i) {
    check_time(b.packs[i].record.ts_us, "packs", i, "ts_us");
    if (!nlohmann::json::accept(b.packs[i].record.lifetime_json)) {
      reject("packs", i, "lifetime_json", "not valid JSON");
    }
  }
  for (std::size_t i = 0; i < b.locks.size(); ++i) {
    check_time(b.locks[i].record.ts_us, "locks", i, "ts_us");
  }
  for (std::size_t i = 0; i < b.command_results.size(); ++i) {
    if (b.command_results[i].record.command_id.empty()) {
      reject("command_results", i, "command_id", "empty");
    }
    check_time(b.command_results[i].record.ts_us, "command_results", i, "ts_us");
  }
  for (std::size_t i = 0; i < b.commands.size(); ++i) {
    if (b.commands[i].command_id.empty()) reject("commands", i, "command_id", "empty");
    check_time(b.commands[i].received_us, "commands", i, "received_us");
  }
  for (std::size_t i = 0; i < b.messages.size(); ++i) {
    const UplinkMessage& m = b.messages[i];
    if (m.priority < 0 || m.priority > kLowestPriority) {
      reject("messages", i, "priority",
             std::to_string(m.priority) + " outside 0.." + std::to_string(kLowestPriority));
    }
    if (to_string(m.kind) == "invalid") reject("messages", i, "kind", "invalid value");
    if (m.payload.size() > Store::kMaxPayloadBytes) {
      reject("messages", i, "payload",
             std::to_string(m.payload.size()) + " bytes exceeds " +
                 std::to_string(Store::kMaxPayloadBytes));
    }
  }
  for (std::size_t i = 0; i < b.meta.size(); ++i) {
    const std::string& key = b.meta[i].first;
    if (key.empty()) reject("meta", i, "key", "empty");
    if (key.starts_with("storage.")) reject("meta", i, "key", "'" + key + "' is reserved");
  }
}

}  // namespace

// ---------------------------------------------------------------------------------------------

std::size_t Batch::size() const {
  return telemetry.size() + rides.size() + faults.size() + packs.size() + locks.size() +
         command_results.size() + commands.size() + messages.size() + meta.size();
}

void Batch::clear() {
  telemetry.clear();
  rides.clear();
  faults.clear();
  packs.clear();
  locks.clear();
  command_results.clear();
  commands.clear();
  messages.clear();
  meta.clear();
}

nlohmann::json Stats::to_json() const {
  nlohmann::json j;
  j["path"] = path;
  j["schema_version"] = schema_version;
  for (const auto& [table, rows] : table_rows) j["tables"][table] = rows;
  j["outbox"]["in_flight"] = outbox_in_flight;
  j["outbox"]["by_priority"] = nlohmann::json::array();
  for (const auto& d : outbox) {
    j["outbox"]["by_priority"].push_back(
        {{"priority", d.priority}, {"entries", d.entries}, {"payload_bytes", d.payload_bytes}});
  }
  j["outbox"]["oldest_unsent_seq"] =
      oldest_unsent_seq ? nlohmann::json(*oldest_unsent_seq) : nlohmann::json();
  j["outbox"]["oldest_unsent_us"] =
      oldest_unsent_us ? nlohmann::json(*oldest_unsent_us) : nlohmann::json();
  j["outbox"]["oldest_unsent_kind"] =
      oldest_unsent_kind ? nlohmann::json(*oldest_unsent_kind) : nlohmann::json();
  j["outbox"]["next_seq"] = next_seq;
  j["disk"] = {{"file_bytes", file_bytes},         {"wal_bytes", wal_bytes},
               {"page_size", page_size},           {"page_count", page_count},
               {"freelist_pages", freelist_pages}, {"live_bytes", live_bytes},
               {"budget_bytes", budget_bytes}};
  j["evictions"] = nlohmann::json::object();
  for (const auto& e : evictions) {
    j["evictions"][e.table] = {
        {"rows", e.rows},
        {"passes", e.passes},
        {"last_us", e.last_us ? nlohmann::json(*e.last_us) : nlohmann::json()}};
  }
  return j;
}

// ---------------------------------------------------------------------------------------------

struct Store::Impl {
  StoreOptions options;
  std::shared_ptr<spdlog::logger> log;
  LockFile lock;
  std::optional<std::string> moved_aside;
  Database db;
  std::uint64_t next_seq = 1;
  std::unordered_set<std::uint64_t> in_flight;
  bool budget_exhausted_logged = false;

  explicit Impl(StoreOptions opts)
      : options(std::move(opts)),
        log(options.logger ? options.logger : spdlog::default_logger()),
        lock(options.path + ".lock"),
        db(open_database()) {
    configure();
    migrate(db);  // logs each step it applies
    if (db.query_int64("PRAGMA auto_vacuum").value_or(0) != 2) {
      // Only a database created by something else lands here; eviction still works (freed
      // pages are reused) but the file does not shrink until a manual VACUUM.
      log->warn(
          "storage: '{}' is not in auto_vacuum=INCREMENTAL mode; evicted space is reused "
          "but not returned to the file system",
          options.path);
    }
    load_next_seq();
  }

  Database open_database() {
    std::optional<std::string> problem = header_problem(options.path);
    if (!problem) {
      try {
        Database candidate(options.path);
        candidate.exec("PRAGMA busy_timeout = 5000");
        int version = schema_version(candidate);  // first real read: NOTADB shows up here
        if (version > kSchemaVersion) {
          throw SchemaTooNewError(options.path, version, kSchemaVersion);
        }
        std::string check = quick_check(candidate);
        if (check == "ok") return candidate;
        problem = "PRAGMA quick_check failed: " + check;
      } catch (const SqliteError& e) {
        if (!is_corruption(e)) throw;
        problem = e.what();
      }
    }
    move_aside(*problem);
    return Database(options.path);
  }

  void move_aside(const std::string& problem) {
    const std::int64_t now = options.wall_clock_us ? options.wall_clock_us() : system_now_us();
    std::string dest = options.path + ".corrupt-" + utc_stamp(now);
    std::error_code ec;
    for (int n = 1; fs::exists(dest, ec); ++n) {
      dest = options.path + ".corrupt-" + utc_stamp(now) + "-" + std::to_string(n);
    }
    fs::rename(options.path, dest, ec);
    if (ec) {
      throw std::system_error(ec, "storage: database '" + options.path + "' is corrupt (" +
                                      problem + ") and could not be moved aside to '" + dest + "'");
    }
    // The WAL and shared-memory files belong to the moved file: left in place they would be
    // replayed into (and corrupt) the fresh database.
    for (std::string_view suffix : {"-wal", "-shm", "-journal"}) {
      std::string side = options.path + std::string(suffix);
      if (fs::exists(side, ec)) {
        fs::rename(side, dest + std::string(suffix), ec);
        if (ec) {
          throw std::system_error(ec, "storage: cannot move '" + side + "' aside");
        }
      }
    }
    log->error(
        "storage: DATABASE '{}' IS CORRUPT OR UNREADABLE ({}); moved it to '{}' and "
        "started a fresh, empty database. Unsent records in the old file were NOT sent.",
        options.path, problem, dest);
    moved_aside = dest;
  }

  void configure() {
    db.exec("PRAGMA busy_timeout = 5000");
    if (schema_version(db) == 0) {
      // Must precede the first page write (journal_mode=WAL below writes the header).
      db.exec("PRAGMA auto_vacuum = INCREMENTAL");
    }
    auto mode = db.query_text("PRAGMA journal_mode = WAL");
    if (mode != "wal") {
      throw std::runtime_error("storage: cannot put '" + options.path +
                               "' in WAL mode (journal_mode is '" + mode.value_or("?") + "')");
    }
    db.exec(options.durability == Durability::kFull ? "PRAGMA synchronous = FULL"
                                                    : "PRAGMA synchronous = NORMAL");
    db.exec("PRAGMA wal_autocheckpoint = " + std::to_string(options.wal_autocheckpoint_pages));
    db.exec("PRAGMA journal_size_limit = " + std::to_string(kJournalSizeLimit));
    db.exec("PRAGMA temp_store = MEMORY");
  }

  void load_next_seq() {
    std::uint64_t from_meta = 0;
    {
      auto st = db.cached("SELECT value FROM meta WHERE key = ?");
      st->bind(1, kNextSeqKey);
      if (st->step()) from_meta = std::stoull(st->column_text(0));
    }
    std::uint64_t from_outbox =
        static_cast<std::uint64_t>(
            db.query_int64("SELECT ifnull(max(seq), 0) FROM outbox").value_or(0)) +
        1;
    if (from_outbox > from_meta && from_meta != 0) {
      // Cannot happen with this code (both are written in one transaction); if the file was
      // edited by hand, never hand out a number that is still queued.
      log->error("storage: '{}' sequence counter {} behind outbox ({}); continuing after outbox",
                 options.path, from_meta, from_outbox - 1);
    }
    next_seq = std::max<std::uint64_t>({from_meta, from_outbox, 1});
  }

  std::uint64_t live_bytes() {
    std::int64_t page_count, freelist, page_size;
    {
      auto st = db.cached("PRAGMA page_count");
      st->step();
      page_count = st->column_int64(0);
    }
    {
      auto st = db.cached("PRAGMA freelist_count");
      st->step();
      freelist = st->column_int64(0);
    }
    {
      auto st = db.cached("PRAGMA page_size");
      st->step();
      page_size = st->column_int64(0);
    }
    return static_cast<std::uint64_t>(std::max<std::int64_t>(page_count - freelist, 0) * page_size);
  }

  void enqueue(Statement& st, OutboxKind kind, int priority, std::span<const std::uint8_t> payload,
               std::optional<std::int64_t> source_id, std::int64_t now_us, std::uint64_t& seq) {
    st.bind_all(static_cast<std::int64_t>(seq), priority, to_string(kind), now_us, payload,
                source_id);
    st.run();
    st.reset();
    ++seq;
  }

  std::optional<EvictionReport> enforce_budget(std::int64_t now_us, Statement& outbox,
                                               std::uint64_t& seq);

  WriteResult write(const Batch& b);
};

WriteResult Store::Impl::write(const Batch& b) {
  validate(b);
  WriteResult result;
  if (b.empty()) return result;

  Transaction tx(db);
  std::uint64_t seq = next_seq;
  auto outbox = db.cached(kInsertOutbox);
  const std::int64_t now = b.now_us;

  // Each table: insert the row, then queue its payload pointing at the new row.
  auto queue = [&](const std::optional<Bytes>& uplink, OutboxKind kind, OutboxPriority prio,
                   std::int64_t row_id) {
    if (uplink) enqueue(*outbox, kind, static_cast<int>(prio), *uplink, row_id, now, seq);
  };

  if (!b.telemetry.empty()) {
    auto st = db.cached(kInsertTelemetry);
    for (const auto& [t, uplink] : b.telemetry) {
      st->bind_all(t.ts_us, t.speed_kmh, t.assist_level, t.soc_pct, t.voltage_v, t.current_a,
                   t.motor_temp_c, t.controller_temp_c, t.battery_temp_c, t.wheel_lock_state,
                   t.battery_lock_state);
      st->run();
      st->reset();
      queue(uplink, OutboxKind::kTelemetry, OutboxPriority::kTelemetry, db.last_insert_rowid());
    }
  }
  if (!b.rides.empty()) {
    auto st = db.cached(kUpsertRide);
    for (const auto& [r, uplink] : b.rides) {
      st->bind_all(r.ride_id, to_string(r.state), r.partial, r.start_us, r.end_us, r.duration_s,
                   r.moving_s, r.start_odo_km, r.end_odo_km, r.distance_km,
                   r.distance_integrated_km, r.max_speed_kmh, r.avg_speed_kmh, r.energy_wh,
                   r.energy_mah, r.soc_start_pct, r.soc_end_pct, json_text(r.assist_time_s),
                   r.fault_count);
      if (!st->step()) throw std::logic_error("storage: ride upsert returned no id");
      std::int64_t id = st->column_int64(0);
      st->reset();
      queue(uplink, OutboxKind::kRide, OutboxPriority::kRide, id);
    }
  }
  if (!b.faults.empty()) {
    auto st = db.cached(kInsertFault);
    for (const auto& [f, uplink] : b.faults) {
      st->bind_all(f.node, f.bit, f.code, f.name, f.severity, to_string(f.event), f.first_seen_us,
                   f.last_seen_us, f.occurrences);
      st->run();
      st->reset();
      queue(uplink, OutboxKind::kFault, OutboxPriority::kFault, db.last_insert_rowid());
    }
  }
  if (!b.packs.empty()) {
    auto st = db.cached(kInsertPack);
    for (const auto& [p, uplink] : b.packs) {
      st->bind_all(p.ts_us, p.voltage_v, p.current_a, p.soc_pct, p.soh_pct, p.cycles,
                   json_text(p.temps_c), p.cell_min_mv, p.cell_max_mv, p.cell_spread_mv,
                   p.cell_min_index, p.cell_max_index, p.lifetime_json);
      st->run();
      st->reset();
      queue(uplink, OutboxKind::kPack, OutboxPriority::kPack, db.last_insert_rowid());
    }
  }
  if (!b.locks.empty()) {
    auto st = db.cached(kInsertLock);
    for (const auto& [l, uplink] : b.locks) {
      st->bind_all(l.ts_us, l.lock_node, l.kind, l.old_state, l.new_state, l.cause);
      st->run();
      st->reset();
      queue(uplink, OutboxKind::kLock, OutboxPriority::kLock, db.last_insert_rowid());
    }
  }
  if (!b.command_results.empty()) {
    auto st = db.cached(kInsertCommandResult);
    for (const auto& [c, uplink] : b.command_results) {
      st->bind_all(c.command_id, c.ts_us, c.result, c.reason, c.final_state, c.duration_ms);
      st->run();
      st->reset();
      queue(uplink, OutboxKind::kCommandResult, OutboxPriority::kCommandResult,
            db.last_insert_rowid());
    }
  }
  if (!b.commands.empty()) {
    auto journal = db.cached(kUpsertCommand);
    auto seen = db.cached(kUpsertSeen);
    for (const auto& c : b.commands) {
      journal->bind_all(c.command_id, c.received_us, c.state, c.expires_at_us);
      journal->run();
      journal->reset();
      seen->bind_all(c.command_id, c.expires_at_us);
      seen->run();
      seen->reset();
    }
  }
  for (const auto& m : b.messages) {
    enqueue(*outbox, m.kind, m.priority, m.payload, std::nullopt, now, seq);
  }
  if (!b.meta.empty()) {
    auto st = db.cached(kUpsertMeta);
    for (const auto& [key, value] : b.meta) {
      st->bind_all(key, value);
      st->run();
      st->reset();
    }
  }

  result.eviction = enforce_budget(now, *outbox, seq);

  if (seq != next_seq) {
    // The counter is persisted in the same transaction as the rows that used the numbers.
    auto st = db.cached(kUpsertMeta);
    st->bind_all(kNextSeqKey, std::to_string(seq));
    st->run();
  }
  tx.commit();

  result.first_seq = seq != next_seq ? next_seq : 0;
  result.end_seq = seq != next_seq ? seq : 0;
  result.records = b.telemetry.size() + b.rides.size() + b.faults.size() + b.packs.size() +
                   b.locks.size() + b.command_results.size() + b.commands.size();
  next_seq = seq;  // only now: a rolled-back batch must not burn numbers in memory either
  if (result.eviction) {
    const EvictionReport& r = *result.eviction;
    log->warn(
        "storage: disk budget {} B reached on '{}' ({} -> {} B live): evicted {} "
        "telemetry samples, {} pack snapshots, {} unsent outbox entries{}",
        r.budget_bytes, options.path, r.bytes_before, r.bytes_after, r.telemetry_rows,
        r.pack_snapshot_rows, r.outbox_rows,
        r.budget_exhausted ? "; NOTHING LEFT TO EVICT, database stays over budget" : "");
  }
  return result;
}

std::optional<EvictionReport> Store::Impl::enforce_budget(std::int64_t now_us, Statement& outbox,
                                                          std::uint64_t& seq) {
  const std::uint64_t budget = options.max_bytes;
  if (budget == 0) return std::nullopt;
  std::uint64_t live = live_bytes();
  if (live <= budget) {
    budget_exhausted_logged = false;
    return std::nullopt;
  }

  EvictionReport report;
  report.at_us = now_us;
  report.budget_bytes = budget;
  report.bytes_before = live;
  const auto target = static_cast<std::uint64_t>(static_cast<double>(budget) * options.low_water);

  for (const auto& [table, kind] : kEvictionOrder) {
    const std::string t(table);
    auto cutoff_st = db.cached("SELECT id FROM " + t + " ORDER BY id LIMIT 1 OFFSET ?");
    auto max_st = db.cached("SELECT max(id) FROM " + t);
    auto delete_st = db.cached("DELETE FROM " + t + " WHERE id <= ?");
    auto delete_outbox =
        db.cached("DELETE FROM outbox WHERE kind = ? AND source_id IS NOT NULL AND source_id <= ?");
    std::uint64_t evicted = 0;
    while (live > target) {
      // Delete in chunks sized from the excess (rows are ~100-200 bytes with their outbox
      // entry) and re-measure: SQLite frees a page only once it is empty.
      const std::uint64_t excess = live - target;
      const std::int64_t chunk =
          std::clamp<std::int64_t>(static_cast<std::int64_t>(excess / 128), 64, 100'000);
      std::optional<std::int64_t> cutoff;
      cutoff_st->bind(1, chunk - 1);
      if (cutoff_st->step()) cutoff = cutoff_st->column_int64(0);
      cutoff_st->reset();
      if (!cutoff) {
        if (max_st->step()) cutoff = max_st->column_opt_int64(0);
        max_st->reset();
      }
      if (!cutoff) break;  // table empty
      delete_st->bind(1, *cutoff);
      delete_st->run();
      delete_st->reset();
      evicted += static_cast<std::uint64_t>(db.changes());
      delete_outbox->bind_all(to_string(kind), *cutoff);
      delete_outbox->run();
      delete_outbox->reset();
      report.outbox_rows += static_cast<std::uint64_t>(db.changes());
      live = live_bytes();
    }
    (kind == OutboxKind::kTelemetry ? report.telemetry_rows : report.pack_snapshot_rows) = evicted;
    if (evicted > 0) {
      auto st = db.cached(
          "UPDATE eviction_counters SET rows = rows + ?, passes = passes + 1, last_us = ? "
          "WHERE table_name = ?");
      st->bind_all(static_cast<std::int64_t>(evicted), now_us, table);
      st->run();
    }
  }
  if (report.outbox_rows > 0) {
    auto st = db.cached(
        "UPDATE eviction_counters SET rows = rows + ?, passes = passes + 1, last_us = ? "
        "WHERE table_name = 'outbox'");
    st->bind_all(static_cast<std::int64_t>(report.outbox_rows), now_us);
    st->run();
  }
  const bool evicted_any = report.telemetry_rows + report.pack_snapshot_rows > 0;
  if (evicted_any) {
    // Give the freed pages back to the file system (the file shrinks at the next checkpoint).
    auto st = db.cached("PRAGMA incremental_vacuum");
    st->run();
  }
  report.bytes_after = live_bytes();
  report.budget_exhausted = report.bytes_after > budget;
  {
    auto st = db.cached("SELECT ts_us FROM telemetry ORDER BY id LIMIT 1");
    if (st->step()) report.oldest_telemetry_kept_us = st->column_int64(0);
  }
  if (report.budget_exhausted && !budget_exhausted_logged) {
    log->error(
        "storage: '{}' is over its {} B budget with no telemetry or pack snapshots left "
        "to evict ({} B of faults, rides, lock events, commands and unsent outbox); "
        "raise max_mb or get the unit online",
        options.path, budget, report.bytes_after);
  }
  const bool first_exhaustion = report.budget_exhausted && !budget_exhausted_logged;
  budget_exhausted_logged = report.budget_exhausted;
  if (!evicted_any && !first_exhaustion) return std::nullopt;

  const std::string payload = report.to_json();
  enqueue(outbox, OutboxKind::kEvictionReport, kEvictionReportPriority,
          std::span(reinterpret_cast<const std::uint8_t*>(payload.data()), payload.size()),
          std::nullopt, now_us, seq);
  return report;
}

// ---------------------------------------------------------------------------------------------

Store::Store(StoreOptions options) {
  if (options.path.empty()) throw std::invalid_argument("storage: StoreOptions.path is empty");
  if (!(options.low_water > 0.0 && options.low_water <= 1.0)) {
    throw std::invalid_argument("storage: StoreOptions.low_water " +
                                std::to_string(options.low_water) + " outside (0, 1]");
  }
  if (options.wal_autocheckpoint_pages < 0) {
    throw std::invalid_argument("storage: StoreOptions.wal_autocheckpoint_pages is negative");
  }
  impl_ = std::make_unique<Impl>(std::move(options));
}

Store::Store(Store&&) noexcept = default;
Store& Store::operator=(Store&&) noexcept = default;
Store::~Store() = default;

WriteResult Store::write(const Batch& batch) {
  return impl_->write(batch);
}

std::vector<OutboxEntry> Store::peek_outbox(std::size_t limit, std::size_t max_bytes) {
  std::vector<OutboxEntry> out;
  if (limit == 0) return out;
  auto& db = impl_->db;
  auto& in_flight = impl_->in_flight;
  // At most in_flight.size() rows are skipped, so this LIMIT never cuts off an eligible entry.
  auto st = db.cached(
      "SELECT seq, priority, kind, created_us, payload, source_id FROM outbox "
      "ORDER BY priority, seq LIMIT ?");
  st->bind(1, static_cast<std::int64_t>(limit + in_flight.size()));
  std::size_t bytes = 0;
  while (out.size() < limit && st->step()) {
    const auto seq = static_cast<std::uint64_t>(st->column_int64(0));
    if (in_flight.contains(seq)) continue;
    OutboxEntry e;
    e.seq = seq;
    e.priority = static_cast<int>(st->column_int64(1));
    const std::string kind = st->column_text(2);
    if (auto k = outbox_kind_from_string(kind)) {
      e.kind = *k;
    } else {
      impl_->log->error("storage: outbox entry {} has unknown kind '{}'; sending it as 'info'", seq,
                        kind);
      e.kind = OutboxKind::kInfo;
    }
    e.created_us = st->column_int64(3);
    e.payload = st->column_blob(4);
    e.source_id = st->column_opt_int64(5);
    if (!out.empty() && bytes + e.payload.size() > max_bytes) break;
    bytes += e.payload.size();
    out.push_back(std::move(e));
  }
  for (const auto& e : out) in_flight.insert(e.seq);
  return out;
}

std::size_t Store::ack(std::span<const std::uint64_t> seqs) {
  if (seqs.empty()) return 0;
  auto& db = impl_->db;
  std::size_t deleted = 0;
  {
    Transaction tx(db);
    auto st = db.cached("DELETE FROM outbox WHERE seq = ?");
    for (auto seq : seqs) {
      st->bind(1, static_cast<std::int64_t>(seq));
      st->run();
      st->reset();
      deleted += static_cast<std::size_t>(db.changes());
    }
    tx.commit();
  }
  for (auto seq : seqs) impl_->in_flight.erase(seq);
  return deleted;
}

void Store::release(std::span<const std::uint64_t> seqs) {
  for (auto seq : seqs) impl_->in_flight.erase(seq);
}

void Store::release_all() {
  impl_->in_flight.clear();
}

std::size_t Store::in_flight() const {
  return impl_->in_flight.size();
}

std::vector<OutboxDepth> Store::outbox_depth() {
  std::vector<OutboxDepth> out;
  auto st = impl_->db.cached(
      "SELECT priority, count(*), ifnull(sum(length(payload)), 0) FROM outbox "
      "GROUP BY priority ORDER BY priority");
  while (st->step()) {
    out.push_back({static_cast<int>(st->column_int64(0)),
                   static_cast<std::uint64_t>(st->column_int64(1)),
                   static_cast<std::uint64_t>(st->column_int64(2))});
  }
  return out;
}

std::optional<std::int64_t> Store::oldest_unsent_us() {
  // Sequence order is creation order, and seq is the rowid: no scan.
  auto st = impl_->db.cached("SELECT created_us FROM outbox ORDER BY seq LIMIT 1");
  if (!st->step()) return std::nullopt;
  return st->column_int64(0);
}

std::uint64_t Store::next_seq() const {
  return impl_->next_seq;
}

std::vector<Ride> Store::open_rides() {
  std::vector<Ride> out;
  auto st = impl_->db.cached("SELECT " + std::string(kRideColumns) +
                             " FROM rides WHERE state = 'open' ORDER BY id");
  while (st->step()) out.push_back(read_ride(*st));
  return out;
}

std::optional<Ride> Store::ride(std::string_view ride_id) {
  auto st =
      impl_->db.cached("SELECT " + std::string(kRideColumns) + " FROM rides WHERE ride_id = ?");
  st->bind(1, ride_id);
  if (!st->step()) return std::nullopt;
  return read_ride(*st);
}

std::optional<CommandJournalEntry> Store::command(std::string_view command_id) {
  auto st = impl_->db.cached(
      "SELECT command_id, received_us, state, expires_at_us FROM commands WHERE command_id = ?");
  st->bind(1, command_id);
  if (!st->step()) return std::nullopt;
  return CommandJournalEntry{st->column_text(0), st->column_int64(1), st->column_text(2),
                             st->column_int64(3)};
}

bool Store::command_seen(std::string_view command_id, std::int64_t now_us) {
  auto st = impl_->db.cached("SELECT expires_at_us FROM seen_command_ids WHERE command_id = ?");
  st->bind(1, command_id);
  return st->step() && st->column_int64(0) > now_us;
}

std::size_t Store::purge_expired_commands(std::int64_t now_us) {
  auto& db = impl_->db;
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

Stats Store::stats() {
  auto& db = impl_->db;
  Stats s;
  s.path = impl_->options.path;
  s.schema_version = schema_version(db);
  for (std::string_view table : kExportNames) {
    auto n = db.query_int64("SELECT count(*) FROM " + std::string(table)).value_or(0);
    s.table_rows.emplace_back(std::string(table), static_cast<std::uint64_t>(n));
  }
  s.outbox = outbox_depth();
  s.outbox_in_flight = impl_->in_flight.size();
  {
    auto st = db.cached("SELECT seq, created_us, kind FROM outbox ORDER BY seq LIMIT 1");
    if (st->step()) {
      s.oldest_unsent_seq = static_cast<std::uint64_t>(st->column_int64(0));
      s.oldest_unsent_us = st->column_int64(1);
      s.oldest_unsent_kind = st->column_text(2);
    }
  }
  std::error_code ec;
  s.file_bytes = fs::file_size(impl_->options.path, ec);
  if (ec) s.file_bytes = 0;
  s.wal_bytes = fs::file_size(impl_->options.path + "-wal", ec);
  if (ec) s.wal_bytes = 0;
  s.page_size = static_cast<std::uint64_t>(db.query_int64("PRAGMA page_size").value_or(0));
  s.page_count = static_cast<std::uint64_t>(db.query_int64("PRAGMA page_count").value_or(0));
  s.freelist_pages =
      static_cast<std::uint64_t>(db.query_int64("PRAGMA freelist_count").value_or(0));
  s.live_bytes = impl_->live_bytes();
  s.budget_bytes = impl_->options.max_bytes;
  s.next_seq = impl_->next_seq;
  auto st = db.cached(
      "SELECT table_name, rows, passes, last_us FROM eviction_counters ORDER BY table_name");
  while (st->step()) {
    s.evictions.push_back({st->column_text(0), static_cast<std::uint64_t>(st->column_int64(1)),
                           static_cast<std::uint64_t>(st->column_int64(2)),
                           st->column_opt_int64(3)});
  }
  return s;
}

std::span<const std::string_view> Store::exportable_tables() {
  return kExportNames;
}

std::uint64_t Store::export_table(std::string_view table, std::int64_t since_us,
                                  const RowWriter& write_row) {
  const ExportSpec* spec = nullptr;
  for (const auto& s : kExportSpecs) {
    if (s.table == table) spec = &s;
  }
  if (spec == nullptr) {
    std::string known;
    for (auto name : kExportNames) {
      if (!known.empty()) known += ", ";
      known += name;
    }
    throw std::invalid_argument("storage: export_table: unknown table '" + std::string(table) +
                                "' (known: " + known + ")");
  }
  // The table name comes from the whitelist above, never from the caller's string.
  std::string sql = "SELECT * FROM " + std::string(spec->table);
  if (!spec->time_column.empty()) sql += " WHERE " + std::string(spec->time_column) + " >= ?";
  sql += " ORDER BY rowid";
  Statement st = impl_->db.prepare(sql);
  if (!spec->time_column.empty()) st.bind(1, since_us);
  std::uint64_t rows = 0;
  const int ncol = st.column_count();
  while (st.step()) {
    nlohmann::json row = nlohmann::json::object();
    for (int c = 0; c < ncol; ++c) {
      const std::string name = st.column_name(c);
      switch (st.column_type(c)) {
        case SQLITE_INTEGER:
          row[name] = st.column_int64(c);
          break;
        case SQLITE_FLOAT:
          row[name] = st.column_double(c);
          break;
        case SQLITE_TEXT: {
          std::string text = st.column_text(c);
          if (name.ends_with("_json")) {
            auto parsed = nlohmann::json::parse(text, nullptr, false);
            row[name] = parsed.is_discarded() ? nlohmann::json(text) : parsed;
          } else {
            row[name] = std::move(text);
          }
          break;
        }
        case SQLITE_BLOB:
          row[name] = hex(st.column_blob(c));
          break;
        default:
          row[name] = nullptr;
      }
    }
    write_row(row);
    ++rows;
  }
  return rows;
}

std::uint64_t Store::export_table(std::string_view table, std::int64_t since_us,
                                  std::ostream& out) {
  return export_table(table, since_us,
                      [&out](const nlohmann::json& row) { out << row.dump() << '\n'; });
}

std::string Store::integrity_check() {
  Statement st = impl_->db.prepare("PRAGMA integrity_check");
  std::string out;
  while (st.step()) {
    if (!out.empty()) out += "; ";
    out += st.column_text(0);
  }
  return out;
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
