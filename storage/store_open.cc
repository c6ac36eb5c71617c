// Opening a store: the writer's lock file, the corrupt-file move-aside, the read-only open of
// the technician tools, connection pragmas and the disk budget plan (see storage/store_impl.h).
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
#include <random>
#include <string>
#include <system_error>

#include "storage/schema.h"
#include "storage/store_impl.h"

namespace fleetgw::storage {
namespace fs = std::filesystem;
namespace {

// ":memory:" or a "file:" URI with mode=memory: no file, so no second connection to it.
bool is_in_memory(std::string_view path) {
  return path == ":memory:" ||
         (path.starts_with("file:") && path.find("mode=memory") != std::string_view::npos);
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
// right (or it is absent/empty, which SQLite treats as a new database). Only reads the file.
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

// "file:<path>?immutable=1", with the characters a URI reserves percent-encoded.
std::string immutable_uri(const std::string& path) {
  std::string uri = "file:";
  for (unsigned char c : path) {
    if (c == '%' || c == '?' || c == '#' || c < 0x20 || c >= 0x7f) {
      static constexpr char kHex[] = "0123456789ABCDEF";
      uri += '%';
      uri += kHex[c >> 4];
      uri += kHex[c & 0xf];
    } else {
      uri += static_cast<char>(c);
    }
  }
  return uri + "?immutable=1";
}

std::optional<LockFile> lock_unless_read_only(const StoreOptions& o) {
  if (o.read_only) return std::nullopt;
  return std::optional<LockFile>(std::in_place, o.path + ".lock");
}

}  // namespace

// ---- lock file ------------------------------------------------------------------------------

LockFile::LockFile(const std::string& path) {
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

LockFile::LockFile(LockFile&& other) noexcept : fd_(std::exchange(other.fd_, -1)) {}

LockFile::~LockFile() {
  if (fd_ >= 0) ::close(fd_);  // releases the flock
}

std::optional<std::uint64_t> disk_capacity_for(Env& env, const std::string& db_path) {
  const fs::path p(db_path);
  const fs::path dir = p.has_parent_path() ? p.parent_path() : fs::path(".");
  std::uint64_t available = 0;
  if (env.free_space(dir, available)) return std::nullopt;
  std::uint64_t ours = 0;
  for (std::string_view suffix : {"", "-wal", "-shm"}) {
    std::error_code ec;
    const auto size = fs::file_size(db_path + std::string(suffix), ec);
    if (!ec) ours += size;
  }
  const std::uint64_t capacity = available + ours;
  return capacity - capacity / 20;
}

// ---- Impl -----------------------------------------------------------------------------------

int Store::Impl::on_wal_commit(void* impl, sqlite3* /*db*/, const char* /*name*/, int frames) {
  static_cast<Impl*>(impl)->wal_frames = static_cast<std::uint64_t>(std::max(frames, 0));
  return SQLITE_OK;
}

Store::Impl::Impl(StoreOptions opts)
    : options(std::move(opts)),
      log(options.logger ? options.logger : spdlog::default_logger()),
      lock(lock_unless_read_only(options)),
      db(options.read_only ? open_read_only() : open_database()),
      error_log(log, std::chrono::seconds(10), *options.env) {
  if (options.read_only) {
    budget = plan_budget(options.max_bytes, options.max_bytes, 4096, 0);
    health.configured_budget_bytes = budget.configured;
    health.effective_budget_bytes = budget.effective;
    // One read snapshot for both reads: the service may commit between them (WAL), and a
    // counter read before a commit next to outbox rows read after it is no inconsistency.
    db.exec("BEGIN");
    load_next_seq();
    db.exec("COMMIT");
    load_store_id(false);
    return;
  }
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
  load_store_id(true);
  plan_disk_budget();
  if (!is_in_memory(options.path)) checkpointer.emplace(options.path, log, *options.env);
}

Database Store::Impl::open_database() {
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

Database Store::Impl::open_read_only() {
  const std::string& path = options.path;
  std::error_code ec;
  const auto status = fs::status(path, ec);
  if (!fs::exists(status)) {
    throw NotAStoreError("storage: no database at '" + path + "' (no such file)");
  }
  if (!fs::is_regular_file(status)) {
    throw NotAStoreError("storage: '" + path + "' is not a fleetgw store (not a regular file)");
  }
  if (fs::file_size(path, ec) == 0) {
    throw NotAStoreError("storage: '" + path + "' is not a fleetgw store (empty file)");
  }
  if (auto problem = header_problem(path)) {
    throw NotAStoreError("storage: '" + path + "' is not a fleetgw store: " + *problem);
  }
  // Without a -wal file nobody is writing (the last writer checkpointed and removed it): read
  // the file as immutable, so SQLite creates no -wal/-shm next to it. With one, the writer may
  // be running: read through the WAL, whose files exist already.
  const bool writer_present = fs::exists(path + "-wal", ec);
  Database db_ro = writer_present
                       ? Database(path, SQLITE_OPEN_READONLY | SQLITE_OPEN_NOMUTEX)
                       : Database(immutable_uri(path),
                                  SQLITE_OPEN_READONLY | SQLITE_OPEN_NOMUTEX | SQLITE_OPEN_URI);
  int version = 0;
  std::int64_t tables = 0;
  try {
    db_ro.exec("PRAGMA busy_timeout = 5000");  // connection setting, writes nothing
    version = schema_version(db_ro);
    tables = db_ro
                 .query_int64(
                     "SELECT count(*) FROM sqlite_master WHERE type = 'table' AND name IN "
                     "('meta', 'outbox', 'telemetry', 'rides', 'commands')")
                 .value_or(0);
  } catch (const SqliteError& e) {
    throw NotAStoreError("storage: '" + path + "' is not a readable fleetgw store: " + e.what());
  }
  if (version > kSchemaVersion) throw SchemaTooNewError(path, version, kSchemaVersion);
  if (version == 0 || tables != 5) {
    throw NotAStoreError("storage: '" + path +
                         "' is an SQLite database but not a fleetgw store (no fleetgw tables)");
  }
  if (version < kSchemaVersion) {
    throw std::runtime_error("storage: '" + path + "' has schema version " +
                             std::to_string(version) + ", older than " +
                             std::to_string(kSchemaVersion) +
                             "; the service migrates it when it starts (inspection never does)");
  }
  return db_ro;
}

void Store::Impl::move_aside(const std::string& problem) {
  const std::int64_t now = options.env->wall_now().count();
  std::string dest = options.path + ".corrupt-" + utc_stamp(now);
  std::error_code ec;
  for (int n = 1; fs::exists(dest, ec); ++n) {
    dest = options.path + ".corrupt-" + utc_stamp(now) + "-" + std::to_string(n);
  }
  ec = options.env->rename_file(options.path, dest);
  if (ec) {
    throw std::system_error(ec, "storage: database '" + options.path + "' is corrupt (" + problem +
                                    ") and could not be moved aside to '" + dest + "'");
  }
  // The WAL and shared-memory files belong to the moved file: left in place they would be
  // replayed into (and corrupt) the fresh database.
  for (std::string_view suffix : {"-wal", "-shm", "-journal"}) {
    std::string side = options.path + std::string(suffix);
    if (fs::exists(side, ec)) {
      ec = options.env->rename_file(side, dest + std::string(suffix));
      if (ec) throw std::system_error(ec, "storage: cannot move '" + side + "' aside");
    }
  }
  log->error(
      "storage: DATABASE '{}' IS CORRUPT OR UNREADABLE ({}); moved it to '{}' and "
      "started a fresh, empty database. Unsent records in the old file were NOT sent.",
      options.path, problem, dest);
  moved_aside = dest;
}

void Store::Impl::configure() {
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
  db.exec("PRAGMA temp_store = MEMORY");
}

void Store::Impl::plan_disk_budget() {
  page_size = static_cast<std::uint64_t>(db.query_int64("PRAGMA page_size").value_or(4096));
  std::uint64_t effective = options.max_bytes;
  if (effective > 0) {
    if (auto capacity = disk_capacity_for(*options.env, options.path); capacity && *capacity < effective) {
      log->warn(
          "storage: storage.max_mb is {} MB but the file system holding '{}' can give the store "
          "only {:.1f} MB; disk budget clamped to {:.1f} MB",
          effective >> 20, options.path, static_cast<double>(*capacity) / (1 << 20),
          static_cast<double>(*capacity) / (1 << 20));  // the same figure: clamped to all of it
      effective = *capacity;
    }
  }
  budget = plan_budget(options.max_bytes, effective, page_size, options.wal_autocheckpoint_pages);
  health.configured_budget_bytes = budget.configured;
  health.effective_budget_bytes = budget.effective;
  // The WAL is checkpointed by the store itself (checkpoint_if_due, and write() at the whole
  // allowance): the hook replaces SQLite's automatic checkpoint inside COMMIT.
  sqlite3_wal_hook(db.handle(), &on_wal_commit, this);
  db.exec("PRAGMA journal_size_limit = " + std::to_string(budget.wal_allowance));
  if (options.max_page_count > 0) {
    db.exec("PRAGMA max_page_count = " + std::to_string(options.max_page_count));
  }
}

void Store::Impl::load_next_seq() {
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

namespace {

// A random version-4 UUID: unique per store without any coordination (122 random bits from the
// operating system's entropy source).
std::string random_store_id() {
  std::random_device entropy;
  std::array<std::uint8_t, 16> b{};
  for (std::size_t i = 0; i < b.size(); i += 4) {
    const std::uint32_t word = entropy();
    for (std::size_t k = 0; k < 4; ++k) b[i + k] = static_cast<std::uint8_t>(word >> (8 * k));
  }
  b[6] = static_cast<std::uint8_t>((b[6] & 0x0F) | 0x40);  // version 4
  b[8] = static_cast<std::uint8_t>((b[8] & 0x3F) | 0x80);  // RFC 4122 variant
  static constexpr char kHex[] = "0123456789abcdef";
  std::string out;
  for (std::size_t i = 0; i < b.size(); ++i) {
    if (i == 4 || i == 6 || i == 8 || i == 10) out.push_back('-');
    out.push_back(kHex[b[i] >> 4]);
    out.push_back(kHex[b[i] & 0x0F]);
  }
  return out;
}

}  // namespace

void Store::Impl::load_store_id(bool create) {
  {
    auto st = db.cached("SELECT value FROM meta WHERE key = ?");
    st->bind(1, kStoreIdKey);
    if (st->step()) store_id = st->column_text(0);
  }
  if (!store_id.empty() || !create) return;
  // Created with the store (or on the first open of a store older than the key) and never
  // changed: sequences restart only with a new store, and then with a new id.
  store_id = random_store_id();
  auto st = db.cached("INSERT INTO meta (key, value) VALUES (?, ?)");
  st->bind(1, kStoreIdKey);
  st->bind(2, store_id);
  st->run();
  log->info("storage: '{}' has the new store id {}", options.path, store_id);
}

}  // namespace fleetgw::storage
