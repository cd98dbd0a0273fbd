#pragma once
// Where tests find data, and the skip rule for the team's shared data.

#include <filesystem>
#include <string>

namespace s2m::test {

inline std::filesystem::path TestData(const std::string& relative) {
  return std::filesystem::path(S2M_TEST_DATA_DIR) / relative;
}

// ../shared/data beside the project; tests that need it call GTEST_SKIP() when this returns false.
inline bool HaveSharedData() {
  return std::filesystem::is_directory(S2M_SHARED_DATA_DIR);
}
inline std::filesystem::path SharedData(const std::string& relative) {
  return std::filesystem::path(S2M_SHARED_DATA_DIR) / relative;
}

}  // namespace s2m::test
