// Test support: one value read from a fleetgw store with SQLite itself, not through the Store, so
// a test checks what is on disk independently of the code under test.
//
// Contract: query_text() opens `db_path` read-only, runs `sql` and returns the first column of
// the first row as text; "" when the file cannot be opened, the SQL fails, or there is no row or
// the value is NULL. Safe to call while a `fleetgw run` writes the store (WAL readers never
// block the writer).
#pragma once

#include <sqlite3.h>

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

}  // namespace fleetgw::testing
