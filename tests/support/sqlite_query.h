// Test support: one value read from a fleetgw store with SQLite itself, not through the Store, so
// a test checks what is on disk independently of the code under test.
//
// Contract: query_text() opens `db_path` read-only, runs `sql` and returns the first column of
// the first row as text; "" when the file cannot be opened, the SQL fails, or there is no row or
// the value is NULL. Safe to call while a `fleetgw run` writes the store (WAL readers never
// block the writer).
// query_number() is that value as a number, NaN when it is "" or not wholly a number (a test's
// isnan check or comparison then fails, naming the value). first_row_number() reads `column` of
// the row with the lowest id in `table` (e.g. the first ride).
#pragma once

#include <sqlite3.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <string>

namespace fleetgw::testing {

inline std::string query_text(const std::filesystem::path& db_path, const std::string& sql) {
  sqlite3* db = nullptr;
  std::string out;
  if (sqlite3_open_v2(db_path.c_str(), &db, SQLITE_OPEN_READONLY, nullptr) == SQLITE_OK) {
    sqlite3_stmt* st = nullptr;
    if (sqlite3_prepare_v2(db, sql.c_str(), -1, &st, nullptr) == SQLITE_OK &&
        sqlite3_step(st) == SQLITE_ROW && sqlite3_column_text(st, 0) != nullptr) {
      out = reinterpret_cast<const char*>(sqlite3_column_text(st, 0));
    }
    sqlite3_finalize(st);
  }
  sqlite3_close(db);
  return out;
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
