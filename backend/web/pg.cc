// libpq wrapper and pool (pg.h).
#include "backend/web/pg.h"

#include <charconv>

namespace fleetgw::web {
namespace {

std::string trimmed(const char* s) {
  std::string m = s == nullptr ? "" : s;
  while (!m.empty() && (m.back() == '\n' || m.back() == ' ')) m.pop_back();
  return m;
}

}  // namespace

std::optional<std::int64_t> PgResult::int64(int row, int col) const {
  if (null(row, col)) return std::nullopt;
  const std::string t = text(row, col);
  std::int64_t v = 0;
  const auto [p, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
  if (ec != std::errc() || p != t.data() + t.size()) {
    throw PgError("column " + std::to_string(col) + " is not an integer", "");
  }
  return v;
}

std::int64_t PgResult::affected() const {
  const char* n = PQcmdTuples(r_.get());
  return n == nullptr || *n == '\0' ? 0 : std::stoll(n);
}

PgConnection::PgConnection(const std::string& conninfo) : conn_(PQconnectdb(conninfo.c_str())) {
  if (!conn_) throw PgError("PostgreSQL: out of memory", "");
  if (PQstatus(conn_.get()) != CONNECTION_OK) {
    throw PgError("cannot connect to PostgreSQL: " + trimmed(PQerrorMessage(conn_.get())), "08000");
  }
  // Server notices ("relation ... already exists, skipping") are not the operator's business:
  // libpq would print each on stderr.
  PQsetNoticeProcessor(
      conn_.get(), [](void*, const char*) {}, nullptr);
}

PgResult PgConnection::query(std::string_view sql, std::span<const PgParam> params,
                             std::string_view what) {
  std::vector<const char*> values;
  values.reserve(params.size());
  for (const PgParam& p : params) values.push_back(p ? p->c_str() : nullptr);
  const std::string text(sql);
  // Without parameters, PQexec: it runs several statements (the schema versions); with them,
  // PQexecParams, which keeps every value out of the SQL text.
  std::unique_ptr<PGresult, PgResult::Deleter> r(
      params.empty() ? PQexec(conn_.get(), text.c_str())
                     : PQexecParams(conn_.get(), text.c_str(), static_cast<int>(values.size()),
                                    nullptr, values.data(), nullptr, nullptr, 0));
  const ExecStatusType st = r ? PQresultStatus(r.get()) : PGRES_FATAL_ERROR;
  if (st != PGRES_COMMAND_OK && st != PGRES_TUPLES_OK) {
    const char* code = r ? PQresultErrorField(r.get(), PG_DIAG_SQLSTATE) : nullptr;
    throw PgError(std::string(what) + ": " + trimmed(PQerrorMessage(conn_.get())),
                  code == nullptr ? "" : code);
  }
  return PgResult(std::move(r));
}

PgTransaction::PgTransaction(PgConnection& c) : c_(c) {
  c_.exec("BEGIN", "begin");
}

PgTransaction::~PgTransaction() {
  if (done_ || !c_.ok()) return;
  try {
    c_.exec("ROLLBACK", "rollback");
  } catch (const PgError&) {
    // The connection is broken: the server rolls back on its own.
  }
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

}  // namespace fleetgw::web
