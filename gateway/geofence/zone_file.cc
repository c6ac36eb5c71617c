#include "gateway/geofence/zone_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace fleetgw::geofence {
namespace {

std::string system_error(std::string_view what, const std::filesystem::path& path) {
  return std::string(what) + " " + path.string() + ": " + std::strerror(errno);
}

// A file descriptor closed on every path out.
class ZoneFd {
 public:
  explicit ZoneFd(int fd) : fd_(fd) {}
  ~ZoneFd() {
    if (fd_ >= 0) ::close(fd_);
  }
  ZoneFd(const ZoneFd&) = delete;
  ZoneFd& operator=(const ZoneFd&) = delete;
  int get() const { return fd_; }
  bool close_checked() {
    const int fd = fd_;
    fd_ = -1;
    return ::close(fd) == 0;
  }

 private:
  int fd_;
};

}  // namespace

std::optional<std::string> read_zone_file(const std::filesystem::path& path, std::string& error,
                                          std::size_t max_bytes) {
  error.clear();
  ZoneFd fd(::open(path.c_str(), O_RDONLY | O_CLOEXEC));
  if (fd.get() < 0) {
    if (errno != ENOENT) error = system_error("cannot open zone bundle", path);
    return std::nullopt;
  }
  struct stat st {};
  if (::fstat(fd.get(), &st) != 0) {
    error = system_error("cannot stat zone bundle", path);
    return std::nullopt;
  }
  if (!S_ISREG(st.st_mode)) {
    error = "zone bundle " + path.string() + " is not a regular file";
    return std::nullopt;
  }
  if (static_cast<std::size_t>(st.st_size) > max_bytes) {
    error = "zone bundle " + path.string() + " has " + std::to_string(st.st_size) +
            " bytes, more than " + std::to_string(max_bytes);
    return std::nullopt;
  }
  std::string data(static_cast<std::size_t>(st.st_size), '\0');
  std::size_t done = 0;
  while (done < data.size()) {
    const ssize_t n = ::read(fd.get(), data.data() + done, data.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      error = system_error("cannot read zone bundle", path);
      return std::nullopt;
    }
    if (n == 0) break;  // shrank while reading: what is there is judged by the authority
    done += static_cast<std::size_t>(n);
  }
  data.resize(done);
  return data;
}

bool write_zone_file(const std::filesystem::path& path, std::string_view payload,
                     std::string& error) {
  error.clear();
  const std::filesystem::path dir = path.has_parent_path() ? path.parent_path() : ".";
  const std::filesystem::path tmp =
      dir / ("." + path.filename().string() + ".tmp" + std::to_string(::getpid()));
  ::unlink(tmp.c_str());  // a leftover of a crash of this very process id
  {
    ZoneFd fd(::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644));
    if (fd.get() < 0) {
      error = system_error("cannot create", tmp);
      return false;
    }
    std::size_t done = 0;
    while (done < payload.size()) {
      const ssize_t n = ::write(fd.get(), payload.data() + done, payload.size() - done);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) {
        error = system_error("cannot write", tmp);
        ::unlink(tmp.c_str());
        return false;
      }
      done += static_cast<std::size_t>(n);
    }
    if (::fsync(fd.get()) != 0 || !fd.close_checked()) {
      error = system_error("cannot sync", tmp);
      ::unlink(tmp.c_str());
      return false;
    }
  }
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    error = system_error("cannot rename " + tmp.string() + " to", path);
    ::unlink(tmp.c_str());
    return false;
  }
  // The rename itself must be durable before the bundle is reported as stored.
  ZoneFd dfd(::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC));
  if (dfd.get() < 0 || ::fsync(dfd.get()) != 0) {
    error = system_error("cannot sync directory", dir);
    return false;
  }
  return true;
}

std::optional<BundleVerdict> restore_zones(ZoneAuthority& authority,
                                           const std::filesystem::path& path, std::string& error) {
  auto payload = read_zone_file(path, error);
  if (!payload) return std::nullopt;
  return authority.offer(*payload);
}

}  // namespace fleetgw::geofence
