// Test support: a private temporary directory (mkdtemp under $TMPDIR), removed recursively when
// the object is destroyed. The one TempDir of the test suites.
//
// Contract: the directory exists and is empty after construction (or std::system_error names
// the path that could not be made); the destructor never throws; moving transfers ownership.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>

namespace fleetgw::testing {

class TempDir {
 public:
  explicit TempDir(std::string_view prefix = "fleetgw-test");
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  TempDir(TempDir&& other) noexcept;
  TempDir& operator=(TempDir&& other) noexcept;

  const std::filesystem::path& path() const { return path_; }
  // path() / name (nothing is created).
  std::filesystem::path file(std::string_view name) const { return path_ / name; }
  std::filesystem::path operator/(std::string_view name) const { return path_ / name; }

 private:
  std::filesystem::path path_;
};

}  // namespace fleetgw::testing
