// Thin RAII wrappers over the SQLite C API, used only inside fleetgw_storage.
//
// Contract:
// - Database owns one sqlite3 connection; it is move-only and closes the connection on
//   destruction. It is NOT thread-safe: one Database is used from one thread at a time (the
//   connection is opened with SQLITE_OPEN_NOMUTEX).
// - Every failing SQLite call throws SqliteError carrying the primary and extended result
//   code, the database path and the SQL text, so a log line says what failed and where.
// - Statement owns one prepared statement. bind() indices are 1-based (SQLite convention),
//   column indices 0-based. step() returns true while a row is available and false when done.
// - Database::cached() hands out a StatementLease on a prepared statement kept for the life of
//   the connection (prepare once, run many times on the hot path). The lease resets the
//   statement and clears its bindings when it goes out of scope, so a half-read SELECT never
//   keeps a read snapshot open (which would block WAL checkpoints).
// - Transaction issues BEGIN IMMEDIATE (take the write lock up front, so a batch never fails
//   half-way on SQLITE_BUSY) and rolls back on destruction unless commit() succeeded.
#pragma once

#include <sqlite3.h>

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace fleetgw::storage {

// A failed SQLite call. code() is the primary result code (SQLITE_CORRUPT, SQLITE_FULL...),
// extended_code() the extended one.
class SqliteError : public std::runtime_error {
 public:
  SqliteError(int code, int extended_code, const std::string& message)
      : std::runtime_error(message), code_(code), extended_code_(extended_code) {}
  int code() const noexcept { return code_; }
  int extended_code() const noexcept { return extended_code_; }

 private:
  int code_;
  int extended_code_;
};

class Statement {
 public:
  // Prepares `sql` on `db`; throws SqliteError naming `db_path` and the SQL on failure.
  Statement(sqlite3* db, std::string_view sql, std::string_view db_path);
  Statement(Statement&& other) noexcept;
  Statement& operator=(Statement&& other) noexcept;
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;
  ~Statement();

  Statement& bind(int index, std::int64_t value);
  Statement& bind(int index, int value) { return bind(index, static_cast<std::int64_t>(value)); }
  Statement& bind(int index, std::uint32_t value) {
    return bind(index, static_cast<std::int64_t>(value));
  }
  Statement& bind(int index, bool value) { return bind(index, std::int64_t{value ? 1 : 0}); }
  Statement& bind(int index, double value);
  Statement& bind(int index, std::string_view text);
  Statement& bind(int index, const char* text) { return bind(index, std::string_view(text)); }
  Statement& bind(int index, const std::string& text) {
    return bind(index, std::string_view(text));
  }
  Statement& bind(int index, std::span<const std::uint8_t> blob);
  Statement& bind(int index, std::nullptr_t);
  // std::nullopt binds SQL NULL.
  template <typename T>
  Statement& bind(int index, const std::optional<T>& value) {
    return value ? bind(index, *value) : bind(index, nullptr);
  }
  // Binds the arguments to parameters 1..N in order.
  template <typename... Args>
  Statement& bind_all(const Args&... args) {
    int index = 0;
    (bind(++index, args), ...);
    return *this;
  }

  // Advances to the next row: true when a row is available, false when the statement is done.
  bool step();
  // Runs a statement that must not return rows (INSERT/UPDATE/DELETE/DDL) to completion.
  void run();
  void reset() noexcept;

  int column_count() const;
  std::string column_name(int col) const;
  int column_type(
      int col) const;  // SQLITE_INTEGER, SQLITE_FLOAT, SQLITE_TEXT, SQLITE_BLOB, SQLITE_NULL
  bool column_is_null(int col) const { return column_type(col) == SQLITE_NULL; }
  std::int64_t column_int64(int col) const;
  double column_double(int col) const;
  std::string column_text(int col) const;
  std::vector<std::uint8_t> column_blob(int col) const;
  std::optional<std::int64_t> column_opt_int64(int col) const;
  std::optional<double> column_opt_double(int col) const;

  std::string_view sql() const;

 private:
  void check_bind(int rc, int index);
  [[noreturn]] void fail(int rc, std::string_view what) const;

  sqlite3_stmt* stmt_ = nullptr;
  sqlite3* db_ = nullptr;
  std::string db_path_;
};

// A borrowed cached statement; resets it on destruction.
class StatementLease {
 public:
  explicit StatementLease(Statement& statement) : statement_(&statement) {}
  StatementLease(const StatementLease&) = delete;
  StatementLease& operator=(const StatementLease&) = delete;
  ~StatementLease() { statement_->reset(); }
  Statement* operator->() const { return statement_; }
  Statement& operator*() const { return *statement_; }

 private:
  Statement* statement_;
};

class Database {
 public:
  // Opens (creating if absent) the database at `path`. Throws SqliteError on failure.
  explicit Database(const std::string& path,
                    int flags = SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX);
  Database(Database&& other) noexcept;
  Database& operator=(Database&& other) noexcept;
  Database(const Database&) = delete;
  Database& operator=(const Database&) = delete;
  ~Database();

  // Runs one or more statements that return no rows of interest.
  void exec(std::string_view sql);
  // Prepares a fresh statement (for one-off or dynamic SQL).
  Statement prepare(std::string_view sql) const;
  // Returns the statement for `sql`, preparing it on first use.
  StatementLease cached(std::string_view sql);

  // Runs a single-value query (typically a PRAGMA) and returns the first column of the first
  // row, or std::nullopt when there is no row.
  std::optional<std::int64_t> query_int64(std::string_view sql);
  std::optional<std::string> query_text(std::string_view sql);

  std::int64_t last_insert_rowid() const;
  int changes() const;
  const std::string& path() const { return path_; }
  sqlite3* handle() const { return db_; }

 private:
  void close() noexcept;

  sqlite3* db_ = nullptr;
  std::string path_;
  std::map<std::string, Statement, std::less<>> cache_;
};

class Transaction {
 public:
  explicit Transaction(Database& db);
  Transaction(const Transaction&) = delete;
  Transaction& operator=(const Transaction&) = delete;
  ~Transaction();
  void commit();

 private:
  Database& db_;
  bool done_ = false;
};

}  // namespace fleetgw::storage
