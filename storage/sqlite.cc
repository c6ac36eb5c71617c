#include "storage/sqlite.h"

#include <spdlog/spdlog.h>

#include <utility>

namespace fleetgw::storage {
namespace {

std::string describe(sqlite3* db, int rc, std::string_view what, std::string_view path,
                     std::string_view sql) {
  std::string msg = "sqlite: ";
  msg += what;
  msg += " failed on '";
  msg += path;
  msg += "': ";
  // sqlite3_errmsg describes the most recent failure on the connection; fall back to the
  // generic text for the code when there is no connection yet.
  msg += db != nullptr ? sqlite3_errmsg(db) : sqlite3_errstr(rc);
  msg += " (code ";
  msg += std::to_string(rc);
  msg += ")";
  if (!sql.empty()) {
    msg += " in SQL: ";
    msg += sql.substr(0, 200);
  }
  return msg;
}

// Process-wide SQLite settings, applied once before the library initialises (sqlite3_config is
// refused afterwards, harmlessly: whoever opened a database first has chosen). Memory
// statistics are off: with them every allocation SQLite makes takes a global mutex, ~5 % of the
// CPU of a replayed hour, and nothing here reads sqlite3_status().
bool configure_sqlite() {
  sqlite3_config(SQLITE_CONFIG_MEMSTATUS, 0);
  return true;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Statement

Statement::Statement(sqlite3* db, std::string_view sql, std::string_view db_path)
    : db_(db), db_path_(db_path) {
  const char* tail = nullptr;
  int rc = sqlite3_prepare_v3(db, sql.data(), static_cast<int>(sql.size()),
                              SQLITE_PREPARE_PERSISTENT, &stmt_, &tail);
  if (rc != SQLITE_OK) {
    int ext = sqlite3_extended_errcode(db);
    std::string msg = describe(db, rc, "prepare", db_path, sql);
    sqlite3_finalize(stmt_);
    stmt_ = nullptr;
    throw SqliteError(rc & 0xff, ext, msg);
  }
  if (stmt_ == nullptr) {
    throw SqliteError(SQLITE_MISUSE, SQLITE_MISUSE,
                      "sqlite: empty SQL statement on '" + db_path_ + "'");
  }
}

Statement::Statement(Statement&& other) noexcept
    : stmt_(std::exchange(other.stmt_, nullptr)),
      db_(other.db_),
      db_path_(std::move(other.db_path_)) {}

Statement& Statement::operator=(Statement&& other) noexcept {
  if (this != &other) {
    sqlite3_finalize(stmt_);
    stmt_ = std::exchange(other.stmt_, nullptr);
    db_ = other.db_;
    db_path_ = std::move(other.db_path_);
  }
  return *this;
}

Statement::~Statement() {
  sqlite3_finalize(stmt_);
}

void Statement::fail(int rc, std::string_view what) const {
  throw SqliteError(rc & 0xff, sqlite3_extended_errcode(db_),
                    describe(db_, rc, what, db_path_, sql()));
}

void Statement::check_bind(int rc, int index) {
  if (rc != SQLITE_OK) fail(rc, "bind of parameter " + std::to_string(index));
}

Statement& Statement::bind(int index, std::int64_t value) {
  check_bind(sqlite3_bind_int64(stmt_, index, value), index);
  return *this;
}

Statement& Statement::bind(int index, double value) {
  check_bind(sqlite3_bind_double(stmt_, index, value), index);
  return *this;
}

Statement& Statement::bind(int index, std::string_view text) {
  // SQLITE_TRANSIENT: SQLite copies the text, so the caller's buffer may die before step().
  check_bind(
      sqlite3_bind_text64(stmt_, index, text.data(), text.size(), SQLITE_TRANSIENT, SQLITE_UTF8),
      index);
  return *this;
}

Statement& Statement::bind(int index, std::span<const std::uint8_t> blob) {
  // A zero-length blob with a null pointer would bind NULL; bind an empty blob explicitly.
  int rc = blob.empty()
               ? sqlite3_bind_zeroblob(stmt_, index, 0)
               : sqlite3_bind_blob64(stmt_, index, blob.data(), blob.size(), SQLITE_TRANSIENT);
  check_bind(rc, index);
  return *this;
}

Statement& Statement::bind(int index, std::nullptr_t) {
  check_bind(sqlite3_bind_null(stmt_, index), index);
  return *this;
}

bool Statement::step() {
  int rc = sqlite3_step(stmt_);
  if (rc == SQLITE_ROW) return true;
  if (rc == SQLITE_DONE) return false;
  fail(rc, "step");
}

void Statement::run() {
  while (step()) {
  }
}

void Statement::reset() noexcept {
  sqlite3_reset(stmt_);
  sqlite3_clear_bindings(stmt_);
}

int Statement::column_count() const {
  return sqlite3_column_count(stmt_);
}

std::string Statement::column_name(int col) const {
  const char* name = sqlite3_column_name(stmt_, col);
  return name != nullptr ? name : "";
}

int Statement::column_type(int col) const {
  return sqlite3_column_type(stmt_, col);
}

std::int64_t Statement::column_int64(int col) const {
  return sqlite3_column_int64(stmt_, col);
}

double Statement::column_double(int col) const {
  return sqlite3_column_double(stmt_, col);
}

std::string Statement::column_text(int col) const {
  const auto* text = sqlite3_column_text(stmt_, col);
  int n = sqlite3_column_bytes(stmt_, col);
  return text != nullptr ? std::string(reinterpret_cast<const char*>(text), n) : std::string();
}

std::vector<std::uint8_t> Statement::column_blob(int col) const {
  const auto* data = static_cast<const std::uint8_t*>(sqlite3_column_blob(stmt_, col));
  int n = sqlite3_column_bytes(stmt_, col);
  return data != nullptr ? std::vector<std::uint8_t>(data, data + n) : std::vector<std::uint8_t>();
}

std::optional<std::int64_t> Statement::column_opt_int64(int col) const {
  if (column_is_null(col)) return std::nullopt;
  return column_int64(col);
}

std::optional<double> Statement::column_opt_double(int col) const {
  if (column_is_null(col)) return std::nullopt;
  return column_double(col);
}

std::string_view Statement::sql() const {
  const char* s = stmt_ != nullptr ? sqlite3_sql(stmt_) : nullptr;
  return s != nullptr ? std::string_view(s) : std::string_view();
}

// ---------------------------------------------------------------------------------------------
// Database

Database::Database(const std::string& path, int flags) : path_(path) {
  [[maybe_unused]] static const bool configured = configure_sqlite();
  int rc = sqlite3_open_v2(path.c_str(), &db_, flags, nullptr);
  if (rc != SQLITE_OK) {
    int ext = db_ != nullptr ? sqlite3_extended_errcode(db_) : rc;
    std::string msg = describe(db_, rc, "open", path, {});
    close();
    throw SqliteError(rc & 0xff, ext, msg);
  }
  sqlite3_extended_result_codes(db_, 1);
}

Database::Database(Database&& other) noexcept
    : db_(std::exchange(other.db_, nullptr)),
      path_(std::move(other.path_)),
      cache_(std::move(other.cache_)) {}

Database& Database::operator=(Database&& other) noexcept {
  if (this != &other) {
    close();
    db_ = std::exchange(other.db_, nullptr);
    path_ = std::move(other.path_);
    cache_ = std::move(other.cache_);
  }
  return *this;
}

Database::~Database() {
  close();
}

void Database::close() noexcept {
  // Statements must be finalized before the connection can really close.
  cache_.clear();
  if (db_ != nullptr) {
    int rc = sqlite3_close_v2(db_);
    if (rc != SQLITE_OK) {
      spdlog::error("sqlite: closing '{}' failed: {}", path_, sqlite3_errstr(rc));
    }
    db_ = nullptr;
  }
}

void Database::exec(std::string_view sql) {
  std::string copy(sql);  // sqlite3_exec needs a NUL-terminated string
  char* err = nullptr;
  int rc = sqlite3_exec(db_, copy.c_str(), nullptr, nullptr, &err);
  if (rc != SQLITE_OK) {
    std::string msg =
        "sqlite: exec failed on '" + path_ +
        "': " + (err != nullptr ? std::string(err) : std::string(sqlite3_errstr(rc))) + " (code " +
        std::to_string(rc) + ") in SQL: " + copy.substr(0, 200);
    sqlite3_free(err);
    throw SqliteError(rc & 0xff, sqlite3_extended_errcode(db_), msg);
  }
}

Statement Database::prepare(std::string_view sql) const {
  return Statement(db_, sql, path_);
}

StatementLease Database::cached(std::string_view sql) {
  auto it = cache_.find(sql);
  if (it == cache_.end()) {
    it = cache_.emplace(std::string(sql), Statement(db_, sql, path_)).first;
  }
  return StatementLease(it->second);
}

std::optional<std::int64_t> Database::query_int64(std::string_view sql) {
  Statement st = prepare(sql);
  if (!st.step()) return std::nullopt;
  return st.column_int64(0);
}

std::optional<std::string> Database::query_text(std::string_view sql) {
  Statement st = prepare(sql);
  if (!st.step()) return std::nullopt;
  return st.column_text(0);
}

std::int64_t Database::last_insert_rowid() const {
  return sqlite3_last_insert_rowid(db_);
}

int Database::changes() const {
  return sqlite3_changes(db_);
}

// ---------------------------------------------------------------------------------------------
// Transaction

Transaction::Transaction(Database& db) : db_(db) {
  db_.cached("BEGIN IMMEDIATE")->run();
}

Transaction::~Transaction() {
  // In autocommit mode SQLite has already rolled the transaction back by itself (it does so
  // after some errors such as SQLITE_FULL); a second ROLLBACK would only produce an error.
  if (done_ || sqlite3_get_autocommit(db_.handle()) != 0) return;
  try {
    db_.cached("ROLLBACK")->run();
  } catch (const std::exception& e) {
    // SQLite may already have rolled back on its own (e.g. after SQLITE_FULL); nothing is lost
    // by logging and carrying on.
    spdlog::warn("sqlite: rollback on '{}': {}", db_.path(), e.what());
  }
}

void Transaction::commit() {
  db_.cached("COMMIT")->run();
  done_ = true;
}

}  // namespace fleetgw::storage
