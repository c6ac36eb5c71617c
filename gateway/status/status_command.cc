#include "gateway/status/status_command.h"

#include <array>
#include <asio/connect.hpp>
#include <asio/io_context.hpp>
#include <asio/local/stream_protocol.hpp>
#include <asio/read.hpp>
#include <functional>

namespace fleetgw::status {
namespace {

struct Fetch {
  std::string body;
  std::error_code error;
  bool done = false;
};

// Connect and read to EOF, all bounded by `timeout`: a service whose loop hangs still accepts
// connections (the kernel does) but never answers, and the technician must learn that rather
// than wait forever.
Fetch fetch(const std::string& path, std::chrono::milliseconds timeout) {
  asio::io_context io;
  asio::local::stream_protocol::socket socket(io);
  Fetch f;
  std::array<char, 4096> chunk{};
  std::function<void()> read_more = [&] {
    socket.async_read_some(asio::buffer(chunk), [&](const std::error_code& ec, std::size_t n) {
      f.body.append(chunk.data(), n);
      if (ec == asio::error::eof) {
        f.done = true;
      } else if (ec) {
        f.error = ec;
        f.done = true;
      } else {
        read_more();
      }
    });
  };
  socket.async_connect(asio::local::stream_protocol::endpoint(path),
                       [&](const std::error_code& ec) {
                         if (ec) {
                           f.error = ec;
                           f.done = true;
                         } else {
                           read_more();
                         }
                       });
  io.run_for(timeout);
  return f;
}

}  // namespace

int run_status_command(const StatusCommandOptions& options, std::ostream& out, std::ostream& err) {
  const Fetch f = fetch(options.socket_path, options.timeout);
  if (!f.done) {
    err << "fleetgw status: no answer from " << options.socket_path << " within "
        << options.timeout.count() << " ms (the service may be hung)\n";
    return kStatusUnreachable;
  }
  if (f.error) {
    err << "fleetgw status: cannot reach the service at " << options.socket_path << ": "
        << f.error.message() << " (is fleetgw running? systemctl status fleetgw)\n";
    return kStatusUnreachable;
  }
  const auto doc = nlohmann::json::parse(f.body, nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded() || !doc.is_object()) {
    err << "fleetgw status: the service answered something that is not a JSON object\n";
    return kStatusUnreachable;
  }
  if (const auto e = doc.find("error"); e != doc.end()) {
    err << "fleetgw status: the service could not build its status: " << e->dump() << '\n';
    return kStatusUnreachable;
  }
  const auto findings = evaluate(doc, options.rules);
  if (options.json) {
    out << doc.dump(2) << '\n';
    // The raw document stays untouched for scripts; the reasons for exit 1 go to `err`.
    for (const auto& f : findings) err << "ATTENTION: " << f.detail << '\n';
  } else {
    out << format_summary(doc, findings);
  }
  return findings.empty() ? kStatusOk : kStatusAttention;
}

int run_status_command(const std::string& socket_path, bool json_output, std::ostream& out) {
  StatusCommandOptions o;
  o.socket_path = socket_path;
  o.json = json_output;
  return run_status_command(o, out, std::cerr);
}

}  // namespace fleetgw::status
