#include "sim_command.h"

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>

#include "hal/recording/recording_files.h"
#include "sim/office_recording.h"
#include "unsigned_option.h"

namespace rilo::tool {
namespace {

/// True if `dir` holds any file of a recording (the writer would refuse it).
bool holdsRecording(const std::filesystem::path& dir) {
  for (std::string_view f : {recording::kMetaFile, recording::kAnchorsFile, recording::kTagsFile, recording::kImuFile,
                             recording::kRangeFile, recording::kTdoaFile, recording::kUltrasonicFile,
                             recording::kGroundTruthFile}) {
    if (std::filesystem::exists(dir / f)) return true;
  }
  return false;
}

/// Progress on stderr once the work has taken more than a second: one line
/// rewritten in place on a terminal, a line per 10% otherwise.
class ProgressPrinter {
 public:
  explicit ProgressPrinter(double minutes) : minutes_(minutes), tty_(::isatty(STDERR_FILENO) == 1) {}
  ~ProgressPrinter() {
    if (tty_ && printed_) std::fputc('\n', stderr);
  }
  ProgressPrinter(const ProgressPrinter&) = delete;
  ProgressPrinter& operator=(const ProgressPrinter&) = delete;

  void operator()(double fraction) {
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    if (elapsed < 1.0) return;
    const int percent = static_cast<int>(fraction * 100.0);
    if (tty_) {
      std::fprintf(stderr, "\rrilo sim: %3d%% of a %.1f min session (%.0f s)", percent, minutes_, elapsed);
      std::fflush(stderr);
      printed_ = true;
    } else if (percent / 10 > last_decile_) {
      last_decile_ = percent / 10;
      spdlog::info("{:3d}% of a {:.1f} min session ({:.0f} s)", percent, minutes_, elapsed);
    }
  }

 private:
  double minutes_;
  bool tty_;
  bool printed_ = false;
  int last_decile_ = -1;
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
};

double percentOf(std::size_t part, std::size_t whole) {
  return whole ? 100.0 * static_cast<double>(part) / static_cast<double>(whole) : 0.0;
}

void printTdoaStats(const sim::TdoaStats& t, const SimOptions& o) {
  std::printf("  tdoa      %zu rows (%.1f /s); %zu packets (%g rounds/s x %d anchors): %.1f%% heard, %.1f%% of those "
              "received, %.1f%% of received without a reference\n",
              t.measurements, t.measurementsPerSecond(), t.packets, o.tdoa_hz, o.anchors, percentOf(t.heard, t.packets),
              100.0 * t.reception(), percentOf(t.no_reference, t.received));
  std::printf("  TDoA NLOS %.1f%% of rows (anchor_b only %.1f%%, reference only %.1f%%, both %.1f%%); NLOS path excess "
              "mean %.2f m, |bias| mean %.2f m, max %.2f m; outliers %.2f%%\n",
              100.0 * t.nlosFraction(), percentOf(t.nlos_b_only, t.measurements),
              percentOf(t.nlos_a_only, t.measurements),
              percentOf(t.nlos - t.nlos_a_only - t.nlos_b_only, t.measurements), t.meanNlosPathExcess(),
              t.meanNlosBias(), t.nlos_bias_abs_max_m, 100.0 * t.outlierRate());
}

void printUltrasonicStats(const sim::UltrasonicStats& u, const sim::OfficePlan& plan,
                          const sim::OfficeScenarioParams& p) {
  const sim::UltrasonicParams& up = p.ultrasonic;
  std::printf("  beacons   %d ultrasonic on the ceiling at %.2f m, receiver at [%g, %g, %g] on the body\n", up.beacons,
              plan.ceiling_m - up.mount_below_ceiling_m, up.p_b_receiver.x(), up.p_b_receiver.y(), up.p_b_receiver.z());
  std::printf("  ultrasonic %zu ranges (%.1f /s) of %zu pings: %.1f%% out of range, %.1f%% behind walls, %.1f%% "
              "blocked by obstacles, %.1f%% dropped\n",
              u.measurements, u.measurementsPerSecond(), u.pings, percentOf(u.out_of_range, u.pings),
              percentOf(u.wall_blocked, u.pings), percentOf(u.obstacle_dropped, u.pings), percentOf(u.dropouts, u.pings));
  std::printf("  reflected %.1f%% of ultrasonic ranges (excess mean %.2f m, max %.2f m)\n", 100.0 * u.nlosFraction(),
              u.meanReflectionExcess(), u.reflection_excess_max_m);
}

}  // namespace

int runSim(const SimOptions& o) {
  try {
    sim::OfficeScenarioParams p;
    p.seed = o.seed;
    p.duration_s = o.seconds;
    p.range_rate_hz = o.range_hz;
    p.anchors.count = o.anchors;
    p.channel.nlos_severity = o.nlos_severity;
    p.imu_rate_hz = o.imu_hz;
    p.ranges_per_cycle = o.ranges_per_cycle;
    p.packet_loss = o.packet_loss;
    p.report_first_path = o.first_path;
    p.walk.start_moving = o.start_moving;
    p.walk.body_height_m = o.body_height_m;
    p.tdoa.enabled = o.tdoa;
    p.tdoa.round_rate_hz = o.tdoa_hz;
    p.tdoa.packet_reception = o.packet_reception;
    p.tdoa.sigma_m = o.tdoa_sigma;
    p.tdoa.keep_twr = o.keep_twr;
    p.ultrasonic.enabled = o.ultrasonic;
    p.ultrasonic.beacons = o.ultrasonic_beacons;
    p.ultrasonic.ping_rate_hz = o.ultrasonic_hz;
    p.ultrasonic.max_range_m = o.ultrasonic_range;
    p.ultrasonic.sigma_m = o.ultrasonic_sigma;
    p.ultrasonic.speed_of_sound_scale_error = o.sound_speed_error;
    if (o.plan == "default") {
      p.plan = sim::OfficePlanKind::kDefault;
    } else if (o.plan == "random") {
      p.plan = sim::OfficePlanKind::kRandom;
    } else if (o.plan == "hall") {
      p.plan = sim::OfficePlanKind::kHall;
    } else {
      throw std::invalid_argument("--plan must be default, random or hall, not '" + o.plan + "'");
    }
    const bool hall = p.plan == sim::OfficePlanKind::kHall;
    if (!hall && (o.hall_length != SimOptions{}.hall_length || o.hall_width != SimOptions{}.hall_width)) {
      throw std::invalid_argument("--hall-length and --hall-width need --plan hall");
    }
    p.hall.size_m = Eigen::Vector2d(o.hall_length, o.hall_width);
    if (o.truth_hz > o.imu_hz) throw std::invalid_argument("--truth-hz must not exceed --imu-hz");
    sim::validate(p);

    const std::filesystem::path out(o.out);
    if (std::filesystem::exists(out) && !std::filesystem::is_directory(out)) {
      throw std::invalid_argument(o.out + " exists and is not a folder");
    }
    if (!o.overwrite && std::filesystem::exists(out) && holdsRecording(out)) {
      throw std::invalid_argument(o.out + " already holds a recording (use --overwrite to replace it)");
    }

    sim::ScenarioRecordingOptions ro;
    ro.name = out.filename().empty() ? out.parent_path().filename().string() : out.filename().string();
    char description[256];
    char plan_text[64];
    if (hall) {
      std::snprintf(plan_text, sizeof(plan_text), "%.1f m x %.1f m hall plan", o.hall_length, o.hall_width);
    } else {
      std::snprintf(plan_text, sizeof(plan_text), "%s office plan", o.plan.c_str());
    }
    std::snprintf(description, sizeof(description),
                  "rilo sim: %s, seed %llu, %d anchors, %.1f min walk%s, ranging %.1f Hz (%d per cycle), "
                  "packet loss %.2f, NLOS severity %.2f",
                  plan_text, static_cast<unsigned long long>(o.seed), o.anchors, o.seconds / 60.0,
                  o.start_moving ? " (moving at start)" : "", o.range_hz, o.ranges_per_cycle, o.packet_loss,
                  o.nlos_severity);
    ro.description = description;
    if (!o.first_path) ro.description += "; RX level only (no first-path power)";
    if (o.body_height_m != SimOptions{}.body_height_m) {
      std::snprintf(description, sizeof(description), "; body frame %.2f m above the floor", o.body_height_m);
      ro.description += description;
    }
    if (o.tdoa) {
      std::snprintf(description, sizeof(description), "; TDoA %.1f Hz rounds, packet reception %.2f, sigma %.3f m%s",
                    o.tdoa_hz, o.packet_reception, o.tdoa_sigma, o.keep_twr ? ", SS-TWR kept" : " (no SS-TWR)");
      ro.description += description;
    }
    if (o.ultrasonic) {
      std::snprintf(description, sizeof(description),
                    "; ultrasonic %d beacons at %.1f Hz, max range %.1f m, sigma %.3f m, sound speed error %+.4f",
                    o.ultrasonic_beacons, o.ultrasonic_hz, o.ultrasonic_range, o.ultrasonic_sigma, o.sound_speed_error);
      ro.description += description;
    }
    ro.truth_rate_hz = o.truth_hz;
    ro.writer.overwrite = o.overwrite;

    // Anchor heights for the summary (the plan is cheap to rebuild).
    const sim::OfficePlan plan = sim::officePlanOf(p);
    const std::vector<Eigen::Vector3d> anchors = sim::anchorsOf(plan, p);
    double z_min = anchors.front().z(), z_max = z_min;
    for (const Eigen::Vector3d& a : anchors) {
      z_min = std::min(z_min, a.z());
      z_max = std::max(z_max, a.z());
    }

    sim::OfficeStats st;
    {
      ProgressPrinter printer(o.seconds / 60.0);
      ro.progress = [&printer](double f) { printer(f); };
      st = sim::writeOfficeRecording(p, out, ro);
    }
    const double lost_pct = st.slots ? 100.0 * static_cast<double>(st.lost) / static_cast<double>(st.slots) : 0.0;
    const double empty_pct =
        st.cycles ? 100.0 * static_cast<double>(st.empty_slots) /
                        static_cast<double>(st.cycles * static_cast<std::size_t>(o.ranges_per_cycle))
                  : 0.0;
    std::printf("rilo sim: wrote %s\n", o.out.c_str());
    if (hall) {
      std::size_t pillars = 0;
      for (const sim::Obstacle& b : plan.obstacles) pillars += b.kind == sim::ObstacleKind::kPillar ? 1 : 0;
      std::printf("  plan      hall %.1f m x %.1f m, %zu pillars, %zu desks, shelves and seated people; %zu anchors "
                  "around it at %.2f-%.2f m (alternating low and high)\n",
                  plan.size_m.x(), plan.size_m.y(), pillars, plan.obstacles.size() - pillars, anchors.size(), z_min,
                  z_max);
    } else {
      std::printf("  plan      %s office %.1f m x %.1f m, %zu spaces; %zu anchors at %.2f-%.2f m\n", o.plan.c_str(),
                  plan.size_m.x(), plan.size_m.y(), plan.spaces.size(), anchors.size(), z_min, z_max);
    }
    std::printf("  duration  %.1f s, seed %llu\n", st.duration_s, static_cast<unsigned long long>(o.seed));
    std::printf("  imu       %zu samples at %g Hz\n", st.imu_samples, o.imu_hz);
    if (!o.tdoa || o.keep_twr) {
      std::printf(
          "  ranges    %zu (%.1f /s of %g scheduled; %.1f%% packets lost, %.1f%% slots without a heard anchor)\n",
          st.ranges, st.rangesPerSecond(), o.range_hz, lost_pct, empty_pct);
      std::printf("  NLOS      %.1f%% of ranges (mean excess %.2f m, max %.2f m); outliers %.2f%%\n",
                  100.0 * st.nlosFraction(), st.meanNlosExcess(), st.nlos_excess_max_m, 100.0 * st.outlierRate());
    } else {
      std::printf("  ranges    none (TDoA replaces SS-TWR; --keep-twr writes both)\n");
    }
    if (o.tdoa) printTdoaStats(st.tdoa, o);
    if (o.ultrasonic) printUltrasonicStats(st.ultrasonic, plan, p);
    return 0;
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
}

void addSimCommand(CLI::App& app) {
  auto o = std::make_shared<SimOptions>();
  CLI::App* cmd = app.add_subcommand(
      "sim", "Simulate a person walking through an office or an open hall (UWB ranges or TDoA, ultrasonic, IMU) and "
      "write it as a recording folder");
  cmd->add_option("OUT", o->out, "Recording folder to create")->required();
  cmd->add_option("--seed", o->seed, "Seed of the walk, the noise and (with --plan random) the plan")
      ->capture_default_str()->check(cli::notNegative());
  cmd->add_option("--seconds", o->seconds, "Duration of the session (s)")
      ->capture_default_str()
      ->check(CLI::Range(3.0, 36000.0));
  cmd->add_option("--range-hz", o->range_hz, "Total ranging rate over all anchors, before packet loss (Hz)")
      ->capture_default_str()
      ->check(CLI::Range(0.1, 1000.0));
  cmd->add_option("--anchors", o->anchors,
                  "Number of anchors, mounted on walls at 2.0-2.8 m (hall: around it, alternating 0.5-1.0 m and "
                  "2.5-2.8 m)")
      ->capture_default_str()
      ->check(CLI::Range(1, 32));
  cmd->add_option("--nlos-severity", o->nlos_severity,
                  "Scale of the range excess through walls, furniture and bodies (0 = none, 1 = typical)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 10.0));
  cmd->add_option("--imu-hz", o->imu_hz, "IMU sample rate (Hz)")->capture_default_str()->check(CLI::Range(50.0, 4000.0));
  cmd->add_option("--ranges-per-cycle", o->ranges_per_cycle, "Strongest anchors ranged per cycle")
      ->capture_default_str()
      ->check(CLI::Range(1, 32));
  cmd->add_option("--packet-loss", o->packet_loss, "Probability that a range packet is lost")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 0.95));
  cmd->add_option("--plan", o->plan,
                  "Office plan: default (20 m x 12 m, corridor, 6 rooms), random (from the seed) or hall (one open "
                  "room with desks, shelves and pillars, the anchors around it)")
      ->capture_default_str()
      ->check(CLI::IsMember({"default", "random", "hall"}));
  cmd->add_option("--hall-length", o->hall_length, "With --plan hall: its size along x (m)")
      ->capture_default_str()
      ->check(CLI::Range(6.0, 100.0));
  cmd->add_option("--hall-width", o->hall_width, "With --plan hall: its size along y (m)")
      ->capture_default_str()
      ->check(CLI::Range(6.0, 100.0));
  cmd->add_option("--truth-hz", o->truth_hz, "Ground-truth pose rate in groundtruth.csv (Hz, at most --imu-hz)")
      ->capture_default_str()
      ->check(CLI::Range(1.0, 4000.0));
  cmd->add_flag("--start-moving", o->start_moving, "Start the session while walking instead of standing still");
  cmd->add_flag("--no-first-path{false}", o->first_path,
                "The receiver reports the RX level only, no first-path power (no NLOS indicator in range.csv)");
  cmd->add_option("--body-height", o->body_height_m,
                  "Height of the body frame (IMU) above the floor while standing (m; the UWB antenna is 0.1 m above "
                  "it): about 1.25 for a chest-worn tag, 1.6 for glasses, 0.95 for a belt")
      ->capture_default_str()
      ->check(CLI::Range(0.3, 2.0));
  cmd->add_flag("--overwrite", o->overwrite, "Replace a recording already in OUT");
  CLI::Option* tdoa =
      cmd->add_flag("--tdoa", o->tdoa,
                    "UWB TDoA instead of SS-TWR: the anchors transmit in turn, the tag writes range differences "
                    "(tdoa.csv, meta ranging: tdoa)");
  cmd->add_option("--tdoa-hz", o->tdoa_hz,
                  "TDoA rounds per second, one packet from every anchor each (the IMU-Ultrasonic-UWB paper: 20 Hz)")
      ->capture_default_str()
      ->check(CLI::Range(0.1, 200.0))
      ->needs(tdoa);
  cmd->add_option("--packet-reception", o->packet_reception,
                  "Probability that the tag receives a TDoA packet of an anchor it hears (that paper's worst case: 0.4)")
      ->capture_default_str()
      ->check(CLI::Range(0.01, 1.0))
      ->needs(tdoa);
  cmd->add_option("--tdoa-sigma", o->tdoa_sigma, "LOS noise of a TDoA range difference (m)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 10.0))
      ->needs(tdoa);
  cmd->add_flag("--keep-twr", o->keep_twr, "With --tdoa, also write the SS-TWR ranges (range.csv)")->needs(tdoa);
  CLI::Option* ultrasonic = cmd->add_flag(
      "--ultrasonic", o->ultrasonic,
      "Ultrasonic beacons on the ceiling and a receiver on the body (anchors of kind ultrasonic, ultrasonic.csv)");
  cmd->add_option("--ultrasonic-beacons", o->ultrasonic_beacons, "Number of ultrasonic beacons (the paper: 4)")
      ->capture_default_str()
      ->check(CLI::Range(1, 64))
      ->needs(ultrasonic);
  cmd->add_option("--ultrasonic-hz", o->ultrasonic_hz,
                  "Pings per beacon per second (the paper: 10 Hz; beacons x rate x max range / 343 m/s must stay below 1)")
      ->capture_default_str()
      ->check(CLI::Range(0.1, 100.0))
      ->needs(ultrasonic);
  cmd->add_option("--ultrasonic-range", o->ultrasonic_range, "Maximum ultrasonic range (m)")
      ->capture_default_str()
      ->check(CLI::Range(0.5, 50.0))
      ->needs(ultrasonic);
  cmd->add_option("--ultrasonic-sigma", o->ultrasonic_sigma, "Ultrasonic range noise (m)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0))
      ->needs(ultrasonic);
  cmd->add_option("--sound-speed-error", o->sound_speed_error,
                  "Speed-of-sound error as a range scale: ranges come out (1 + e) too long (about -0.0018 per degree "
                  "the air is warmer than assumed)")
      ->capture_default_str()
      ->check(CLI::Range(-0.1, 0.1))
      ->needs(ultrasonic);
  cmd->callback([o] {
    const int rc = runSim(*o);
    if (rc != 0) throw CLI::RuntimeError(rc);
  });
}

}  // namespace rilo::tool
