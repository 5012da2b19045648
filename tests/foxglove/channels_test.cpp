// The channel table and the PoseUpdate -> foxglove message conversion:
// topics and schema names, field names, covariance layout, timestamps,
// which channels a pose feeds, and the bounded /locaid/path.
#include "output/channels.hpp"
#include "clients/recorder.hpp"
#include "temp_dir.hpp"
#include "output/json_schemas.hpp"
#include "output/static_transforms.hpp"
#include "foxglove/ws_server.hpp"
#include "server/synthetic_drive.hpp"

#include <google/protobuf/descriptor.pb.h>
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <sstream>
#include <map>

namespace fx = locaid::output;  // the channels are output/'s
namespace v1 = locaid::v1;
using nlohmann::json;

namespace {

constexpr double kTol = 1e-12;

v1::PoseUpdate SamplePose(int64_t t_ns, v1::Mode mode = v1::MODE_GPS_FUSED) {
  v1::PoseUpdate p;
  p.set_session_id("s0123456789ab");
  p.set_sequence(7);
  p.set_t_ns(t_ns);
  p.mutable_position_enu_m()->set_x(1.5);
  p.mutable_position_enu_m()->set_y(-2.5);
  p.mutable_position_enu_m()->set_z(0.25);
  p.mutable_orientation_enu_body()->set_w(1);
  p.set_latitude_deg(49.011);
  p.set_longitude_deg(8.422);
  p.set_altitude_m(112.5);
  for (int i = 0; i < 36; ++i) p.add_covariance(i);  // value = its row-major index
  p.set_mode(mode);
  p.set_seconds_since_gps(INFINITY);
  return p;
}

// A message body filled into a fresh object.
template <typename Fill, typename... Args>
json Body(Fill fill, const Args&... args) {
  json body;
  fill(args..., body);
  return body;
}

std::map<fx::Topic, int> CountByTopic(const std::vector<fx::OutMessage>& messages) {
  std::map<fx::Topic, int> counts;
  for (const auto& m : messages) ++counts[m.topic];
  return counts;
}

}  // namespace

TEST(FoxgloveChannels, TableHasTheTopicsAndSchemaNames) {
  const std::vector<std::pair<std::string, std::string>> expected = {
      {"/locaid/pose", "foxglove.PoseInFrame"},   {"/tf", "foxglove.FrameTransforms"},
      {"/locaid/fix", "foxglove.LocationFix"},    {"/locaid/gps", "foxglove.LocationFix"},
      {"/locaid/truth", "foxglove.PoseInFrame"},  {"/locaid/truth_fix", "foxglove.LocationFix"},
      {"/locaid/path", "foxglove.PosesInFrame"},  {"/locaid/status", "locaid.Status"},
      {"/locaid/update", "locaid.v1.PoseUpdate"}};
  ASSERT_EQ(fx::Channels().size(), expected.size());
  for (size_t i = 0; i < expected.size(); ++i) {
    const fx::ChannelSpec& c = fx::Channels()[i];
    EXPECT_EQ(c.topic, expected[i].first);
    EXPECT_EQ(c.schema_name, expected[i].second);
    if (c.encoding == "json") {
      EXPECT_EQ(c.schema_encoding, "jsonschema") << c.topic;
      const json schema = json::parse(c.schema);
      EXPECT_EQ(schema["title"], c.schema_name) << c.topic;
      EXPECT_EQ(schema["type"], "object") << c.topic;
    } else {
      EXPECT_EQ(c.encoding, "protobuf");
      EXPECT_EQ(c.schema_encoding, "protobuf");
    }
  }
}

// What Foxglove's parseJsonSchema accepts (packages/mcap-support): each
// field has one "type" among these, objects recurse, arrays have typed items,
// and an enum is "oneOf" numeric constants.
void ExpectViewerReadable(const json& schema, const std::string& where) {
  ASSERT_EQ(schema.value("type", ""), "object") << where;
  for (const auto& [name, field] : schema["properties"].items()) {
    const std::string path = where + "." + name;
    if (field.contains("oneOf")) {
      for (const auto& alternative : field["oneOf"]) EXPECT_TRUE(alternative["const"].is_number()) << path;
      continue;
    }
    ASSERT_TRUE(field.contains("type") && field["type"].is_string()) << path << ": " << field.dump();
    const std::string type = field["type"];
    if (type == "object") {
      ExpectViewerReadable(field, path);
    } else if (type == "array") {
      const json& items = field["items"];
      ASSERT_TRUE(items["type"].is_string()) << path;
      if (items["type"] == "object") ExpectViewerReadable(items, path + "[]");
      else EXPECT_TRUE(items["type"] == "number" || items["type"] == "integer" || items["type"] == "string") << path;
    } else {
      EXPECT_TRUE(type == "boolean" || type == "string" || type == "number" || type == "integer") << path;
    }
  }
}

TEST(FoxgloveChannels, JsonSchemasStayWithinWhatViewersRead) {
  for (const fx::ChannelSpec& c : fx::Channels()) {
    if (c.encoding == "json") ExpectViewerReadable(json::parse(c.schema), c.topic);
  }
}

TEST(FoxgloveChannels, LocationFixSchemaNamesTheFoxgloveFields) {
  const json schema = json::parse(fx::Channel(fx::Topic::kFix).schema);
  for (const char* field : {"timestamp", "frame_id", "latitude", "longitude", "altitude", "position_covariance",
                            "position_covariance_type", "color", "metadata"}) {
    EXPECT_TRUE(schema["properties"].contains(field)) << field;
  }
  EXPECT_EQ(schema["properties"]["position_covariance"]["minItems"], 9);
}

TEST(FoxgloveChannels, DescriptorSetHoldsPoseUpdate) {
  google::protobuf::FileDescriptorSet set;
  ASSERT_TRUE(set.ParseFromString(fx::PoseUpdateDescriptorSet()));
  ASSERT_GE(set.file_size(), 1);
  const auto& file = set.file(set.file_size() - 1);  // dependencies come first
  EXPECT_EQ(file.name(), "locaid/v1/localization.proto");
  EXPECT_EQ(file.package(), "locaid.v1");
  bool found = false;
  for (const auto& m : file.message_type()) found = found || m.name() == "PoseUpdate";
  EXPECT_TRUE(found);
}

TEST(FoxgloveChannels, TimestampsSplitNanoseconds) {
  EXPECT_EQ(Body(fx::TimeJson, 1'715'953'912'123'456'789), json({{"sec", 1715953912}, {"nsec", 123456789}}));
  EXPECT_EQ(Body(fx::TimeJson, 999'999'999), json({{"sec", 0}, {"nsec", 999999999}}));
  EXPECT_EQ(Body(fx::TimeJson, -5), json({{"sec", 0}, {"nsec", 0}}));  // foxglove time is unsigned
}

TEST(FoxgloveChannels, FusedFixCarriesTheEnuPositionBlockOfTheCovariance) {
  const v1::PoseUpdate p = SamplePose(2'000'000'001);
  // Rows 0-2, columns 0-2 of the 6x6 (row-major index r * 6 + c).
  const std::array<double, 9> block = {0, 1, 2, 6, 7, 8, 12, 13, 14};
  EXPECT_EQ(fx::PositionCovarianceEnu(p), block);
  const json fix = Body(fx::FusedFixJson, p);
  EXPECT_EQ(fix["position_covariance"], json(block));
  EXPECT_EQ(fix["position_covariance_type"], 3);  // KNOWN
  EXPECT_NEAR(fix["latitude"].get<double>(), 49.011, kTol);
  EXPECT_NEAR(fix["longitude"].get<double>(), 8.422, kTol);
  EXPECT_NEAR(fix["altitude"].get<double>(), 112.5, kTol);
  EXPECT_EQ(fix["timestamp"], json({{"sec", 2}, {"nsec", 1}}));
  EXPECT_EQ(fix["frame_id"], "base_link");

  v1::PoseUpdate no_cov = p;
  no_cov.clear_covariance();
  EXPECT_EQ(Body(fx::FusedFixJson, no_cov)["position_covariance_type"], 0);  // UNKNOWN
}

TEST(FoxgloveChannels, GpsFixIsGreenWhenUsedRedWhenRejected) {
  v1::GpsFixSeen fix;
  fix.set_t_ns(3'000'000'000);
  fix.set_latitude_deg(49.0);
  fix.set_sigma_horizontal_m(2);
  fix.set_sigma_vertical_m(3);
  fix.set_used(true);
  json used = Body(fx::GpsFixJson, fix);
  EXPECT_EQ(used["position_covariance"], json({4, 0, 0, 0, 4, 0, 0, 0, 9}));
  EXPECT_EQ(used["position_covariance_type"], 2);  // DIAGONAL_KNOWN
  EXPECT_GT(used["color"]["g"].get<double>(), used["color"]["r"].get<double>());
  EXPECT_EQ(used["metadata"][0], json({{"key", "used"}, {"value", "true"}}));
  fix.set_used(false);
  json rejected = Body(fx::GpsFixJson, fix);
  EXPECT_GT(rejected["color"]["r"].get<double>(), rejected["color"]["g"].get<double>());
  EXPECT_EQ(rejected["metadata"][0]["value"], "false");
}

TEST(FoxgloveChannels, PoseAndTransformsUseTheFoxgloveFieldNames) {
  const v1::PoseUpdate p = SamplePose(5);
  const json pose = Body(fx::PoseInFrameJson, p.t_ns(), p.position_enu_m(), p.orientation_enu_body());
  EXPECT_EQ(pose["frame_id"], "enu");
  EXPECT_EQ(pose["pose"]["position"], json({{"x", 1.5}, {"y", -2.5}, {"z", 0.25}}));
  EXPECT_EQ(pose["pose"]["orientation"], json({{"x", 0.0}, {"y", 0.0}, {"z", 0.0}, {"w", 1.0}}));
  const json tf = Body(fx::FrameTransformsJson, p);
  ASSERT_EQ(tf["transforms"].size(), 2u);
  EXPECT_EQ(tf["transforms"][0]["parent_frame_id"], "enu");
  EXPECT_EQ(tf["transforms"][0]["child_frame_id"], "base_link");
  EXPECT_EQ(tf["transforms"][0]["translation"], pose["pose"]["position"]);
  EXPECT_EQ(tf["transforms"][1]["parent_frame_id"], "base_link");
  EXPECT_EQ(tf["transforms"][1]["child_frame_id"], "cam0");
}

// The camera looks forward: cam0's optical axis (z) is the body's x axis,
// and cam0's y (down) is the body's -z, to within the rig's small tilts.
TEST(FoxgloveChannels, CameraMountPointsCam0AlongTheBodyAxis) {
  const auto& t = fx::BaseLinkToCam0();
  const double x = t.rotation_xyzw[0], y = t.rotation_xyzw[1], z = t.rotation_xyzw[2], w = t.rotation_xyzw[3];
  EXPECT_NEAR(x * x + y * y + z * z + w * w, 1.0, 1e-9);
  // Third column of R(q): where cam0's z axis points in base_link.
  const double zx = 2 * (x * z + w * y), zz = 1 - 2 * (x * x + y * y);
  EXPECT_GT(zx, 0.99);
  // Second column: cam0's y axis.
  const double yz = 2 * (y * z + w * x);
  EXPECT_LT(yz, -0.99);
  EXPECT_LT(std::abs(zz), 0.05);
}

// The written-out constant is the inverse of the rig the server uses.
TEST(FoxgloveChannels, CameraMountIsTheServersKittiRig) {
  const auto& t = fx::BaseLinkToCam0();
  const Eigen::Isometry3d T_imu_cam0 = locaid::server::KittiRigTcam0Imu().inverse();
  const Eigen::Quaterniond q(T_imu_cam0.linear());
  const Eigen::Quaterniond ours(t.rotation_xyzw[3], t.rotation_xyzw[0], t.rotation_xyzw[1], t.rotation_xyzw[2]);
  EXPECT_NEAR(q.angularDistance(ours), 0.0, 1e-9);
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(T_imu_cam0.translation()[i], t.translation[static_cast<size_t>(i)], 1e-9);
}

TEST(FoxgloveChannels, StatusTurnsInfinityIntoNull) {
  v1::PoseUpdate p = SamplePose(1);
  json status = Body(fx::StatusJson, p);
  EXPECT_TRUE(status["seconds_since_gps"].is_null());
  EXPECT_TRUE(status["horizontal_error_m"].is_null());  // no truth
  EXPECT_EQ(status["mode"], "GPS_FUSED");
  EXPECT_EQ(status["vo_status"], "UNSPECIFIED");
  p.set_seconds_since_gps(0.25);
  p.set_has_truth(true);
  p.set_horizontal_error_m(1.75);
  status = Body(fx::StatusJson, p);
  EXPECT_EQ(status["seconds_since_gps"], 0.25);
  EXPECT_EQ(status["horizontal_error_m"], 1.75);
}

TEST(FoxgloveChannels, StatusSaysWhenTheSessionFallsBehind) {
  v1::PoseUpdate p = SamplePose(1);
  json status = Body(fx::StatusJson, p);
  EXPECT_EQ(status["behind_real_time_s"], 0.0);
  EXPECT_EQ(status["falling_behind"], false);
  p.set_behind_real_time_s(0.75);
  p.set_falling_behind(true);
  status = Body(fx::StatusJson, p);
  EXPECT_EQ(status["behind_real_time_s"], 0.75);
  EXPECT_EQ(status["falling_behind"], true);
  const json schema = json::parse(fx::schemas::Status());
  EXPECT_TRUE(schema["properties"].contains("behind_real_time_s"));
  EXPECT_EQ(schema["properties"]["falling_behind"]["type"], "boolean");
}

// The converter refills one body per channel; a refilled body must read
// exactly as a fresh one (no value of the previous pose left behind).
TEST(FoxgloveChannels, ARefilledBodyEqualsAFreshOne) {
  v1::PoseUpdate first = SamplePose(1'000'000'000);
  first.set_has_truth(true);
  first.set_horizontal_error_m(2.5);
  first.set_seconds_since_gps(0.1);
  first.set_mode(v1::MODE_VO_ONLY);
  v1::PoseUpdate second = SamplePose(2'500'000'123);
  second.mutable_position_enu_m()->set_x(-7.25);
  second.clear_covariance();
  json status, fix, tf;
  fx::StatusJson(first, status);
  fx::FusedFixJson(first, fix);
  fx::FrameTransformsJson(first, tf);
  fx::StatusJson(second, status);
  fx::FusedFixJson(second, fix);
  fx::FrameTransformsJson(second, tf);
  EXPECT_EQ(status.dump(), Body(fx::StatusJson, second).dump());
  EXPECT_EQ(fix.dump(), Body(fx::FusedFixJson, second).dump());
  EXPECT_EQ(tf.dump(), Body(fx::FrameTransformsJson, second).dump());
  EXPECT_TRUE(status["horizontal_error_m"].is_null());

  v1::GpsFixSeen used, rejected;
  used.set_used(true);
  used.set_nis(1.5);
  rejected.set_rejected_vertical(true);
  json gps;
  fx::GpsFixJson(used, gps);
  fx::GpsFixJson(rejected, gps);
  EXPECT_EQ(gps.dump(), Body(fx::GpsFixJson, rejected).dump());
}

TEST(FoxgloveChannels, PathMessageIsAPosesInFrameOfTheTrack) {
  fx::PoseConverter converter(fx::PathOptions{.spacing_ns = 1'000'000'000, .max_poses = 100});
  json path;
  for (int i = 0; i <= 30; ++i) {
    v1::PoseUpdate p = SamplePose(int64_t{i} * 100'000'000);
    p.mutable_position_enu_m()->set_x(i);
    for (const auto& m : converter.Convert(p)) {
      if (m.topic == fx::Topic::kPath) path = json::parse(m.data);
    }
  }
  ASSERT_TRUE(path.is_object());
  EXPECT_EQ(path["frame_id"], "enu");
  EXPECT_EQ(path["timestamp"], json({{"sec", 3}, {"nsec", 0}}));
  // Track poses at 0, 1, 2, 3 s (x = 0, 10, 20, 30).
  ASSERT_EQ(path["poses"].size(), 4u);
  for (size_t k = 0; k < 4; ++k) {
    EXPECT_EQ(path["poses"][k]["position"], json({{"x", 10.0 * static_cast<double>(k)}, {"y", -2.5}, {"z", 0.25}}));
    EXPECT_EQ(path["poses"][k]["orientation"], json({{"x", 0.0}, {"y", 0.0}, {"z", 0.0}, {"w", 1.0}}));
  }
}

TEST(FoxgloveChannels, ConvertFeedsChannelsByWhatThePoseHas) {
  fx::PoseConverter converter;
  // LOST: no position yet, so no fix and no path; no truth, no GPS.
  auto counts = CountByTopic(converter.Convert(SamplePose(1'000, v1::MODE_LOST)));
  EXPECT_EQ(counts, (std::map<fx::Topic, int>{
                        {fx::Topic::kPose, 1}, {fx::Topic::kTf, 1}, {fx::Topic::kStatus, 1}, {fx::Topic::kUpdate, 1}}));

  v1::PoseUpdate p = SamplePose(2'000);
  p.add_gps_fixes()->set_used(true);
  p.add_gps_fixes()->set_used(false);
  p.set_has_truth(true);
  const auto messages = converter.Convert(p);
  counts = CountByTopic(messages);
  EXPECT_EQ(counts[fx::Topic::kFix], 1);
  EXPECT_EQ(counts[fx::Topic::kGps], 2);
  EXPECT_EQ(counts[fx::Topic::kTruth], 1);
  EXPECT_EQ(counts[fx::Topic::kTruthFix], 1);
  EXPECT_EQ(counts[fx::Topic::kPath], 1);  // the first fused pose starts the track
  for (const auto& m : messages) {
    if (m.topic == fx::Topic::kUpdate) {
      v1::PoseUpdate back;
      ASSERT_TRUE(back.ParseFromString(m.data));
      EXPECT_EQ(back.session_id(), p.session_id());
      EXPECT_EQ(back.gps_fixes_size(), 2);
    }
    if (m.topic != fx::Topic::kGps) {
      EXPECT_EQ(m.log_time_ns, 2'000u);
    }
  }
}

TEST(FoxgloveChannels, PathGrowsAtItsSpacingAndStaysBounded) {
  fx::PoseConverter converter(fx::PathOptions{.spacing_ns = 1'000'000'000, .max_poses = 4});
  int published = 0;
  // 10 Hz for 20 s of sensor time.
  for (int i = 0; i <= 200; ++i) {
    for (const auto& m : converter.Convert(SamplePose(int64_t{i} * 100'000'000))) {
      if (m.topic != fx::Topic::kPath) continue;
      ++published;
      EXPECT_LE(json::parse(m.data)["poses"].size(), 4u);
    }
  }
  EXPECT_LE(converter.path_size(), 4u);
  EXPECT_GE(converter.path_size(), 2u);
  // 4 poses at 1 s, then halved to 2 at 2 s, 4 at 2 s, halved at 4 s ... 8 s.
  EXPECT_EQ(converter.path_spacing_ns(), 8'000'000'000);
  EXPECT_GE(published, 8);
  EXPECT_LE(published, 21);
  converter.Reset();
  EXPECT_EQ(converter.path_size(), 0u);
  EXPECT_EQ(converter.path_spacing_ns(), 1'000'000'000);
}

TEST(FoxgloveChannels, Base64MatchesRfc4648Vectors) {
  EXPECT_EQ(locaid::foxglove::Base64(""), "");
  EXPECT_EQ(locaid::foxglove::Base64("f"), "Zg==");
  EXPECT_EQ(locaid::foxglove::Base64("fo"), "Zm8=");
  EXPECT_EQ(locaid::foxglove::Base64("foo"), "Zm9v");
  EXPECT_EQ(locaid::foxglove::Base64("foob"), "Zm9vYg==");
  EXPECT_EQ(locaid::foxglove::Base64("foobar"), "Zm9vYmFy");
  EXPECT_EQ(locaid::foxglove::Base64(std::string("\xff\x00\x80", 3)), "/wCA");
}

// Every mode the proto has, DEAD_RECKONING included, is written by its own
// name in the status channel and in `locaid subscribe`'s CSV, never as
// UNSPECIFIED: the names come from the proto, not from a table of our own.
TEST(OutputEnumNames, EveryModeIsWrittenByTheProtosName) {
  const locaid::test_support::ScopedTempDir dir("enum_names");
  const auto* modes = v1::Mode_descriptor();
  for (int i = 0; i < modes->value_count(); ++i) {
    const auto mode = static_cast<v1::Mode>(modes->value(i)->number());
    const std::string name = modes->value(i)->name().substr(std::string("MODE_").size());
    EXPECT_EQ(Body(fx::StatusJson, SamplePose(1, mode))["mode"], name);
    const std::string csv = (dir.path() / (name + ".csv")).string();
    {
      locaid::clients::Recorder recorder("csv", csv);
      recorder.Add(SamplePose(1, mode), 0.0);
      recorder.Close();
    }
    std::ifstream in(csv);
    std::stringstream text;
    text << in.rdbuf();
    EXPECT_NE(text.str().find("," + name + ","), std::string::npos) << text.str();
  }
  EXPECT_EQ(fx::ModeName(static_cast<v1::Mode>(99)), "99") << "a value this build does not know: its number";
}
