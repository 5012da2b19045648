// The ROS 2 bag tests' reader: js/read_ros2_bag.mjs (installed into the
// build tree by js/setup.sh, the McapJsReaderSetup CTest fixture), run with
// node. A test that needs it derives from Ros2BagReaderTest: it skips when
// node is missing (fails when CI is set: needs_tool.hpp).
#pragma once

#include "foxglove/bridge_support.hpp"

#include <gtest/gtest.h>

namespace locaid::output::testing {

inline const std::filesystem::path kRos2BagJsDir = LOCAID_MCAP_JS_DIR;

// read_ros2_bag.mjs [--messages] FILE.
inline foxglove::testing::NodeRun ReadRos2Bag(const std::filesystem::path& file, bool messages = false) {
  std::vector<std::string> args;
  if (messages) args.push_back("--messages");
  args.push_back(file.string());
  return foxglove::testing::RunNode(kRos2BagJsDir / "read_ros2_bag.mjs", args);
}

class Ros2BagReaderTest : public ::testing::Test {
 protected:
  void SetUp() override {
    LOCAID_NEEDS_TOOL(foxglove::testing::HaveNode(),
                      "node is not installed; the ROS 2 bag reader (@foxglove/rosmsg2-serialization) needs it");
    ASSERT_TRUE(std::filesystem::exists(kRos2BagJsDir / "node_modules/@foxglove/rosmsg2-serialization"))
        << "run tests/record/js/setup.sh " << kRos2BagJsDir << " (the McapJsReaderSetup CTest fixture does)";
  }
  const test_support::ScopedTempDir dir_{"ros2_bag"};
};

}  // namespace locaid::output::testing
