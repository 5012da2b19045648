// The ROS side of bag/: images to gray, rectification from CameraInfo, the
// stereo pair from two CameraInfo, /tf_static chains, topic choice and the
// --bag-topics YAML. (Whole bags written by the official libraries are read in
// tests/rosbag.)
#include "bag/bag_topics.hpp"
#include "bag/ros_images.hpp"
#include "bag/tf_tree.hpp"
#include "temp_dir.hpp"

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include <fstream>

namespace locaid::bag {
namespace {

using test_support::ScopedTempDir;

template <typename F>
std::string ErrorOf(F&& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

ros::CameraInfo Info(double tx, std::vector<double> d = {}, std::string model = "plumb_bob") {
  ros::CameraInfo c;
  c.header.frame_id = "cam";
  c.width = 64;
  c.height = 48;
  c.distortion_model = std::move(model);
  c.d = std::move(d);
  c.k = {50, 0, 32, 0, 50, 24, 0, 0, 1};
  c.r = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  c.p = {50, 0, 32, tx, 0, 50, 24, 0, 0, 0, 1, 0};
  return c;
}

TEST(RosImages, EveryRawEncodingBecomesTheSameGray) {
  std::string mono(64 * 48, '\0');
  for (size_t i = 0; i < mono.size(); ++i) mono[i] = static_cast<char>(i % 251);
  ros::Image img{{}, 48, 64, "mono8", false, 64, mono};
  const cv::Mat gray = ToGray(img);
  ASSERT_EQ(gray.type(), CV_8UC1);
  // mono16 big-endian: the high byte first; scaled by 1/256.
  std::string m16;
  for (char c : mono) m16 += std::string{c, '\x7f'};
  img = {{}, 48, 64, "mono16", true, 128, m16};
  EXPECT_EQ(cv::norm(ToGray(img), gray, cv::NORM_INF), 0);
  // rgb8 with padded rows (step > 3 * width): grey pixels stay their value.
  std::string rgb;
  for (int y = 0; y < 48; ++y) {
    for (int x = 0; x < 64; ++x) rgb += std::string(3, mono[static_cast<size_t>(64 * y + x)]);
    rgb += std::string(8, '\x55');
  }
  for (const std::string enc : {"rgb8", "bgr8"}) {
    img = {{}, 48, 64, enc, false, 64 * 3 + 8, rgb};
    EXPECT_LE(cv::norm(ToGray(img), gray, cv::NORM_INF), 1) << enc;
  }
  EXPECT_EQ(ToGray(ros::Image{{}, 48, 64, "bayer_rggb8", false, 64, mono}).size(), gray.size());
}

TEST(RosImages, BadImagesAreRefusedWithTheReason) {
  const std::string data(100, '\0');
  EXPECT_NE(ErrorOf([&] { ToGray(ros::Image{{}, 10, 10, "yuv422", false, 20, data}); }).find("'yuv422' not supported"),
            std::string::npos);
  EXPECT_NE(ErrorOf([&] { ToGray(ros::Image{{}, 10, 10, "mono8", false, 5, data}); }).find("step 5"),
            std::string::npos);
  EXPECT_NE(ErrorOf([&] { ToGray(ros::Image{{}, 20, 10, "mono8", false, 10, data}); }).find("100 bytes of data"),
            std::string::npos);
  EXPECT_NE(ErrorOf([&] { ToGray(ros::CompressedImage{{}, "png", data}); }).find("does not decode"),
            std::string::npos);
  EXPECT_NE(ErrorOf([&] { ToGray(ros::CompressedImage{{}, "tiff", data}); }).find("'tiff' not supported"),
            std::string::npos);
}

TEST(RosImages, PngAndJpegDecode) {
  cv::Mat img(48, 64, CV_8UC1);
  cv::randu(img, 0, 255);
  for (const std::string ext : {".png", ".jpg"}) {
    std::vector<uchar> bytes;
    cv::imencode(ext, img, bytes);
    const std::string s(bytes.begin(), bytes.end());
    const cv::Mat back = ToGray(ros::CompressedImage{{}, ext == ".png" ? "mono8; png compressed " : "jpeg", s});
    ASSERT_EQ(back.size(), img.size());
    if (ext == ".png") {
      EXPECT_EQ(cv::norm(back, img, cv::NORM_INF), 0);  // lossless
    }
  }
}

TEST(Rectifier, RectifiedInputPassesThroughAndRawIsRemapped) {
  const Rectifier already(Info(0));
  EXPECT_TRUE(already.passthrough());
  const Rectifier raw(Info(0, {-0.3, 0.1, 0, 0, 0}));
  EXPECT_FALSE(raw.passthrough());
  cv::Mat img(48, 64, CV_8UC1, cv::Scalar(200));
  EXPECT_EQ(raw.Rectify(img).size(), img.size());
  EXPECT_NE(ErrorOf([&] { raw.Rectify(cv::Mat(10, 10, CV_8UC1)); }).find("disagrees with its camera_info"),
            std::string::npos);
  // A crop gives exactly that part of the full rectified image.
  cv::Mat texture(48, 64, CV_8UC1);
  cv::randu(texture, 0, 255);
  const cv::Mat full = Rectifier(Info(0, {0.3, 0.1, 0, 0, 0})).Rectify(texture);
  Rectifier cropped(Info(0, {0.3, 0.1, 0, 0, 0}));  // corners map outside the raw image
  const cv::Rect region = cropped.valid_region();
  ASSERT_LT(region.area(), 64 * 48);
  cropped.Crop(region);
  EXPECT_EQ(cv::norm(cropped.Rectify(texture), full(region), cv::NORM_INF), 0);
  EXPECT_NE(ErrorOf([&] { cropped.Crop(cv::Rect(0, 0, 64, 48)); }).find("not inside"), std::string::npos);
  EXPECT_FALSE(Rectifier(Info(0, {0.1, 0.01, 0, 0}, "equidistant")).passthrough());
  EXPECT_FALSE(Rectifier(Info(0, {0.1, 0.01, 0, 0, 0, 0, 0, 0}, "rational_polynomial")).passthrough());
}

TEST(Rectifier, CameraInfoThatCannotRectifyIsRefused) {
  ros::CameraInfo zero;
  zero.width = 64;
  zero.height = 48;
  EXPECT_NE(ErrorOf([&] { Rectifier{zero}; }).find("uncalibrated"), std::string::npos);
  EXPECT_NE(ErrorOf([&] { Rectifier{Info(0, {0.1}, "fisheye_x")}; }).find("'fisheye_x' not supported"),
            std::string::npos);
  EXPECT_NE(ErrorOf([&] { Rectifier{Info(0, {0.1, 0.2}, "equidistant")}; }).find("needs 4"), std::string::npos);
  auto binned = Info(0);
  binned.binning_x = 2;
  EXPECT_NE(ErrorOf([&] { Rectifier{binned}; }).find("binning"), std::string::npos);
}

TEST(StereoFromCameraInfo, BaselineFromTheRightP) {
  const StereoCamera cam = StereoFromCameraInfo(Info(0), Info(-50 * 0.54));
  EXPECT_NEAR(cam.baseline_m, 0.54, 1e-12);
  EXPECT_EQ(cam.width, 64);
  EXPECT_NE(ErrorOf([] { StereoFromCameraInfo(Info(-27), Info(0)); }).find("no positive baseline"), std::string::npos);
  auto other = Info(-27);
  other.p[2] = 40;
  EXPECT_NE(ErrorOf([&] { StereoFromCameraInfo(Info(0), other); }).find("not a rectified stereo pair"),
            std::string::npos);
}

TEST(TfTree, ChainsInEitherDirection) {
  ros::TransformStamped a, b;
  a.header.frame_id = "base_link";
  a.child_frame_id = "imu";
  a.T_parent_child.translation() = Eigen::Vector3d(1, 0, 0);
  b.header.frame_id = "base_link";
  b.child_frame_id = "cam";
  b.T_parent_child = Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitZ()) * Eigen::Translation3d(0, 2, 0);
  const auto T_imu_cam = FindTransform({a, b}, "imu", "cam");
  ASSERT_TRUE(T_imu_cam);
  EXPECT_TRUE(T_imu_cam->isApprox(a.T_parent_child.inverse() * b.T_parent_child));
  EXPECT_TRUE(FindTransform({a, b}, "cam", "cam")->isApprox(Eigen::Isometry3d::Identity()));
  EXPECT_FALSE(FindTransform({a}, "imu", "cam"));
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
