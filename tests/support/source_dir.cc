#include "tests/support/source_dir.h"

namespace fleetgw::testing {

std::filesystem::path source_dir() {
  // Defined for this file only: one object differs between checkouts, not every test's.
  return FLEETGW_SUPPORT_SOURCE_DIR;
}

}  // namespace fleetgw::testing
