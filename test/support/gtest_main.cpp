// gtest's main() for the unit tests: upstream catkin (Noetic) provides gtest but no gtest_main target
// that every CMake version knows (test/CMakeLists.txt).
#include <gtest/gtest.h>

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
