// Topic choice in a bag's inventory (by type, left and right from the right
// camera's P[3]) and the --bag-topics YAML. (Whole bags written by the
// official libraries are read in tests/rosbag.)
#include "bag/bag_topics.hpp"
#include "error_of.hpp"
#include "temp_dir.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace locaid::bag {
namespace {

using test_support::ScopedTempDir;

template <typename F>
std::string ErrorOf(F&& f) {
  return test_support::ErrorOf<std::exception>(std::forward<F>(f));
}

// A camera_info whose P[3] (= -fx * baseline) makes it a left (0) or right
// (negative) camera: all topic choice reads of it.
ros::CameraInfo Info(double tx) {
  ros::CameraInfo c;
  c.p[3] = tx;
  return c;
}

BagInventory Inventory(std::vector<std::pair<std::string, std::string_view>> topics) {
  BagInventory inv;
  inv.complete = true;
  for (const auto& [name, type] : topics) {
    TopicSummary& s = inv.topics[name];
    s.topic = name;
    s.type = std::string(type);
    s.count = 10;
    if (type == ros::kCameraInfo) s.camera_info = Info(name.find("right") != std::string::npos ? -27 : 0);
  }
  return inv;
}

TEST(ChooseTopics, ByTypeWithLeftAndRightFromP) {
  const auto inv = Inventory({{"/s/right/camera_info", ros::kCameraInfo}, {"/s/right/image_raw", ros::kImage},
                              {"/s/right/image_raw/compressed", ros::kCompressedImage},
                              {"/s/left/camera_info", ros::kCameraInfo}, {"/s/left/image_raw", ros::kImage},
                              {"/imu", ros::kImu}, {"/fix", ros::kNavSatFix}});
  const BagTopics t = ChooseTopics(inv);
  EXPECT_EQ(t.left_image, "/s/left/image_raw");  // raw over compressed
  EXPECT_EQ(t.right_info, "/s/right/camera_info");
  EXPECT_EQ(t.imu, "/imu");
  EXPECT_EQ(t.gps, "/fix");
  EXPECT_EQ(t.speed, "");
  BagTopics off;
  off.gps = "none";
  EXPECT_EQ(ChooseTopics(inv, off).gps, "");
}

TEST(ChooseTopics, AmbiguityAndWrongTypesAreExplained) {
  auto inv = Inventory({{"/l/camera_info", ros::kCameraInfo}, {"/l/image_raw", ros::kImage},
                        {"/r/camera_info", ros::kCameraInfo}, {"/r/image_raw", ros::kImage}, {"/imu/a", ros::kImu},
                        {"/imu/b", ros::kImu}});
  inv.topics["/r/camera_info"].camera_info = Info(-27);
  EXPECT_NE(ErrorOf([&] { ChooseTopics(inv); }).find("several sensor_msgs/msg/Imu topics (/imu/a, /imu/b)"),
            std::string::npos);
  BagTopics named;
  named.imu = "/imu/b";
  EXPECT_EQ(ChooseTopics(inv, named).imu, "/imu/b");
  named.gps = "/l/image_raw";
  EXPECT_NE(ErrorOf([&] { ChooseTopics(inv, named); }).find("gps: topic /l/image_raw has type"), std::string::npos);
  named.gps = "/nowhere";
  EXPECT_NE(ErrorOf([&] { ChooseTopics(inv, named); }).find("not in the bag"), std::string::npos);
  const auto mono = Inventory({{"/l/camera_info", ros::kCameraInfo}, {"/l/image_raw", ros::kImage}});
  EXPECT_NE(ErrorOf([&] { ChooseTopics(mono); }).find("need a stereo pair"), std::string::npos);
}

TEST(LoadBagTopics, KeysAreCheckedAndNamed) {
  ScopedTempDir dir("bag_topics");
  const auto write = [&](const std::string& text) {
    std::ofstream(dir.path() / "t.yaml") << text;
    return dir.path() / "t.yaml";
  };
  const BagTopics t = LoadBagTopics(write("left_image: /a\nimu: none\n"));
  EXPECT_EQ(t.left_image, "/a");
  EXPECT_EQ(t.imu, "none");
  EXPECT_NE(ErrorOf([&] { LoadBagTopics(write("lefft: /a\n")); }).find("unknown key 'lefft'"), std::string::npos);
  EXPECT_NE(ErrorOf([&] { LoadBagTopics(write("imu: [1, 2]\n")); }).find("imu must be a topic name"),
            std::string::npos);
  EXPECT_NE(ErrorOf([&] { LoadBagTopics(write("[1, 2]\n")); }).find("expected a map"), std::string::npos);
}

}  // namespace
}  // namespace locaid::bag
