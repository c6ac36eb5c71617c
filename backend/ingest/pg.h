// A thin RAII layer over libpq (the PostgreSQL C client), just what the ingest needs: one
// connection, parameterised statements, transactions.
//
// Contract:
//  * PgConnection owns a PGconn (PQfinish on destruction). connect() throws PgError naming the
//    server's message when the connection cannot be made; the conninfo string (it may carry a
//    password) is never part of an error message or a log line.
//  * exec()/exec_params() return a PgResult (PQclear on destruction) or throw PgError with the
//    server's message and the SQLSTATE; `what` names the statement's purpose, not its text.
//  * Parameters are text (PostgreSQL converts them to the column type); std::nullopt is SQL NULL.
//    Nothing is ever spliced into SQL text: every value goes as a parameter.
//  * ok() is false once the connection is broken (the caller reconnects).
//  * Not thread-safe: one connection per thread.
#pragma once

#include <libpq-fe.h>

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>

namespace fleetgw::ingest {

class PgError : public std::runtime_error {
 public:
  PgError(const std::string& message, std::string sqlstate)
      : std::runtime_error(message), sqlstate_(std::move(sqlstate)) {}
  const std::string& sqlstate() const { return sqlstate_; }

 private:
  std::string sqlstate_;
};

struct PgResultDeleter {
  void operator()(PGresult* r) const { PQclear(r); }
};
using PgResultPtr = std::unique_ptr<PGresult, PgResultDeleter>;

// A query result; rows and columns are 0-based.
class PgResult {
 public:
  explicit PgResult(PgResultPtr r) : r_(std::move(r)) {}
  int rows() const { return PQntuples(r_.get()); }
  bool is_null(int row, int col) const { return PQgetisnull(r_.get(), row, col) != 0; }
  std::string_view text(int row, int col) const {
    return {PQgetvalue(r_.get(), row, col),
            static_cast<std::size_t>(PQgetlength(r_.get(), row, col))};
  }
  std::int64_t int64(int row, int col) const;
  // Rows an INSERT/UPDATE/DELETE touched (0 for other statements).
  std::int64_t affected() const;

 private:
  PgResultPtr r_;
};

using PgParam = std::optional<std::string>;

class PgConnection {
 public:
  // Connects (blocking). Throws PgError.
  explicit PgConnection(const std::string& conninfo);
  PgConnection(const PgConnection&) = delete;
  PgConnection& operator=(const PgConnection&) = delete;

  PgResult exec(std::string_view sql, std::string_view what);
  PgResult exec_params(std::string_view sql, std::span<const PgParam> params,
                       std::string_view what);
  // A named server-side prepared statement (parsed and planned once per connection), and its
  // execution with text parameters; throw PgError like exec().
  void prepare(const std::string& name, std::string_view sql, int params, std::string_view what);
  PgResult exec_prepared(const std::string& name, std::span<const PgParam> params,
                         std::string_view what);
  bool ok() const { return PQstatus(conn_.get()) == CONNECTION_OK; }
  PGconn* raw() { return conn_.get(); }

 private:
  struct ConnDeleter {
    void operator()(PGconn* c) const { PQfinish(c); }
  };
  std::unique_ptr<PGconn, ConnDeleter> conn_;
};

// BEGIN on construction, ROLLBACK on destruction unless commit() succeeded.
class PgTransaction {
 public:
  explicit PgTransaction(PgConnection& c);
  ~PgTransaction();
  PgTransaction(const PgTransaction&) = delete;
  PgTransaction& operator=(const PgTransaction&) = delete;
  void commit();

 private:
  PgConnection& c_;
  bool done_ = false;
};

}  // namespace fleetgw::ingest
