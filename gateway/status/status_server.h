// The service's status socket: a local UNIX stream socket on the service's own asio io_context
// that answers every connection with one JSON document (status_report.h) and closes it.
//
// Contract:
//  * The document comes from the provider callback, called on the io_context's thread, so it may
//    read the runtime's state without locking. A provider that throws yields
//    {"error": "<what>"} instead of killing the service.
//  * Clients send nothing; the answer is the JSON text followed by "\n", then EOF.
//  * Construction creates the parent directory if needed, replaces a stale socket file left by a
//    crashed run (never any other kind of file), listens, and sets mode 0660 (owner and group,
//    i.e. the fleetgw user and technicians in its group). Errors throw std::system_error naming
//    the path. Destruction (or stop()) closes the listener and removes the socket file.
//  * Never blocks the loop: accepts and writes are asynchronous; a client that does not read
//    costs one small buffered write, not a stalled gateway.
#pragma once

#include <asio/io_context.hpp>
#include <asio/local/stream_protocol.hpp>
#include <asio/steady_timer.hpp>
#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>

namespace fleetgw::status {

inline constexpr const char* kDefaultStatusSocket = "/run/fleetgw/status.sock";

class StatusServer {
 public:
  using Provider = std::function<nlohmann::json()>;

  StatusServer(asio::io_context& io, std::filesystem::path socket_path, Provider provider);
  ~StatusServer();
  StatusServer(const StatusServer&) = delete;
  StatusServer& operator=(const StatusServer&) = delete;

  void stop();
  const std::filesystem::path& path() const { return path_; }
  uint64_t served() const { return served_; }

 private:
  void accept();
  std::filesystem::path path_;
  Provider provider_;
  asio::local::stream_protocol::acceptor acceptor_;
  asio::steady_timer retry_;
  uint64_t served_ = 0;
  bool stopped_ = false;
};

}  // namespace fleetgw::status
