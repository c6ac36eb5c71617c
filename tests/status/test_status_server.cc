// The status socket end to end: a StatusServer on a real io_context, `fleetgw status` against it.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <asio/post.hpp>
#include <fstream>
#include <future>
#include <sstream>
#include <thread>

#include "gateway/status/status_command.h"
#include "gateway/status/status_server.h"
#include "status_doc.h"
#include "status_test_util.h"

namespace fleetgw::status {
namespace {

using namespace std::chrono_literals;
using nlohmann::json;
using test::healthy_status;
using test::TempDir;

// A service stand-in: an io_context on its own thread with a StatusServer whose document the
// test can change (on the loop's thread, like the runtime's state).
class Service {
 public:
  Service(std::filesystem::path path, std::function<json()> provider) {
    server_ = std::make_unique<StatusServer>(io_, std::move(path), std::move(provider));
    thread_ = std::thread([this] { io_.run(); });
  }
  ~Service() {
    asio::post(io_, [this] { server_->stop(); });
    thread_.join();
    server_.reset();
  }
  asio::io_context& io() { return io_; }
  uint64_t served() {
    std::promise<uint64_t> p;
    asio::post(io_, [&] { p.set_value(server_->served()); });
    return p.get_future().get();
  }

 private:
  asio::io_context io_;
  std::unique_ptr<StatusServer> server_;
  std::thread thread_;
};

struct Result {
  int code;
  std::string out, err;
};

Result query_status(const std::filesystem::path& path, bool json_out = false,
                    std::chrono::milliseconds timeout = 5s) {
  StatusCommandOptions o;
  o.socket_path = path.string();
  o.json = json_out;
  o.timeout = timeout;
  std::ostringstream out, err;
  const int code = run_status_command(o, out, err);
  return {code, out.str(), err.str()};
}

TEST(StatusServer, HealthyServiceExitsZeroWithSummary) {
  TempDir dir;
  const auto sock = dir.path() / "run" / "status.sock";  // parent created by the server
  Service svc(sock, [] { return healthy_status(); });
  struct stat st {};
  ASSERT_EQ(::stat(sock.c_str(), &st), 0);
  EXPECT_TRUE(S_ISSOCK(st.st_mode));
  EXPECT_EQ(st.st_mode & 0777, 0660u);

  const Result r = query_status(sock);
  EXPECT_EQ(r.code, kStatusOk) << r.err;
  EXPECT_NE(r.out.find("vehicle bike-0042"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("\nOK\n"), std::string::npos) << r.out;
  EXPECT_EQ(r.err, "");
  EXPECT_EQ(svc.served(), 1u);
}

TEST(StatusServer, JsonOutputIsTheServiceDocument) {
  TempDir dir;
  const auto sock = dir.path() / "status.sock";
  Service svc(sock, [] { return healthy_status(); });
  const Result r = query_status(sock, true);
  EXPECT_EQ(r.code, kStatusOk);
  EXPECT_EQ(json::parse(r.out), healthy_status());
}

TEST(StatusServer, BrokerUnreachableExitsOne) {
  TempDir dir;
  const auto sock = dir.path() / "status.sock";
  Service svc(sock, [] {
    json d = healthy_status();
    d["broker"]["connected"] = false;
    d["broker"]["last_error"] = "TCP/TLS connect failure";
    return d;
  });
  Result r = query_status(sock);
  EXPECT_EQ(r.code, kStatusAttention);
  EXPECT_NE(r.out.find("ATTENTION: broker"), std::string::npos) << r.out;
  r = query_status(sock, true);
  EXPECT_EQ(r.code, kStatusAttention);
  EXPECT_TRUE(json::parse(r.out).is_object());
  EXPECT_NE(r.err.find("ATTENTION: broker"), std::string::npos) << r.err;
}

TEST(StatusServer, NoServiceExitsThree) {
  TempDir dir;
  const Result r = query_status(dir.path() / "absent.sock");
  EXPECT_EQ(r.code, kStatusUnreachable);
  EXPECT_NE(r.err.find("cannot reach the service"), std::string::npos) << r.err;
  EXPECT_EQ(r.out, "");
}

TEST(StatusServer, HungLoopTimesOutWithThree) {
  TempDir dir;
  const auto sock = dir.path() / "status.sock";
  Service svc(sock, [] { return healthy_status(); });
  std::promise<void> release;
  auto released = release.get_future().share();
  asio::post(svc.io(), [released] { released.wait(); });  // the loop hangs
  // The client gives up by itself while the loop still hangs (the loop is released only after
  // the answer, or after 60 s, which only ends a client that would wait for ever).
  auto query = std::async(std::launch::async, [&] { return query_status(sock, false, 300ms); });
  const bool gave_up = query.wait_for(60s) == std::future_status::ready;
  release.set_value();
  ASSERT_TRUE(gave_up) << "the client waited for a hung loop";
  const Result r = query.get();
  EXPECT_EQ(r.code, kStatusUnreachable);
  EXPECT_NE(r.err.find("may be hung"), std::string::npos) << r.err;
}

TEST(StatusServer, ProviderFailureIsReportedAndTheServerKeepsServing) {
  TempDir dir;
  const auto sock = dir.path() / "status.sock";
  bool fail = true;  // read and written on the loop thread only
  Service svc(sock, [&fail] {
    if (fail) {
      fail = false;
      throw std::runtime_error("store closed");
    }
    return healthy_status();
  });
  Result r = query_status(sock);
  EXPECT_EQ(r.code, kStatusUnreachable);
  EXPECT_NE(r.err.find("store closed"), std::string::npos) << r.err;
  r = query_status(sock);
  EXPECT_EQ(r.code, kStatusOk) << r.err;
}

TEST(StatusServer, InvalidUtf8FromTheBusDoesNotBreakTheAnswer) {
  TempDir dir;
  const auto sock = dir.path() / "status.sock";
  Service svc(sock, [] {
    json d = healthy_status();
    d["nodes"][0]["firmware"] = std::string("MC\xff\xfe");
    return d;
  });
  const Result r = query_status(sock);
  EXPECT_EQ(r.code, kStatusOk) << r.err;
  EXPECT_NE(r.out.find("firmware MC"), std::string::npos);
}

TEST(StatusServer, ManySequentialClients) {
  TempDir dir;
  const auto sock = dir.path() / "status.sock";
  Service svc(sock, [] { return healthy_status(); });
  for (int i = 0; i < 50; ++i) ASSERT_EQ(query_status(sock).code, kStatusOk) << i;
  EXPECT_EQ(svc.served(), 50u);
}

TEST(StatusServer, ReplacesAStaleSocketButNeverARegularFile) {
  TempDir dir;
  const auto sock = dir.path() / "status.sock";
  {
    // A crashed run: the socket file stays behind.
    asio::io_context io;
    asio::local::stream_protocol::acceptor stale(io, sock.string());
  }
  ASSERT_TRUE(std::filesystem::is_socket(sock));
  {
    Service svc(sock, [] { return healthy_status(); });
    EXPECT_EQ(query_status(sock).code, kStatusOk);
  }
  EXPECT_FALSE(std::filesystem::exists(sock)) << "removed on shutdown";

  const auto file = dir.path() / "precious.txt";
  std::ofstream(file) << "keep me";
  asio::io_context io;
  EXPECT_THROW(StatusServer(io, file, [] { return json::object(); }), std::system_error);
  EXPECT_TRUE(std::filesystem::is_regular_file(file));
}

}  // namespace
}  // namespace fleetgw::status
