// A thin RAII layer over libpq for the web server, and a small connection pool: every request
// handler thread borrows a connection for the length of its request.
//
// Contract:
//  * PgConnection owns a PGconn. Its constructor throws PgError with the server's message when
//    the connection cannot be made; the conninfo (it may carry a password) never appears in an
//    error message or a log line.
//  * query() runs one statement with text parameters ($1, $2, ...; std::nullopt is NULL) and
//    returns its rows, or throws PgError (message, SQLSTATE; `what` names the statement's
//    purpose, never its text). Values are never spliced into SQL text.
//  * PgPool hands out at most `size` connections (lease()), opened on first use and reopened
//    when broken; lease() waits up to `wait` for a free one, then throws PgError("busy").
//    Thread-safe. A Lease returns its connection on destruction (a broken one is dropped).
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

namespace fleetgw::web {

class PgError : public std::runtime_error {
 public:
  PgError(const std::string& message, std::string sqlstate)
      : std::runtime_error(message), sqlstate_(std::move(sqlstate)) {}
  const std::string& sqlstate() const { return sqlstate_; }

 private:
  std::string sqlstate_;
};

class PgResult {
 public:
  struct Deleter {
    void operator()(PGresult* r) const { PQclear(r); }
  };
  explicit PgResult(std::unique_ptr<PGresult, Deleter> r) : r_(std::move(r)) {}
  int rows() const { return PQntuples(r_.get()); }
  int cols() const { return PQnfields(r_.get()); }
  bool null(int row, int col) const { return PQgetisnull(r_.get(), row, col) != 0; }
  std::string text(int row, int col) const {
    return {PQgetvalue(r_.get(), row, col),
            static_cast<std::size_t>(PQgetlength(r_.get(), row, col))};
  }
  // The column as an integer; nullopt when NULL. Throws PgError when it is not one.
  std::optional<std::int64_t> int64(int row, int col) const;
  bool boolean(int row, int col) const { return !null(row, col) && text(row, col) == "t"; }
  std::int64_t affected() const;

 private:
  std::unique_ptr<PGresult, Deleter> r_;
};

using PgParam = std::optional<std::string>;

class PgConnection {
 public:
  explicit PgConnection(const std::string& conninfo);
  PgConnection(const PgConnection&) = delete;
  PgConnection& operator=(const PgConnection&) = delete;

  PgResult query(std::string_view sql, std::span<const PgParam> params, std::string_view what);
  PgResult exec(std::string_view sql, std::string_view what) { return query(sql, {}, what); }
  bool ok() const { return PQstatus(conn_.get()) == CONNECTION_OK; }

 private:
  struct Deleter {
    void operator()(PGconn* c) const { PQfinish(c); }
  };
  std::unique_ptr<PGconn, Deleter> conn_;
};

// BEGIN on construction, ROLLBACK on destruction unless commit() ran.
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

}  // namespace fleetgw::web
