#include "gateway/status/status_server.h"

#include <sys/stat.h>

#include <asio/write.hpp>
#include <memory>
#include <system_error>

namespace fleetgw::status {
namespace {

std::system_error path_error(std::error_code ec, const std::filesystem::path& p, const char* what) {
  return std::system_error(ec, "status socket " + p.string() + ": " + what);
}

}  // namespace

StatusServer::StatusServer(asio::io_context& io, std::filesystem::path socket_path,
                           Provider provider)
    : path_(std::move(socket_path)), provider_(std::move(provider)), acceptor_(io), retry_(io) {
  std::error_code ec;
  if (path_.has_parent_path()) {
    std::filesystem::create_directories(path_.parent_path(), ec);
    if (ec) throw path_error(ec, path_, "cannot create the directory");
  }
  // A crashed run leaves its socket file behind and bind() would fail with EADDRINUSE. Only a
  // socket is removed: a mistyped path must not delete a regular file.
  const auto st = std::filesystem::symlink_status(path_, ec);
  if (!ec && std::filesystem::is_socket(st)) std::filesystem::remove(path_, ec);

  const asio::local::stream_protocol::endpoint ep(path_.string());
  acceptor_.open(ep.protocol(), ec);
  if (!ec) acceptor_.bind(ep, ec);
  if (ec) throw path_error(ec, path_, "cannot bind");
  if (::chmod(path_.c_str(), 0660) != 0) {
    throw path_error(std::error_code(errno, std::generic_category()), path_, "cannot chmod");
  }
  acceptor_.listen(asio::socket_base::max_listen_connections, ec);
  if (ec) throw path_error(ec, path_, "cannot listen");
  accept();
}

StatusServer::~StatusServer() {
  stop();
}

void StatusServer::stop() {
  if (stopped_) return;
  stopped_ = true;
  std::error_code ec;
  acceptor_.close(ec);
  retry_.cancel();
  std::filesystem::remove(path_, ec);
}

void StatusServer::accept() {
  acceptor_.async_accept([this](const std::error_code& ec,
                                asio::local::stream_protocol::socket socket) {
    // Cancelled by stop()/destruction: `this` may be gone.
    if (ec == asio::error::operation_aborted) return;
    if (!ec) {
      std::string body;
      try {
        // Firmware and model strings come off the CAN bus: replace invalid UTF-8 rather than fail.
        body = provider_().dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
      } catch (const std::exception& e) {
        body = nlohmann::json{{"error", e.what()}}.dump();
      }
      body += '\n';
      ++served_;
      // The buffer and the socket live in the completion handler until the write ends.
      auto conn = std::make_shared<std::pair<asio::local::stream_protocol::socket, std::string>>(
          std::move(socket), std::move(body));
      asio::async_write(conn->first, asio::buffer(conn->second),
                        [conn](const std::error_code&, std::size_t) {
                          std::error_code ignored;
                          conn->first.shutdown(asio::socket_base::shutdown_both, ignored);
                        });
    }
    if (stopped_) return;
    if (!ec) {
      accept();
      return;
    }
    // Out of descriptors or similar: retrying at once would spin the loop, so pause briefly.
    retry_.expires_after(std::chrono::milliseconds(100));
    retry_.async_wait([this](const std::error_code& wait_ec) {
      if (!wait_ec && !stopped_) accept();
    });
  });
}

}  // namespace fleetgw::status
