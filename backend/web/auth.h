// Operators, logins, sessions and the audit trail, all in PostgreSQL (console_schema.h), so any
// number of `fleetgw serve` instances behind a load balancer share them.
//
// Contract:
//  * Roles are ordered: viewer < operator < admin; a role allows what the ones below it do.
//  * add_operator() creates the account or replaces its role and password (Argon2id, secrets.h)
//    and ends its sessions; remove_operator() deletes it with its sessions. Names are 1-64
//    printable ASCII characters without spaces; passwords at least 8 bytes, at most 1024.
//    Both throw std::invalid_argument naming what is wrong.
//  * login() checks the throttle first: after `free` failures of an account (3) or of a client
//    address (20) within the forgetting window (15 min), each further attempt must come at
//    least 2^(failures - free) s (capped at 5 min) after the last failure, or it is refused as
//    Throttled with the seconds to wait, without looking at the password (which also keeps
//    Argon2's cost away from an attacker). A wrong password or an unknown or disabled account
//    (indistinguishable, and as slow: a decoy hash is verified) is BadCredentials and counts a
//    failure for both the account and the address; success clears the account's failures and
//    opens a session: a random 256-bit id (only its SHA-256 is stored) and a CSRF token.
//  * session() returns the session of a cookie value if it exists, is neither past its
//    absolute lifetime (12 h) nor idle longer than 2 h, and its operator is not disabled; the
//    role is read on every call, so a role change counts at once.
//  * audit() appends one row (who, from where, what, on what, result, detail) and never throws
//    (a failure is logged): a refused request is still answered.
#pragma once

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "backend/common/pg.h"

namespace fleetgw::web {

enum class Role { Viewer = 0, Operator = 1, Admin = 2 };
std::optional<Role> parse_role(std::string_view s);
std::string_view role_name(Role r);

struct Session {
  std::string operator_name;
  Role role = Role::Viewer;
  std::string csrf_token;
  // An API token's (api_tokens.h), sent as `Authorization: Bearer`: no cookie, so no CSRF.
  bool bearer = false;
};

struct LoginOutcome {
  enum class Kind { Ok, BadCredentials, Throttled } kind = Kind::BadCredentials;
  std::string session_id;          // Ok: the cookie's value
  Session session;                 // Ok
  std::int64_t retry_after_s = 0;  // Throttled
};

struct AuthLimits {
  int account_free_failures = 3;
  int address_free_failures = 20;
  std::chrono::seconds max_delay{300};
  std::chrono::seconds forget_after{900};
  std::chrono::seconds session_lifetime{12 * 3600};
  std::chrono::seconds session_idle{2 * 3600};
};

class Auth {
 public:
  Auth(PgPool& pool, AuthLimits limits = {});

  void add_operator(std::string_view name, Role role, std::string_view password);
  bool remove_operator(std::string_view name);

  LoginOutcome login(std::string_view name, std::string_view password, std::string_view address);
  std::optional<Session> session(std::string_view session_id);
  void logout(std::string_view session_id);

  void audit(std::optional<std::string_view> operator_name, std::string_view address,
             std::string_view action, std::string_view target, std::string_view result,
             std::string_view detail = "");

  const AuthLimits& limits() const { return limits_; }

 private:
  // Seconds the key must still wait (0: may try now).
  std::int64_t throttle_wait(PgConnection& c, const std::string& key, int free_failures,
                             std::int64_t now_us);
  void count_failure(PgConnection& c, const std::string& key, std::int64_t now_us);

  PgPool& pool_;
  AuthLimits limits_;
  std::string decoy_hash_;
};

std::int64_t now_us();

}  // namespace fleetgw::web
