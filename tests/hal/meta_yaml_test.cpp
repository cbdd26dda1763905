// meta.yaml: types, domains, unknown keys, and exact round trip.
#include <gtest/gtest.h>

#include "hal/recording/meta_yaml.h"
#include "recording_test_util.h"

namespace rilo {
namespace {

using recording::formatMetaYaml;
using recording::parseMetaYaml;
using testing::expectRecordingError;

RecordingError metaError(const std::string& text) {
  return expectRecordingError([&] {
    ReadReport rep;
    parseMetaYaml(text, "meta.yaml", rep);
  });
}

TEST(MetaYaml, ParsesTheDocumentedKeys) {
  ReadReport rep;
  const RecordingMeta m = parseMetaYaml(
      "name: office_loop\n"
      "description: walk around the desks\n"
      "gravity: 9.806\n"
      "imu:\n"
      "  rate_hz: 200\n"
      "  gyro_noise_density: 1.7e-4\n"
      "  accel_noise_density: 2.0e-3\n"
      "  gyro_bias_random_walk: 1.9e-5\n"
      "  accel_bias_random_walk: 3.0e-3\n"
      "uwb:\n"
      "  lever_arm: [0.1, 0, -0.05]\n"
      "ultrasonic: {lever_arm: [0, 0.2, 0]}\n"
      "ranging: ds-twr\n",
      "meta.yaml", rep);
  EXPECT_TRUE(rep.warnings.empty());
  EXPECT_EQ(m.name, "office_loop");
  EXPECT_EQ(m.gravity_m_s2, 9.806);
  EXPECT_EQ(m.imu_rate_hz, 200.0);
  EXPECT_EQ(m.gyro_noise_density, 1.7e-4);
  EXPECT_EQ(m.accel_bias_random_walk, 3.0e-3);
  EXPECT_EQ(m.uwb_lever_arm_m, Vec3(0.1, 0, -0.05));
  EXPECT_EQ(m.ultrasonic_lever_arm_m, Vec3(0, 0.2, 0));
  EXPECT_EQ(m.ranging, RangingKind::kDsTwr);
}

TEST(MetaYaml, EmptyFileGivesDefaults) {
  ReadReport rep;
  const RecordingMeta m = parseMetaYaml("", "meta.yaml", rep);
  EXPECT_EQ(m.gravity_m_s2, 9.81);
  EXPECT_FALSE(m.imu_rate_hz.has_value());
  EXPECT_FALSE(m.ranging.has_value());
  EXPECT_TRUE(rep.warnings.empty());
  EXPECT_NO_THROW(parseMetaYaml("# only a comment\n", "meta.yaml", rep));
}

TEST(MetaYaml, UnknownKeysAreWarnings) {
  ReadReport rep;
  parseMetaYaml("name: x\noperator: bob\nimu:\n  rate_hz: 100\n  model: bmi088\nimu.gyro_noise_density: 1e-4\n",
                "meta.yaml", rep);
  ASSERT_EQ(rep.warnings.size(), 3u);
  EXPECT_EQ(rep.warnings[0].message, "meta.yaml:2: key 'operator': unknown key ignored");
  EXPECT_EQ(rep.warnings[1].column, "imu.model");
  EXPECT_EQ(rep.warnings[1].line, 5u);
  EXPECT_EQ(rep.warnings[2].column, "imu.gyro_noise_density");
  EXPECT_NE(rep.warnings[2].message.find("nested"), std::string::npos);
}

TEST(MetaYaml, WrongTypesAreErrorsNamingTheKey) {
  RecordingError e = metaError("name: x\ngravity: fast\n");
  EXPECT_EQ(e.column(), "gravity");
  EXPECT_EQ(e.line(), 2u);
  EXPECT_STREQ(e.what(), "meta.yaml:2: key 'gravity': expected a number: 'fast' is not a number");
  EXPECT_EQ(metaError("gravity: -9.81\n").detail(), "value -9.81 must be > 0");
  EXPECT_EQ(metaError("gravity: .inf\n").column(), "gravity");
  EXPECT_EQ(metaError("imu: 5\n").column(), "imu");
  EXPECT_EQ(metaError("imu:\n  rate_hz: [1, 2]\n").column(), "imu.rate_hz");
  EXPECT_EQ(metaError("imu:\n  gyro_noise_density: -1\n").column(), "imu.gyro_noise_density");
  EXPECT_EQ(metaError("uwb:\n  lever_arm: [1, 2]\n").column(), "uwb.lever_arm");
  EXPECT_EQ(metaError("uwb:\n  lever_arm: [1, 2, x]\n").column(), "uwb.lever_arm");
  EXPECT_EQ(metaError("ranging: uwb\n").detail(), "'uwb' is not a ranging kind (ss-twr, ds-twr, tdoa)");
  EXPECT_EQ(metaError("name: {first: a}\n").column(), "name");
  EXPECT_EQ(metaError("- a\n- b\n").detail(), "top level must be a mapping of keys");
  EXPECT_EQ(metaError("gravity: 9.8\ngravity: 9.7\n").detail(), "key repeated");
}

TEST(MetaYaml, InvalidYamlIsAnErrorWithLine) {
  const RecordingError e = metaError("name: x\ndescription: [unclosed\n");
  EXPECT_EQ(e.file(), "meta.yaml");
  EXPECT_GE(e.line(), 2u);
  EXPECT_NE(std::string(e.what()).find("invalid YAML"), std::string::npos);
}

TEST(MetaYaml, FormatRoundTripsAndRefusesInvalidValues) {
  RecordingMeta m;
  m.name = "yes";  // would be a boolean if unquoted
  m.description = "multi\nline: \"quoted\" # not a comment";
  m.gravity_m_s2 = 9.80665;
  m.imu_rate_hz = 1.0 / 3.0;
  m.accel_bias_random_walk = 1e-300;
  m.uwb_lever_arm_m = Vec3(-0.0, 0.1, 1e22);
  m.ranging = RangingKind::kTdoa;
  ReadReport rep;
  const RecordingMeta back = parseMetaYaml(formatMetaYaml(m), "meta.yaml", rep);
  EXPECT_TRUE(rep.warnings.empty());
  EXPECT_EQ(back.name, m.name);
  EXPECT_EQ(back.description, m.description);
  EXPECT_EQ(back.gravity_m_s2, m.gravity_m_s2);
  EXPECT_EQ(back.imu_rate_hz, m.imu_rate_hz);
  EXPECT_FALSE(back.gyro_noise_density.has_value());
  EXPECT_EQ(back.accel_bias_random_walk, m.accel_bias_random_walk);
  ASSERT_TRUE(back.uwb_lever_arm_m.has_value());
  EXPECT_EQ(*back.uwb_lever_arm_m, *m.uwb_lever_arm_m);
  EXPECT_TRUE(std::signbit(back.uwb_lever_arm_m->x()));
  // Not given, not written: a reader can tell "at the origin" from "unknown".
  EXPECT_FALSE(back.ultrasonic_lever_arm_m.has_value());
  EXPECT_EQ(back.ranging, m.ranging);

  m.imu_rate_hz = 0.0;
  EXPECT_THROW(formatMetaYaml(m), std::invalid_argument);
  m.imu_rate_hz = 100.0;
  m.ultrasonic_lever_arm_m = Vec3(std::nan(""), 0.0, 0.0);
  EXPECT_THROW(formatMetaYaml(m), std::invalid_argument);
}

}  // namespace
}  // namespace rilo
