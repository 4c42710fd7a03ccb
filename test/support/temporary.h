// Test support: paths under gtest's temporary directory that carry the process id, so that test binaries
// run side by side (ctest -j, or two checkouts' suites on one machine) never write the same file.
#pragma once

#include <unistd.h>

#include <string>

#include <gtest/gtest.h>

namespace lidar_deskew::test {

/// TempDir()/<prefix>_<pid>_<name>.
inline std::string temporary(const std::string& prefix, const std::string& name) {
  return ::testing::TempDir() + "/" + prefix + "_" + std::to_string(::getpid()) + "_" + name;
}

}  // namespace lidar_deskew::test
