// API tokens for machine clients (issue 28): created by an admin, shown once, stored as their
// SHA-256 only, sent as `Authorization: Bearer <token>`, each with a role, revocable.
//
// Contract:
//  * create_api_token() makes a token "fgw_" + 256 random bits (base64url) named `name` (1-48
//    printable ASCII characters without spaces; std::invalid_argument otherwise) and returns
//    its id and the token itself, which is nowhere else afterwards.
//  * token_session() is the session a token stands for (operator "token:<name>", its role,
//    bearer = true), nullopt for an unknown, revoked or malformed token. Its last use is
//    written at most once a minute.
//  * revoke_api_token() is false when the id is unknown or already revoked.
//  * list_api_tokens() never includes a token or its hash.
#pragma once

#include <nlohmann/json.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "backend/common/pg.h"
#include "backend/web/auth.h"

namespace fleetgw::web {

struct CreatedToken {
  std::int64_t id = 0;
  std::string token;
};

CreatedToken create_api_token(PgConnection& c, std::string_view name, Role role,
                              std::string_view created_by);
std::optional<Session> token_session(PgConnection& c, std::string_view token);
bool revoke_api_token(PgConnection& c, std::int64_t id, std::string_view by);
nlohmann::json list_api_tokens(PgConnection& c);

}  // namespace fleetgw::web
