// A gtest assertion on messages: whether a text holds a part, printing both when not.
#pragma once

#include <gtest/gtest.h>

#include <string>

namespace lidar_deskew::test {

/// EXPECT_TRUE(holds(text, part)): passes when `part` occurs in `text`.
inline ::testing::AssertionResult holds(const std::string& text, const std::string& part) {
  if (text.find(part) != std::string::npos)
    return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "'" << text << "' does not hold '" << part << "'";
}

}  // namespace lidar_deskew::test
