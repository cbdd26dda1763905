// Garbage in, RecordingError (or a clean parse) out: the parsers must never
// crash, hang or throw anything else. Bounded loops with fixed seeds.
#include <gtest/gtest.h>

#include <cstdlib>
#include <random>
#include <string>

#include "hal/recording/meta_yaml.h"
#include "hal/recording/recording_reader.h"

namespace rilo {
namespace {

using namespace rilo::recording;

const std::vector<Anchor>& fuzzAnchors() {
  static const std::vector<Anchor> a{Anchor{1, Vec3(0, 0, 2), AnchorKind::kUwb, std::nullopt},
                                     Anchor{2, Vec3(4, 0, 2), AnchorKind::kUwb, std::nullopt},
                                     Anchor{3, Vec3(0, 4, 3), AnchorKind::kUltrasonic, std::nullopt}};
  return a;
}

/// Iterations: `base`, or RILO_FUZZ_ITERS from the environment for a longer manual run.
int iterations(int base) {
  const char* env = std::getenv("RILO_FUZZ_ITERS");
  return env != nullptr ? std::atoi(env) : base;
}

/// Feeds `text` to every parser; anything but RecordingError fails the test.
void feedAll(const std::string& text, std::size_t& accepted) {
  const std::vector<Tag> tags{Tag{0, Vec3::Zero()}, Tag{1, Vec3(0.1, 0, 0)}};
  auto run = [&](auto&& fn) {
    ReadReport rep;
    try {
      fn(rep);
      ++accepted;
    } catch (const RecordingError& e) {
      EXPECT_NE(std::string(e.what()), "");
    } catch (const std::exception& e) {
      ADD_FAILURE() << "unexpected exception " << e.what() << " for input of " << text.size() << " bytes";
    }
  };
  run([&](ReadReport& r) { parseAnchors(text, "anchors.csv", r); });
  run([&](ReadReport& r) { parseTags(text, "tags.csv", r); });
  run([&](ReadReport& r) {
    std::vector<ImuSample> imu;
    std::vector<double> temp;
    parseImu(text, "imu.csv", imu, temp, r);
    for (const ImuSample& s : imu) {
      EXPECT_TRUE(s.gyro_rad_s.allFinite());
      EXPECT_TRUE(s.accel_m_s2.allFinite());
    }
  });
  run([&](ReadReport& r) { parseRanges(text, "range.csv", fuzzAnchors(), tags, r); });
  run([&](ReadReport& r) { parseTdoa(text, "tdoa.csv", fuzzAnchors(), r); });
  run([&](ReadReport& r) { parseUltrasonic(text, "ultrasonic.csv", fuzzAnchors(), r); });
  run([&](ReadReport& r) { parseGroundTruth(text, "groundtruth.csv", r); });
  run([&](ReadReport& r) { parseMetaYaml(text, "meta.yaml", r); });
}

TEST(RecordingFuzz, RandomBytesNeverCrash) {
  std::mt19937 rng(12345);
  // Biased alphabet: mostly the characters CSV and YAML care about.
  const std::string alphabet = "0123456789,,,\n\n\r#-.e+nainf tx_sdm:[]{}'\"&*!|>";
  std::uniform_int_distribution<int> len(0, 400);
  std::uniform_int_distribution<int> coin(0, 9);
  std::uniform_int_distribution<std::size_t> pick(0, alphabet.size() - 1);
  std::uniform_int_distribution<int> byte(0, 255);
  std::size_t accepted = 0;
  for (int iter = 0, n_iter = iterations(1500); iter < n_iter; ++iter) {
    std::string text;
    const int n = len(rng);
    for (int i = 0; i < n; ++i) {
      text += coin(rng) == 0 ? static_cast<char>(byte(rng)) : alphabet[pick(rng)];
    }
    feedAll(text, accepted);
  }
  EXPECT_GT(accepted, 0u);  // some inputs (e.g. blank) are accepted
}

TEST(RecordingFuzz, MutatedValidFilesNeverCrash) {
  const std::vector<std::string> seeds = {
      "id,x,y,z,kind,sigma\n1,0,0,2,uwb,0.1\n2,4,0,2,,\n3,0,4,3,ultrasonic,\n",
      "# t_ns,wx,wy,wz,ax,ay,az,temp_c\n1,0.1,0.2,0.3,0,0,9.81,25\n2,0.1,0.2,0.3,0,0,9.81,\n3,1e-3,-2,3,4,5,6,7\n",
      "t_ns,anchor_id,range_m,tag_id,rssi_dbm,fp_power_dbm,los\n1,1,2.5,0,-80,,1\n1,2,3.5,1,,,0\n2,1,2.6,0,,,\n",
      "t_ns,anchor_a,anchor_b,diff_m,los\n1,1,2,0.5,1\n2,2,1,-0.5,\n",
      "t_ns,anchor_id,range_m,los\n1,3,2.5,1\n2,3,2.4,0\n",
      "t_ns,px,py,pz,qw,qx,qy,qz,vx,vy,vz\n1,0,0,0,1,0,0,0,,,\n2,1,2,3,0,1,0,0,1,2,3\n",
      "name: x\ngravity: 9.81\nimu:\n  rate_hz: 200\nuwb:\n  lever_arm: [0, 0, 0.1]\nranging: tdoa\n",
  };
  std::mt19937 rng(777);
  std::uniform_int_distribution<int> op(0, 3);
  std::uniform_int_distribution<int> byte(0, 255);
  std::size_t accepted = 0;
  for (int iter = 0, n_iter = iterations(2000); iter < n_iter; ++iter) {
    std::string text = seeds[static_cast<std::size_t>(iter) % seeds.size()];
    const int edits = 1 + iter % 4;
    for (int e = 0; e < edits && !text.empty(); ++e) {
      const std::size_t at = std::uniform_int_distribution<std::size_t>(0, text.size() - 1)(rng);
      switch (op(rng)) {
        case 0: text[at] = static_cast<char>(byte(rng)); break;
        case 1: text.erase(at, 1); break;
        case 2: text.insert(at, 1, ",\n.-e0#"[static_cast<std::size_t>(byte(rng)) % 7]); break;
        default: text.resize(at); break;  // truncation, as by a crash
      }
    }
    feedAll(text, accepted);
  }
  EXPECT_GT(accepted, 0u);
}

}  // namespace
}  // namespace rilo
