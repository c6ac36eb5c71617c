// Test support: a fleetgw store read with SQLite itself, not through the Store, so a test checks
// what is on disk independently of the code under test.
//
// Contract:
//  * SqliteReader opens `db_path` read-only (ok() is false when it cannot: a missing file is not
//    created); every query on a reader that is not ok, or whose SQL fails, returns its "nothing"
//    value (no row, "", `otherwise`) and leaves the reason in error(). No test assertions here:
//    it also polls a store another process is still creating. Safe while a `fleetgw run`
//    writes the store (WAL readers never block the writer). One reader per thread.
//  * query_text() opens, reads the first column of the first row as text ("" for none or NULL)
//    and closes; query_number() is that value as a number, NaN when it is "" or not wholly a
//    number (a test's isnan check or comparison then fails, naming the value);
//    first_row_number() reads `column` of the row with the lowest id in `table`.
#pragma once

#include <sqlite3.h>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace fleetgw::testing {

class SqliteReader {
 public:
  explicit SqliteReader(const std::filesystem::path& db_path) {
    if (sqlite3_open_v2(db_path.c_str(), &db_, SQLITE_OPEN_READONLY, nullptr) != SQLITE_OK) {
      error_ = "cannot open " + db_path.string() + ": " + sqlite3_errmsg(db_);
      sqlite3_close(db_);
      db_ = nullptr;
    }
  }
  ~SqliteReader() { sqlite3_close(db_); }
  SqliteReader(const SqliteReader&) = delete;
  SqliteReader& operator=(const SqliteReader&) = delete;

  bool ok() const { return db_ != nullptr; }
  const std::string& error() const { return error_; }

  // Calls `row` with the statement positioned on each row of `sql`; false when the SQL cannot
  // be run.
  bool each(const std::string& sql, const std::function<void(sqlite3_stmt*)>& row) {
    if (db_ == nullptr) return false;
    sqlite3_stmt* st = nullptr;
    if (sqlite3_prepare_v2(db_, sql.c_str(), -1, &st, nullptr) != SQLITE_OK) {
      error_ = sql + ": " + sqlite3_errmsg(db_);
      sqlite3_finalize(st);
      return false;
    }
    while (sqlite3_step(st) == SQLITE_ROW) row(st);
    sqlite3_finalize(st);
    return true;
  }
  // The first column of every row, as integers.
  std::vector<std::int64_t> column(const std::string& sql) {
    std::vector<std::int64_t> out;
    each(sql, [&](sqlite3_stmt* st) { out.push_back(sqlite3_column_int64(st, 0)); });
    return out;
  }
  // The first column of the first row as text; "" for none or NULL.
  std::string text(const std::string& sql) {
    std::string out;
    bool first = true;
    each(sql, [&](sqlite3_stmt* st) {
      if (first && sqlite3_column_text(st, 0) != nullptr) {
        out = reinterpret_cast<const char*>(sqlite3_column_text(st, 0));
      }
      first = false;
    });
    return out;
  }
  // The first column of the first row as an integer; `otherwise` when there is none.
  std::int64_t scalar(const std::string& sql, std::int64_t otherwise = -1) {
    const auto c = column(sql);
    return c.empty() ? otherwise : c.front();
  }
  // Every row as its columns joined by `separator`, NULL as `null`.
  std::vector<std::string> rows(const std::string& sql, const std::string& separator = "|",
                                const std::string& null = "-") {
    std::vector<std::string> out;
    each(sql, [&](sqlite3_stmt* st) {
      std::string row;
      for (int i = 0; i < sqlite3_column_count(st); ++i) {
        if (i > 0) row += separator;
        const auto* t = sqlite3_column_text(st, i);
        row += t != nullptr ? reinterpret_cast<const char*>(t) : null;
      }
      out.push_back(std::move(row));
    });
    return out;
  }

 private:
  sqlite3* db_ = nullptr;
  std::string error_;
};

inline std::string query_text(const std::filesystem::path& db_path, const std::string& sql) {
  return SqliteReader(db_path).text(sql);
}

inline double query_number(const std::filesystem::path& db_path, const std::string& sql) {
  const std::string v = query_text(db_path, sql);
  char* end = nullptr;
  const double d = std::strtod(v.c_str(), &end);
  return v.empty() || *end != '\0' ? std::nan("") : d;
}

inline double first_row_number(const std::filesystem::path& db_path, const std::string& table,
                               const std::string& column) {
  return query_number(db_path, "SELECT " + column + " FROM " + table + " ORDER BY id LIMIT 1");
}

}  // namespace fleetgw::testing
