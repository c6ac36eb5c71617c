// API tokens (api_tokens.h).
#include "backend/web/api_tokens.h"

#include <stdexcept>

#include "backend/web/secrets.h"

namespace fleetgw::web {
namespace {

constexpr std::string_view kTokenPrefix = "fgw_";

void check_token_name(std::string_view name) {
  if (name.empty() || name.size() > 48) {
    throw std::invalid_argument("token name must be 1 to 48 characters");
  }
  for (const char ch : name) {
    if (ch <= ' ' || ch > '~') {
      throw std::invalid_argument("token name must be printable ASCII without spaces");
    }
  }
}

}  // namespace

CreatedToken create_api_token(PgConnection& c, std::string_view name, Role role,
                              std::string_view created_by) {
  check_token_name(name);
  CreatedToken out;
  out.token = std::string(kTokenPrefix) + random_token(32);
  const PgParam p[] = {std::string(name), sha256_hex(out.token), std::string(role_name(role)),
                       std::string(created_by), std::to_string(now_us())};
  const PgResult r = c.query(
      "INSERT INTO console_api_tokens (name, token_sha256, role, created_by, created_at_us) "
      "VALUES ($1, $2, $3, $4, $5::bigint) RETURNING id",
      p, "create API token");
  out.id = r.int64_or_null(0, 0).value_or(0);
  return out;
}

std::optional<Session> token_session(PgConnection& c, std::string_view token) {
  if (!token.starts_with(kTokenPrefix) || token.size() > 128) return std::nullopt;
  const std::int64_t t = now_us();
  const PgParam p[] = {sha256_hex(token)};
  const PgResult r = c.query(
      "SELECT id, name, role, last_used_us FROM console_api_tokens WHERE token_sha256 = $1 "
      "AND revoked_at_us IS NULL",
      p, "read API token");
  if (r.rows() != 1) return std::nullopt;
  const std::optional<Role> role = parse_role(r.str(0, 2));
  if (!role) return std::nullopt;
  if (t - r.int64_or_null(0, 3).value_or(0) > 60'000'000) {
    const PgParam u[] = {r.str(0, 0), std::to_string(t)};
    c.query("UPDATE console_api_tokens SET last_used_us = $2::bigint WHERE id = $1::bigint", u,
            "touch API token");
  }
  return Session{"token:" + r.str(0, 1), *role, "", true};
}

bool revoke_api_token(PgConnection& c, std::int64_t id, std::string_view by) {
  const PgParam p[] = {std::to_string(id), std::to_string(now_us()), std::string(by)};
  return c.query(
              "UPDATE console_api_tokens SET revoked_at_us = $2::bigint, revoked_by = $3 "
              "WHERE id = $1::bigint AND revoked_at_us IS NULL",
              p, "revoke API token")
             .affected() == 1;
}

nlohmann::json list_api_tokens(PgConnection& c) {
  const PgResult r = c.exec(
      "SELECT id, name, role, created_by, created_at_us, revoked_at_us, revoked_by, "
      "last_used_us FROM console_api_tokens ORDER BY id",
      "list API tokens");
  nlohmann::json out = nlohmann::json::array();
  for (int i = 0; i < r.rows(); ++i) {
    auto opt = [&](int col) {
      const auto v = r.int64_or_null(i, col);
      return v ? nlohmann::json(*v) : nlohmann::json(nullptr);
    };
    out.push_back(
        {{"id", r.int64_or_null(i, 0).value_or(0)},
         {"name", r.str(i, 1)},
         {"role", r.str(i, 2)},
         {"created_by", r.str(i, 3)},
         {"created_at_us", opt(4)},
         {"revoked_at_us", opt(5)},
         {"revoked_by", r.is_null(i, 6) ? nlohmann::json(nullptr) : nlohmann::json(r.str(i, 6))},
         {"last_used_us", opt(7)}});
  }
  return out;
}

}  // namespace fleetgw::web
