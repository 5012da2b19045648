#include "kitti/pose_io.hpp"
#include "error_of.hpp"
#include "temp_dir.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <filesystem>
#include <fstream>
#include <functional>
#include <random>
#include <string>

namespace locaid::kitti {
namespace {

namespace fs = std::filesystem;

class PoseIoTest : public ::testing::Test {
 protected:
  fs::path Write(const std::string& name, const std::string& content) {
    fs::path p = dir_ / name;
    std::ofstream(p) << content;
    return p;
  }

  const test_support::ScopedTempDir dir_{"pose_io"};
};

// Random rigid transforms with a fixed seed (rotations cover all of SO(3)).
std::vector<Eigen::Isometry3d> RandomPoses(size_t n, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::uniform_real_distribution<double> uni(-1000.0, 1000.0);
  std::vector<Eigen::Isometry3d> poses;
  for (size_t i = 0; i < n; ++i) {
    Eigen::Quaterniond q(gauss(rng), gauss(rng), gauss(rng), gauss(rng));
    q.normalize();
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = q.toRotationMatrix();
    T.translation() = Eigen::Vector3d(uni(rng), uni(rng), uni(rng)) / 3.0;  // non-terminating decimals
    poses.push_back(T);
  }
  return poses;
}

std::string ErrorOf(const std::function<void()>& f) { return locaid::test_support::ErrorOf<Error>(f); }

const std::string kIdentityKitti = "1 0 0 0 0 1 0 0 0 0 1 0\n";

TEST_F(PoseIoTest, KittiRoundTripIsBitExact) {
  const auto poses = RandomPoses(50, 7);
  const fs::path p = dir_ / "poses.txt";
  WriteKittiPoses(p, poses);
  const auto back = ReadKittiPoses(p);
  ASSERT_EQ(back.size(), poses.size());
  for (size_t i = 0; i < poses.size(); ++i) {
    EXPECT_EQ(back[i].matrix(), poses[i].matrix()) << "pose " << i;
  }
}

TEST_F(PoseIoTest, TumRoundTripIsExactUpToQuaternionRounding) {
  // The quaternion is re-derived from the matrix, so allow a few ulps.
  constexpr double kRotationTol = 1e-14;
  const auto poses = RandomPoses(50, 11);
  std::vector<StampedPose> stamped;
  for (size_t i = 0; i < poses.size(); ++i) stamped.push_back({1317384506.0 + 0.1 * i / 3.0, poses[i]});
  const fs::path p = dir_ / "poses.tum";
  WriteTumPoses(p, stamped);
  const auto back = ReadTumPoses(p);
  ASSERT_EQ(back.size(), stamped.size());
  for (size_t i = 0; i < stamped.size(); ++i) {
    EXPECT_EQ(back[i].t_s, stamped[i].t_s);
    EXPECT_EQ(back[i].T_world_cam.translation(), stamped[i].T_world_cam.translation());
    EXPECT_LT((back[i].T_world_cam.linear() - stamped[i].T_world_cam.linear()).cwiseAbs().maxCoeff(),
              kRotationTol);
  }
}

TEST_F(PoseIoTest, WriteLeavesNoTemporaryFileAndReplacesTarget) {
  const fs::path p = Write("poses.txt", "old content that is not poses\n");
  WriteKittiPoses(p, RandomPoses(3, 1));
  EXPECT_EQ(ReadKittiPoses(p).size(), 3u);
  size_t files = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir_)) ++files;
  EXPECT_EQ(files, 1u);
}

TEST_F(PoseIoTest, WriteIntoMissingFolderThrowsNamingPath) {
  const fs::path p = dir_ / "no_such_dir" / "poses.txt";
  const std::string e = ErrorOf([&] { WriteKittiPoses(p, RandomPoses(1, 1)); });
  EXPECT_NE(e.find(p.string()), std::string::npos) << e;
  EXPECT_NE(e.find("cannot create"), std::string::npos) << e;
  const std::string e2 = ErrorOf([&] { WriteTumPoses(p, {}); });
  EXPECT_NE(e2.find(p.string()), std::string::npos) << e2;
}

TEST_F(PoseIoTest, KittiKeepsValuesAsReadAndSkipsBlankLinesAndCrLf) {
  const fs::path p = Write("k.txt",
                           "1.000000 0.000000 0.000000 0.5 0.000000 0.999999940 0.000000 -2 0 0 "
                           "0.999999940 3 \r\n\n   \n" +
                               kIdentityKitti);
  const auto poses = ReadKittiPoses(p);
  ASSERT_EQ(poses.size(), 2u);
  EXPECT_EQ(poses[0].matrix()(1, 1), 0.999999940);
  EXPECT_EQ(poses[0].translation(), Eigen::Vector3d(0.5, -2, 3));
  EXPECT_EQ(poses[0].matrix().row(3), Eigen::RowVector4d(0, 0, 0, 1));
}

TEST_F(PoseIoTest, KittiBadInputsNameFileLineAndReason) {
  struct Case {
    std::string line, reason;
  };
  const std::vector<Case> cases = {
      {"1 0 0 0 0 1 0 0 0 0 1", "11 numbers, expected 12"},
      {"1 0 0 0 0 1 0 0 0 0 1 0 7", "13 numbers, expected 12"},
      {"1 0 0 0 0 1 0 0 0 0 1 abc", "number 12 'abc' is not a number"},
      {"1 0 0 0 0 1 0 0 0 0 1 1.5x", "number 12 '1.5x' is not a number"},
      {"1 0 0 nan 0 1 0 0 0 0 1 0", "number 4 'nan' is not finite"},
      {"1 0 0 0 0 1 0 inf 0 0 1 0", "number 8 'inf' is not finite"},
      {"1 0 0 0 0 1 0 0 0 0 1 1e999", "out of range"},
      {"2 0 0 0 0 1 0 0 0 0 1 0", "not a rotation"},
      {"0 0 0 0 0 0 0 0 0 0 0 0", "not a rotation"},
      {"-1 0 0 0 0 1 0 0 0 0 1 0", "not a rotation"},  // reflection, det -1
      {"# comment 1 2 3", "5 numbers, expected 12"},  // no comments in KITTI files
  };
  for (const Case& c : cases) {
    const fs::path p = Write("bad.txt", kIdentityKitti + kIdentityKitti + c.line + "\n");
    const std::string e = ErrorOf([&] { ReadKittiPoses(p); });
    EXPECT_NE(e.find(p.string() + ":3: "), std::string::npos) << c.line << " -> " << e;
    EXPECT_NE(e.find(c.reason), std::string::npos) << c.line << " -> " << e;
  }
}

TEST_F(PoseIoTest, RotationToleranceIsConfigurable) {
  // 1e-3 off orthonormal: accepted by default, rejected with a tight tolerance.
  const fs::path p = Write("k.txt", "1.001 0 0 0 0 1 0 0 0 0 1 0\n");
  EXPECT_EQ(ReadKittiPoses(p).size(), 1u);
  PoseReadConfig tight;
  tight.rotation_tolerance = 1e-4;
  EXPECT_NE(ErrorOf([&] { ReadKittiPoses(p, tight); }).find("not a rotation"), std::string::npos);
}

TEST_F(PoseIoTest, MissingFileThrowsNamingIt) {
  const fs::path p = dir_ / "absent.txt";
  for (const auto& f : std::vector<std::function<void()>>{[&] { ReadKittiPoses(p); },
                                                          [&] { ReadTumPoses(p); },
                                                          [&] { ReadPoses(p); }}) {
    const std::string e = ErrorOf(f);
    EXPECT_NE(e.find(p.string() + ": cannot open"), std::string::npos) << e;
  }
}

TEST_F(PoseIoTest, TumNormalisesQuaternionAndSkipsComments) {
  const fs::path p = Write("t.tum",
                           "# timestamp tx ty tz qx qy qz qw\n"
                           "  # indented comment\n"
                           "10.5 1 2 3 0 0 0 2\n"
                           "10.6 1 2 3 0 0 3 3\n");
  const auto poses = ReadTumPoses(p);
  ASSERT_EQ(poses.size(), 2u);
  EXPECT_EQ(poses[0].t_s, 10.5);
  EXPECT_TRUE(poses[0].T_world_cam.linear().isApprox(Eigen::Matrix3d::Identity(), 1e-15));
  EXPECT_EQ(poses[0].T_world_cam.translation(), Eigen::Vector3d(1, 2, 3));
  const Eigen::Matrix3d Rz90 = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  EXPECT_TRUE(poses[1].T_world_cam.linear().isApprox(Rz90, 1e-15));
}

TEST_F(PoseIoTest, TumBadInputsNameFileLineAndReason) {
  struct Case {
    std::string line, reason;
  };
  const std::vector<Case> cases = {
      {"1 0 0 0 0 0 0", "7 numbers, expected 8"},
      {"1 0 0 0 0 0 0 0", "quaternion has zero norm"},
      {"1 0 0 0 0 0 0 x", "number 8 'x' is not a number"},
      {"1 0 0 0 0 0 -inf 1", "number 7 '-inf' is not finite"},
  };
  for (const Case& c : cases) {
    const fs::path p = Write("bad.tum", "# header\n0 0 0 0 0 0 0 1\n" + c.line + "\n");
    const std::string e = ErrorOf([&] { ReadTumPoses(p); });
    EXPECT_NE(e.find(p.string() + ":3: "), std::string::npos) << c.line << " -> " << e;
    EXPECT_NE(e.find(c.reason), std::string::npos) << c.line << " -> " << e;
  }
}

TEST_F(PoseIoTest, ReadPosesDetectsFormat) {
  const fs::path k = Write("k.txt", kIdentityKitti + kIdentityKitti);
  const PoseFile fk = ReadPoses(k);
  EXPECT_EQ(fk.format, PoseFormat::kKitti);
  ASSERT_EQ(fk.poses.size(), 2u);
  EXPECT_EQ(fk.poses[1].t_s, 1.0);  // frame index

  const fs::path t = Write("t.tum", "# c\n\n5 1 2 3 0 0 0 1\n");
  const PoseFile ft = ReadPoses(t);
  EXPECT_EQ(ft.format, PoseFormat::kTum);
  ASSERT_EQ(ft.poses.size(), 1u);
  EXPECT_EQ(ft.poses[0].t_s, 5.0);

  const fs::path bad = Write("b.txt", "\n1 2 3 4 5\n");
  const std::string e = ErrorOf([&] { ReadPoses(bad); });
  EXPECT_NE(e.find(bad.string() + ":2: 5 columns"), std::string::npos) << e;

  const fs::path empty = Write("e.txt", "# only a comment\n\n");
  EXPECT_NE(ErrorOf([&] { ReadPoses(empty); }).find("no pose line"), std::string::npos);
}

}  // namespace
}  // namespace locaid::kitti
