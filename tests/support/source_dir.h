// Test support: the source tree, for the files tests read from it (config/, scenarios, docs/).
//
// Contract: source_dir() is the CMake project's source directory, absolute, compiled into this
// library (one translation unit), so it holds whatever ctest's working directory is and however
// the build names its files: __FILE__ is no way to find it, as it is relative when ccache runs
// with CCACHE_BASEDIR set (and so are some IDE builds).
#pragma once

#include <filesystem>

namespace fleetgw::testing {

std::filesystem::path source_dir();

}  // namespace fleetgw::testing
