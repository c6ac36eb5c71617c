// libpq wrappers and pool (pg.h).
#include "backend/common/pg.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <charconv>
#include <optional>
#include <vector>

namespace fleetgw {
namespace {

std::string trimmed(const char* s) {
  std::string out = s != nullptr ? s : "";
  while (!out.empty() && (out.back() == '\n' || out.back() == ' ')) out.pop_back();
  return out;
}

PgResult checked(PGresult* raw, PGconn* conn, std::string_view what) {
  PgResultPtr r(raw);
  const ExecStatusType st = r ? PQresultStatus(r.get()) : PGRES_FATAL_ERROR;
  if (st == PGRES_COMMAND_OK || st == PGRES_TUPLES_OK) return PgResult(std::move(r));
  std::string state;
  std::string message;
  if (r) {
    const char* s = PQresultErrorField(r.get(), PG_DIAG_SQLSTATE);
    state = s != nullptr ? s : "";
    message = trimmed(PQresultErrorMessage(r.get()));
  }
  if (message.empty()) message = trimmed(PQerrorMessage(conn));
  throw PgError(std::string(what) + ": " + message + (state.empty() ? "" : " [" + state + "]"),
                state);
}

}  // namespace

std::int64_t PgResult::int64(int row, int col) const {
  const std::string_view t = text(row, col);
  std::int64_t v = 0;
  const auto [p, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
  if (ec != std::errc() || p != t.data() + t.size()) {
    throw PgError("not an integer in column " + std::to_string(col) + ": " + std::string(t), "");
  }
  return v;
}

std::int64_t PgResult::affected() const {
  const char* n = PQcmdTuples(r_.get());
  if (n == nullptr || *n == '\0') return 0;
  std::int64_t v = 0;
  std::from_chars(n, n + std::char_traits<char>::length(n), v);
  return v;
}

PgConnection::PgConnection(const std::string& conninfo) : conn_(PQconnectdb(conninfo.c_str())) {
  if (!conn_) throw PgError("PostgreSQL: out of memory", "");
  if (PQstatus(conn_.get()) != CONNECTION_OK) {
    // libpq's message names host, port and the server's reason, never the password.
    throw PgError("cannot connect to PostgreSQL: " + trimmed(PQerrorMessage(conn_.get())), "08000");
  }
  // Server notices (e.g. "relation already exists, skipping") are not errors: debug level,
  // instead of libpq's default of printing them on stderr.
  PQsetNoticeProcessor(
      conn_.get(),
      [](void*, const char* message) { spdlog::debug("PostgreSQL: {}", trimmed(message)); },
      nullptr);
  // Row values are untrusted text from vehicles: make sure the session encoding is UTF-8
  // whatever the server's default.
  PQsetClientEncoding(conn_.get(), "UTF8");
}

PgResult PgConnection::exec(std::string_view sql, std::string_view what) {
  const std::string s(sql);
  return checked(PQexec(conn_.get(), s.c_str()), conn_.get(), what);
}

PgResult PgConnection::exec_params(std::string_view sql, std::span<const PgParam> params,
                                   std::string_view what) {
  const std::string s(sql);
  std::vector<const char*> values;
  values.reserve(params.size());
  for (const PgParam& p : params) values.push_back(p ? p->c_str() : nullptr);
  return checked(PQexecParams(conn_.get(), s.c_str(), static_cast<int>(values.size()), nullptr,
                              values.data(), nullptr, nullptr, 0),
                 conn_.get(), what);
}

std::int64_t PgConnection::copy_in(std::string_view copy_sql, std::string_view data,
                                   std::string_view what) {
  const std::string s(copy_sql);
  PgResultPtr start(PQexec(conn_.get(), s.c_str()));
  if (!start || PQresultStatus(start.get()) != PGRES_COPY_IN)
    checked(start.release(), conn_.get(), what);
  // Sent in pieces of 1 MiB (libpq buffers each; a blocking connection waits while it drains).
  constexpr std::size_t kPiece = 1024 * 1024;
  bool sent = true;
  for (std::size_t at = 0; at < data.size() && sent; at += kPiece) {
    const std::size_t n = std::min(kPiece, data.size() - at);
    sent = PQputCopyData(conn_.get(), data.data() + at, static_cast<int>(n)) == 1;
  }
  PQputCopyEnd(conn_.get(), sent ? nullptr : "ingest: sending the COPY data failed");
  // The COPY's own result, then the end of the command (NULL).
  PgResultPtr end(PQgetResult(conn_.get()));
  while (PGresult* extra = PQgetResult(conn_.get())) PQclear(extra);
  return checked(end.release(), conn_.get(), what).affected();
}

void PgConnection::prepare(const std::string& name, std::string_view sql, int params,
                           std::string_view what) {
  const std::string s(sql);
  checked(PQprepare(conn_.get(), name.c_str(), s.c_str(), params, nullptr), conn_.get(), what);
}

PgResult PgConnection::exec_prepared(const std::string& name, std::span<const PgParam> params,
                                     std::string_view what) {
  std::vector<const char*> values;
  values.reserve(params.size());
  for (const PgParam& p : params) values.push_back(p ? p->c_str() : nullptr);
  return checked(PQexecPrepared(conn_.get(), name.c_str(), static_cast<int>(values.size()),
                                values.data(), nullptr, nullptr, 0),
                 conn_.get(), what);
}

PgTransaction::PgTransaction(PgConnection& c) : c_(c) {
  c_.exec("BEGIN", "begin transaction");
}

PgTransaction::~PgTransaction() {
  if (done_) return;
  // A broken connection cannot roll back; the server aborts the transaction when it notices.
  if (c_.ok()) PQclear(PQexec(c_.raw(), "ROLLBACK"));
}

void PgTransaction::commit() {
  c_.exec("COMMIT", "commit");
  done_ = true;
}

PgPool::PgPool(std::string conninfo, std::size_t size, std::chrono::milliseconds wait)
    : conninfo_(std::move(conninfo)), size_(size == 0 ? 1 : size), wait_(wait) {}

PgPool::Lease PgPool::lease() {
  std::unique_lock lock(mu_);
  if (!cv_.wait_for(lock, wait_, [&] { return !idle_.empty() || open_ < size_; })) {
    throw PgError("busy: every database connection is in use", "53300");
  }
  if (!idle_.empty()) {
    std::unique_ptr<PgConnection> c = std::move(idle_.back());
    idle_.pop_back();
    return Lease(*this, std::move(c));
  }
  ++open_;
  lock.unlock();
  // Connecting happens outside the lock: it can take a while and other threads may return
  // connections meanwhile.
  try {
    return Lease(*this, std::make_unique<PgConnection>(conninfo_));
  } catch (...) {
    const std::lock_guard relock(mu_);
    --open_;
    cv_.notify_one();
    throw;
  }
}

void PgPool::give_back(std::unique_ptr<PgConnection> c) {
  const std::lock_guard lock(mu_);
  if (c && c->ok()) {
    idle_.push_back(std::move(c));
  } else {
    --open_;  // broken: the next lease opens a new one
  }
  cv_.notify_one();
}

PgPool::Lease::~Lease() {
  if (c_) pool_->give_back(std::move(c_));
}

}  // namespace fleetgw
