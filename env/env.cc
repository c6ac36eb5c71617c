#include "env/env.h"

#include <pthread.h>

#include <fcntl.h>
#include <unistd.h>
#include <cstdio>
#include <fstream>
#include <string>

namespace fleetgw {
namespace {

class SystemEnv final : public Env {
 public:
  Micros wall_now() const override {
    return std::chrono::duration_cast<Micros>(std::chrono::system_clock::now().time_since_epoch());
  }
  SteadyTime steady_now() const override { return std::chrono::steady_clock::now(); }
};

}  // namespace

Env& Env::system() {
  // Stateless: one instance for the program is not mutable state.
  static SystemEnv env;
  return env;
}

std::jthread Env::start_thread(std::string_view name, std::function<void(std::stop_token)> fn) {
  std::jthread t(std::move(fn));
  // Linux keeps 15 characters and a NUL; the name shows in top -H and in core dumps.
  const std::string n(name.substr(0, 15));
  pthread_setname_np(t.native_handle(), n.c_str());
  return t;
}

std::error_code Env::write_file_atomic(const std::filesystem::path& path, std::string_view bytes) {
  const std::filesystem::path tmp = path.string() + ".tmp";
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return {errno, std::generic_category()};
  std::size_t off = 0;
  while (off < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + off, bytes.size() - off);
    if (n < 0) {
      if (errno == EINTR) continue;
      const std::error_code ec(errno, std::generic_category());
      ::close(fd);
      ::unlink(tmp.c_str());
      return ec;
    }
    off += static_cast<std::size_t>(n);
  }
  if (::fsync(fd) != 0) {
    const std::error_code ec(errno, std::generic_category());
    ::close(fd);
    ::unlink(tmp.c_str());
    return ec;
  }
  ::close(fd);
  return rename_file(tmp, path);
}

std::error_code Env::rename_file(const std::filesystem::path& from,
                                 const std::filesystem::path& to) {
  std::error_code ec;
  std::filesystem::rename(from, to, ec);
  return ec;
}

std::error_code Env::free_space(const std::filesystem::path& path, std::uint64_t& bytes) {
  std::error_code ec;
  const auto info = std::filesystem::space(path, ec);
  if (!ec) bytes = info.available;
  return ec;
}

ManualEnv::ManualEnv(Micros wall) : wall_us_(wall.count()) {}

void ManualEnv::advance(std::chrono::nanoseconds d) {
  if (d.count() <= 0) return;
  steady_ns_.fetch_add(d.count());
  wall_us_.fetch_add(std::chrono::duration_cast<Micros>(d).count());
}

}  // namespace fleetgw
