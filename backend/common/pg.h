// A thin RAII layer over libpq (the PostgreSQL C client) shared by the backend's two programs,
// the ingest (backend/ingest) and the web server (backend/web), so that both talk to the
// database the same way: one connection, parameterised statements, transactions, and the web
// server's small connection pool.
//
// Contract:
//  * PgConnection owns a PGconn (PQfinish on destruction). Its constructor throws PgError
//    (SQLSTATE 08000) naming the server's message when the connection cannot be made; the
//    conninfo string (it may carry a password) is never part of an error message or a log line.
//    The session encoding is UTF-8 (row values are untrusted text); server notices go to the
//    debug log, not stderr.
//  * exec()/exec_params()/query() return a PgResult (PQclear on destruction) or throw PgError
//    with the server's message and the SQLSTATE; `what` names the statement's purpose, not its
//    text.
//  * Parameters are text (PostgreSQL converts them to the column type); std::nullopt is SQL NULL.
//    Nothing is ever spliced into SQL text: every value goes as a parameter.
//  * ok() is false once the connection is broken (the caller reconnects).
//  * PgConnection is not thread-safe: one connection per thread. PgPool hands out at most `size`
//    connections (lease()), opened on first use and reopened when broken; lease() waits up to
//    `wait` for a free one, then throws PgError (SQLSTATE 53300, "busy"). PgPool is
//    thread-safe; a Lease returns its connection on destruction (a broken one is dropped).
#pragma once

#include <libpq-fe.h>

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

// In fleetgw itself, not a sub-namespace, so that code in fleetgw::ingest and fleetgw::web
// names these types unqualified.
namespace fleetgw {

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
  int cols() const { return PQnfields(r_.get()); }
  bool is_null(int row, int col) const { return PQgetisnull(r_.get(), row, col) != 0; }
  std::string_view text(int row, int col) const {
    return {PQgetvalue(r_.get(), row, col),
            static_cast<std::size_t>(PQgetlength(r_.get(), row, col))};
  }
  // A copy of text(), for callers that keep the value past the result's life.
  std::string str(int row, int col) const { return std::string(text(row, col)); }
  // The column as an integer; throws PgError when it is not one (NULL is not one).
  std::int64_t int64(int row, int col) const;
  // The same for a nullable column: nullopt when NULL.
  std::optional<std::int64_t> int64_or_null(int row, int col) const {
    if (is_null(row, col)) return std::nullopt;
    return int64(row, col);
  }
  // A boolean column: true only for a non-NULL 't'.
  bool boolean(int row, int col) const { return !is_null(row, col) && text(row, col) == "t"; }
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
  // exec() without parameters (it may run several statements, e.g. a schema version), else
  // exec_params().
  PgResult query(std::string_view sql, std::span<const PgParam> params, std::string_view what) {
    return params.empty() ? exec(sql, what) : exec_params(sql, params, what);
  }
  // A named server-side prepared statement (parsed and planned once per connection), and its
  // execution with text parameters; throw PgError like exec().
  void prepare(const std::string& name, std::string_view sql, int params, std::string_view what);
  PgResult exec_prepared(const std::string& name, std::span<const PgParam> params,
                         std::string_view what);
  // `COPY ... FROM STDIN` (text format) with `data` as its whole input; returns the rows
  // copied. Throws PgError like exec() (the server's refusal of a row ends the COPY).
  std::int64_t copy_in(std::string_view copy_sql, std::string_view data, std::string_view what);
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

class PgPool {
 public:
  PgPool(std::string conninfo, std::size_t size,
         std::chrono::milliseconds wait = std::chrono::seconds(5));
  PgPool(const PgPool&) = delete;
  PgPool& operator=(const PgPool&) = delete;

  class Lease {
   public:
    Lease(PgPool& pool, std::unique_ptr<PgConnection> c) : pool_(&pool), c_(std::move(c)) {}
    Lease(Lease&& o) noexcept : pool_(o.pool_), c_(std::move(o.c_)) {}
    Lease& operator=(Lease&&) = delete;
    ~Lease();
    PgConnection& operator*() { return *c_; }
    PgConnection* operator->() { return c_.get(); }

   private:
    PgPool* pool_;
    std::unique_ptr<PgConnection> c_;
  };

  Lease lease();
  const std::string& conninfo() const { return conninfo_; }

 private:
  void give_back(std::unique_ptr<PgConnection> c);

  std::string conninfo_;
  std::size_t size_;
  std::chrono::milliseconds wait_;
  std::mutex mu_;
  std::condition_variable cv_;
  std::vector<std::unique_ptr<PgConnection>> idle_;
  std::size_t open_ = 0;  // leased + idle
};

}  // namespace fleetgw
