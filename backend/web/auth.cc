// Operators, throttled logins, sessions, audit (auth.h).
#include "backend/web/auth.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <stdexcept>

#include "backend/web/secrets.h"

namespace fleetgw::web {

std::int64_t now_us() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

std::optional<Role> parse_role(std::string_view s) {
  if (s == "viewer") return Role::Viewer;
  if (s == "operator") return Role::Operator;
  if (s == "admin") return Role::Admin;
  return std::nullopt;
}

std::string_view role_name(Role r) {
  switch (r) {
    case Role::Viewer:
      return "viewer";
    case Role::Operator:
      return "operator";
    case Role::Admin:
      return "admin";
  }
  return "viewer";
}

namespace {

void check_name(std::string_view name) {
  if (name.empty() || name.size() > 64) {
    throw std::invalid_argument("operator name must be 1 to 64 characters");
  }
  for (const char ch : name) {
    if (ch <= ' ' || ch > '~') {
      throw std::invalid_argument(
          "operator name must be printable ASCII without spaces (got a byte 0x" +
          std::to_string(static_cast<unsigned char>(ch)) + ")");
    }
  }
}

std::string us(std::int64_t v) {
  return std::to_string(v);
}

// Audit text comes from requests: bytes outside printable ASCII are written as \xNN, so a row
// is always valid text and reads unambiguously.
std::string printable(std::string_view s, std::size_t max) {
  static constexpr char kHex[] = "0123456789abcdef";
  std::string out;
  for (const char ch : s.substr(0, max)) {
    const auto b = static_cast<unsigned char>(ch);
    if (b >= 0x20 && b < 0x7f && b != '\\') {
      out += ch;
    } else {
      out += "\\x";
      out += kHex[b >> 4];
      out += kHex[b & 15];
    }
  }
  return out;
}

}  // namespace

Auth::Auth(PgPool& pool, AuthLimits limits)
    : pool_(pool), limits_(limits), decoy_hash_(hash_password(random_token(16))) {}

void Auth::add_operator(std::string_view name, Role role, std::string_view password) {
  check_name(name);
  if (password.size() < 8) throw std::invalid_argument("password must be at least 8 bytes");
  if (password.size() > 1024) throw std::invalid_argument("password must be at most 1024 bytes");
  const std::string hash = hash_password(password);
  auto c = pool_.lease();
  PgTransaction tx(*c);
  const PgParam p[] = {std::string(name), std::string(role_name(role)), hash, us(now_us())};
  c->query(
      "INSERT INTO console_operators (name, role, password_hash, created_at_us) "
      "VALUES ($1, $2, $3, $4) ON CONFLICT (name) DO UPDATE SET role = EXCLUDED.role, "
      "password_hash = EXCLUDED.password_hash, disabled = false",
      p, "add operator");
  // A new password or role ends the sessions opened under the old ones.
  c->query("DELETE FROM console_sessions WHERE operator = $1", std::span(p, 1),
           "end operator sessions");
  tx.commit();
}

bool Auth::remove_operator(std::string_view name) {
  auto c = pool_.lease();
  const PgParam p[] = {std::string(name)};
  return c->query("DELETE FROM console_operators WHERE name = $1", p, "remove operator")
             .affected() > 0;
}

std::int64_t Auth::throttle_wait(PgConnection& c, const std::string& key, int free_failures,
                                 std::int64_t now) {
  const PgParam p[] = {key};
  const PgResult r =
      c.query("SELECT failures, last_failure_us FROM console_login_throttle WHERE key = $1", p,
              "read login throttle");
  if (r.rows() == 0) return 0;
  const std::int64_t failures = r.int64_or_null(0, 0).value_or(0);
  const std::int64_t last = r.int64_or_null(0, 1).value_or(0);
  const std::int64_t forget_us =
      std::chrono::duration_cast<std::chrono::microseconds>(limits_.forget_after).count();
  if (now - last > forget_us || failures < free_failures) return 0;
  const std::int64_t over = std::min<std::int64_t>(failures - free_failures, 20);
  const std::int64_t delay_s =
      std::min<std::int64_t>(std::int64_t{1} << over, limits_.max_delay.count());
  const std::int64_t ready = last + delay_s * 1'000'000;
  return now >= ready ? 0 : (ready - now + 999'999) / 1'000'000;
}

void Auth::count_failure(PgConnection& c, const std::string& key, std::int64_t now) {
  const std::int64_t forget_us =
      std::chrono::duration_cast<std::chrono::microseconds>(limits_.forget_after).count();
  const PgParam p[] = {key, us(now), us(now - forget_us)};
  c.query(
      "INSERT INTO console_login_throttle AS t (key, failures, last_failure_us) "
      "VALUES ($1, 1, $2) ON CONFLICT (key) DO UPDATE SET failures = CASE WHEN "
      "t.last_failure_us < $3::bigint THEN 1 ELSE t.failures + 1 END, last_failure_us = $2",
      p, "count login failure");
}

LoginOutcome Auth::login(std::string_view name, std::string_view password,
                         std::string_view address) {
  LoginOutcome out;
  const std::string account_key = "account:" + std::string(name.substr(0, 64));
  const std::string address_key = "address:" + std::string(address.substr(0, 64));
  std::string hash;
  std::optional<Role> role;
  {
    auto c = pool_.lease();
    const std::int64_t t = now_us();
    const std::int64_t wait =
        std::max(throttle_wait(*c, account_key, limits_.account_free_failures, t),
                 throttle_wait(*c, address_key, limits_.address_free_failures, t));
    if (wait > 0) {
      out.kind = LoginOutcome::Kind::Throttled;
      out.retry_after_s = wait;
      return out;
    }
    const PgParam p[] = {std::string(name)};
    const PgResult r = c->query(
        "SELECT password_hash, role FROM console_operators WHERE name = $1 AND NOT disabled", p,
        "read operator");
    if (r.rows() == 1) {
      hash = r.str(0, 0);
      role = parse_role(r.str(0, 1));
    }
  }
  // The hash is verified without holding a database connection: it takes ~0.1 s of CPU.
  const bool good = verify_password(hash.empty() ? decoy_hash_ : hash, password) && !hash.empty() &&
                    role.has_value();
  auto c = pool_.lease();
  const std::int64_t t = now_us();
  if (!good) {
    count_failure(*c, account_key, t);
    count_failure(*c, address_key, t);
    out.kind = LoginOutcome::Kind::BadCredentials;
    return out;
  }
  const PgParam clear[] = {account_key};
  c->query("DELETE FROM console_login_throttle WHERE key = $1", clear, "clear login throttle");
  out.kind = LoginOutcome::Kind::Ok;
  out.session_id = random_token(32);
  out.session = Session{std::string(name), *role, random_token(32)};
  const std::int64_t lifetime_us =
      std::chrono::duration_cast<std::chrono::microseconds>(limits_.session_lifetime).count();
  const PgParam s[] = {sha256_hex(out.session_id),
                       std::string(name),
                       out.session.csrf_token,
                       std::string(address.substr(0, 64)),
                       us(t),
                       us(t + lifetime_us)};
  c->query(
      "INSERT INTO console_sessions (id_sha256, operator, csrf_token, address, created_at_us, "
      "last_seen_us, expires_at_us) VALUES ($1, $2, $3, $4, $5, $5, $6)",
      s, "open session");
  return out;
}

std::optional<Session> Auth::session(std::string_view session_id) {
  if (session_id.empty() || session_id.size() > 128) return std::nullopt;
  auto c = pool_.lease();
  const std::int64_t t = now_us();
  const std::int64_t idle_us =
      std::chrono::duration_cast<std::chrono::microseconds>(limits_.session_idle).count();
  const std::string id_hash = sha256_hex(session_id);
  const PgParam p[] = {id_hash, us(t), us(t - idle_us)};
  const PgResult r = c->query(
      "SELECT s.operator, o.role, s.csrf_token, s.last_seen_us FROM console_sessions s "
      "JOIN console_operators o ON o.name = s.operator WHERE s.id_sha256 = $1 AND "
      "s.expires_at_us > $2::bigint AND s.last_seen_us > $3::bigint AND NOT o.disabled",
      p, "read session");
  if (r.rows() != 1) return std::nullopt;
  const std::optional<Role> role = parse_role(r.str(0, 1));
  if (!role) return std::nullopt;
  // The idle clock is written at most once a minute, not on every request.
  if (t - r.int64_or_null(0, 3).value_or(0) > 60'000'000) {
    const PgParam u[] = {id_hash, us(t)};
    c->query("UPDATE console_sessions SET last_seen_us = $2 WHERE id_sha256 = $1", u,
             "touch session");
  }
  return Session{r.str(0, 0), *role, r.str(0, 2)};
}

void Auth::logout(std::string_view session_id) {
  auto c = pool_.lease();
  const PgParam p[] = {sha256_hex(session_id)};
  c->query("DELETE FROM console_sessions WHERE id_sha256 = $1", p, "close session");
}

void Auth::audit(std::optional<std::string_view> operator_name, std::string_view address,
                 std::string_view action, std::string_view target, std::string_view result,
                 std::string_view detail) {
  try {
    auto c = pool_.lease();
    const PgParam p[] = {
        us(now_us()),
        operator_name ? PgParam(printable(*operator_name, 64)) : PgParam(std::nullopt),
        printable(address, 64),
        printable(action, 64),
        printable(target, 1024),
        printable(result, 64),
        printable(detail, 1024)};
    c->query(
        "INSERT INTO console_audit (at_us, operator, address, action, target, result, detail) "
        "VALUES ($1, $2, $3, $4, $5, $6, $7)",
        p, "audit");
  } catch (const std::exception& e) {
    spdlog::error("serve: audit row not written ({}): {} {} {}", e.what(), action, target, result);
  }
}

}  // namespace fleetgw::web
