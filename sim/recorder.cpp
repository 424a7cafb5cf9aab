#include "sim/recorder.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <random>
#include <vector>

#include "app/io/y4m.hpp"
#include "app/tools/common/still_image.hpp"
#include "app/tools/common/tool_files.hpp"
#include "dbc/markloop_messages.hpp"
#include "drivers/can/candump_log.hpp"
#include "sim/noise.hpp"

namespace markloop::sim {

namespace {

constexpr double kRadToDeg = 180.0 / 3.14159265358979323846;

// A checked output file: the first failure is remembered in `error`.
class OutputFile {
 public:
  OutputFile(const std::filesystem::path& path, std::string& error) : error_(error) {
    std::string problem;
    if (!file_.open(path.string(), problem) && error_.empty()) error_ = problem;
  }
  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;
  bool ok() const { return file_.get() != nullptr; }
  std::FILE* get() { return file_.get(); }
  bool close() {
    if (!ok()) return error_.empty();
    std::string problem;
    if (file_.close(problem)) return true;
    if (error_.empty()) error_ = problem;
    return false;
  }

 private:
  tools::OutputFile file_;
  std::string& error_;
};

// CPU time, not wall time: the figure should not depend on what else runs.
double thread_cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

// The true pose at time t, as Drive computes it; held at the end of the
// drive (a route does not wrap round to its start).
Pose2 truth_at(const Scenario& scenario, double speed, double t) {
  const double lap = scenario.road.length();
  const double end = lap * scenario.laps - 1e-6;
  return scenario.road.at(std::fmod(std::clamp(speed * t, 0.0, end), lap));
}

// Ground frame (x ahead, y left) to the camera-style world of the paper's
// files (x right, y down, z ahead); the ground lies 1.5 m below the camera.
void write_kitti_pose(std::FILE* f, const Pose2& p) {
  const double c = std::cos(p.yaw), s = std::sin(p.yaw);
  std::fprintf(f, "%.6f 0 %.6f %.4f 0 1 0 0 %.6f 0 %.6f %.4f\n", c, -s, -p.y, s, c, p.x);
}

void write_quad_row(std::FILE* f, std::size_t frame_or_image, const VisibleMarking& v, bool image_name) {
  if (image_name)
    std::fprintf(f, "%06zu.png,%s", frame_or_image, marking_class_names()[v.label].c_str());
  else
    std::fprintf(f, "%zu,%u,%s", frame_or_image, v.id, marking_class_names()[v.label].c_str());
  for (const auto& corner : v.quad) std::fprintf(f, ",%.2f,%.2f", corner[0], corner[1]);
  std::fputc('\n', f);
}

bool write_odometry(const Scenario& scenario, const RecordOptions& options, double end_time_s,
                    RecordSummary& summary, std::string& error) {
  const std::filesystem::path path = std::filesystem::path(options.out_dir) / "odometry.log";
  OutputFile log(path, error);
  if (!log.ok()) return false;
  const OdometryConfig& config = options.odometry;
  const double speed = options.drive.speed_mps;
  std::mt19937_64 rng(hash_mix(options.seed ^ 0x0D0D0D));
  std::normal_distribution<double> gauss(0.0, 1.0);
  dbc::E2eSenderState counter;
  const auto messages = static_cast<std::size_t>(std::floor(end_time_s / config.period_s + 1e-9)) + 1;
  const double h = 0.05;  // yaw rate from the path's heading +-50 ms
  char line[can::kCandumpMaxLine];
  for (std::size_t j = 0; j < messages; ++j) {
    const double t = static_cast<double>(j) * config.period_s;
    const Pose2 before = truth_at(scenario, speed, std::max(0.0, t - h));
    const Pose2 after = truth_at(scenario, speed, t + h);
    const double span = t + h - std::max(0.0, t - h);
    const double yaw_rate_dps = wrap_angle(after.yaw - before.yaw) / span * kRadToDeg;
    dbc::VehicleOdometry m;
    m.wheel_speed_m_per_s = speed * (1.0 + config.speed_scale_error) + config.speed_noise_mps * gauss(rng);
    m.yaw_rate_deg_per_s = yaw_rate_dps + config.yaw_rate_bias_dps + config.yaw_rate_noise_dps * gauss(rng);
    m.wheel_speed_valid = true;
    m.yaw_rate_valid = true;
    can::CanFrame frame;
    frame.id = dbc::VehicleOdometry::kId;
    frame.dlc = dbc::encode(m, counter.next(), std::span<std::uint8_t, 8>(frame.data));
    frame.timestamp_ns =
        static_cast<std::int64_t>(j) * static_cast<std::int64_t>(std::llround(config.period_s * 1e9));
    const std::size_t n = can::format_candump_line(frame, "vcan0", line, sizeof line);
    if (n == 0 || std::fwrite(line, 1, n, log.get()) != n) {
      error = tools::write_error(path.string());
      return false;
    }
  }
  summary.odometry_messages = messages;
  return log.close();
}

}  // namespace

Conditions conditions_for_day(const Conditions& first, int day) {
  if (day == 0) return first;
  Conditions c = first;
  c.seed = hash_mix(first.seed + static_cast<std::uint64_t>(day));
  c.light = day % 2 == 1 ? Illumination::kDusk : Illumination::kWetGlare;
  c.shadows = false;
  return c;
}

bool record_drive(const Scenario& scenario, const perception::CameraModel& camera,
                  const RecordOptions& options, RecordSummary& summary, std::string& error) {
  const std::filesystem::path dir(options.out_dir);
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) {
    error = dir.string() + ": cannot create the directory: " + ec.message();
    return false;
  }
  summary = {};
  Drive drive(scenario, options.drive, options.seed * 7919 + 17);
  const std::size_t frames =
      options.max_frames > 0 ? std::min(options.max_frames, drive.frame_count()) : drive.frame_count();
  const double lap_seconds = scenario.road.length() / options.drive.speed_mps;

  OutputFile poses(dir / "poses.txt", error), truth(dir / "frames.csv", error);
  if (!poses.ok() || !truth.ok()) return false;
  std::fprintf(truth.get(), "frame,t,x,y,yaw\n");

  std::optional<Renderer> renderer;
  io::Y4mWriter video;
  std::optional<OutputFile> visible;
  const auto fps_num = static_cast<int>(std::lround(options.drive.fps * 1000));
  if (options.render) {
    renderer.emplace(camera, scenario);
    if (!video.open((dir / "frames.y4m").string(), camera.width(), camera.height(), fps_num, 1000)) {
      error = video.error();
      return false;
    }
    visible.emplace(dir / "visible.csv", error);
    if (!visible->ok()) return false;
    std::fprintf(visible->get(), "frame,id,class,x1,y1,x2,y2,x3,y3,x4,y4\n");
  }

  const auto& classes = marking_class_names();
  // The legacy markings.txt starts with its record count: the records go to
  // a side file first, so memory stays bounded however long the drive.
  const std::filesystem::path records_path = dir / "markings.txt.part";
  std::optional<OutputFile> records;
  records.emplace(records_path, error);
  if (!records->ok()) return false;
  std::size_t record_count = 0;
  std::vector<VisibleMarking> seen;
  std::vector<Occluder> occluders;
  cv::Mat image(camera.height(), camera.width(), CV_8UC1);
  Conditions first_day = options.conditions;
  DriveFrame frame;
  std::size_t next_report = 1;
  for (std::size_t k = 0; k < frames && drive.next(frame); ++k) {
    write_kitti_pose(poses.get(), frame.estimate.pose);
    std::fprintf(truth.get(), "%u,%.3f,%.4f,%.4f,%.6f\n", frame.estimate.frame, frame.estimate.t,
                 frame.truth.x, frame.truth.y, frame.truth.yaw);
    for (const auto& obs : frame.observations) {
      std::fprintf(records->get(), "%u %.4f 1.5 %.4f %s\n", frame.estimate.frame, -obs.y, obs.x,
                   classes.at(obs.label).c_str());
      ++record_count;
    }
    if (renderer) {
      const int day = scenario.days > 1
                          ? std::min(scenario.days - 1, static_cast<int>(frame.estimate.t / lap_seconds))
                          : 0;
      const Conditions conditions = conditions_for_day(first_day, day);
      const double car_s = std::fmod(std::clamp(options.drive.speed_mps * frame.estimate.t, 0.0,
                                                scenario.road.length() * scenario.laps - 1e-6),
                                     scenario.road.length());
      occluders_at(conditions, frame.estimate.t, scenario.road, car_s, frame.truth, 3.5, occluders);
      const double start = thread_cpu_seconds();
      const bool covered =
          frame.estimate.t >= options.lens_covered_from_s && frame.estimate.t < options.lens_covered_until_s;
      if (covered) {
        cv::RNG sensor(options.seed + k);
        sensor.fill(image, cv::RNG::NORMAL, 4.0, conditions.noise_sigma);
      } else {
        renderer->render(frame.truth, options.drive.speed_mps, conditions, k, occluders, image);
      }
      summary.render_seconds += thread_cpu_seconds() - start;
      if (!video.write_frame({image.data, image.total()})) {
        error = video.error();
        return false;
      }
      renderer->visible_markings(frame.truth, options.visible_near_m, options.visible_far_m, occluders, seen);
      if (covered) seen.clear();
      for (const VisibleMarking& v : seen) write_quad_row(visible->get(), k, v, false);
      summary.visible_rows += seen.size();
    }
    ++summary.frames;
    if (options.progress && frames >= 50 && summary.frames * 10 >= next_report * frames) {
      std::fprintf(stderr, "markloop-sim: %zu %% (%zu / %zu frames)\n", next_report * 10, summary.frames,
                   frames);
      ++next_report;
    }
  }
  if (!poses.close() || !truth.close()) return false;
  if (options.render) {
    if (!video.close()) {
      error = video.error();
      return false;
    }
    if (!visible->close()) return false;
  }

  const double end_time = summary.frames > 0 ? double(summary.frames - 1) / options.drive.fps : 0.0;
  if (!write_odometry(scenario, options, end_time, summary, error)) return false;

  if (!records->close()) return false;
  {
    OutputFile markings(dir / "markings.txt", error);
    if (!markings.ok()) return false;
    std::fprintf(markings.get(), "%zu\n", record_count);
    std::FILE* part = std::fopen(records_path.c_str(), "r");
    if (part == nullptr) {
      error = records_path.string() + ": cannot read: " + std::strerror(errno);
      return false;
    }
    char buffer[1 << 16];
    for (std::size_t n; (n = std::fread(buffer, 1, sizeof buffer, part)) > 0;)
      std::fwrite(buffer, 1, n, markings.get());
    const bool read_ok = std::ferror(part) == 0;
    std::fclose(part);
    if (!read_ok) {
      error = records_path.string() + ": cannot read: " + std::strerror(errno);
      return false;
    }
    if (!markings.close()) return false;
    std::filesystem::remove(records_path, ec);
  }
  {
    OutputFile world(dir / "markings.csv", error);
    if (!world.ok()) return false;
    std::fprintf(world.get(), "id,class,x,y,heading\n");
    for (const Marking& m : scenario.markings)
      std::fprintf(world.get(), "%u,%s,%.4f,%.4f,%.6f\n", m.id, classes.at(m.label).c_str(), m.x, m.y,
                   m.heading);
    if (!world.close()) return false;
  }
  summary.detections = record_count;
  return perception::save_camera_model(camera, (dir / "camera.yaml").string(), error);
}

bool record_training_set(const perception::CameraModel& camera, const TrainingSetOptions& options,
                         std::size_t& annotations, std::string& error) {
  const std::filesystem::path dir(options.out_dir);
  std::error_code ec;
  std::filesystem::create_directories(dir / "images", ec);
  if (ec) {
    error = (dir / "images").string() + ": cannot create the directory: " + ec.message();
    return false;
  }
  const std::uint64_t seed = options.seed + kTrainingSeedOffset;
  // Dense rows of every class in equal shares, on the city streets.
  WorldConfig world;
  world.row_spacing_min_m = 9.0;
  world.row_spacing_max_m = 22.0;
  world.marking_probability = 0.8;
  std::array<double, kClassCount> equal;
  equal.fill(1.0);
  world.class_weights = equal;
  auto scenario = make_scenario("grid", seed, world);
  if (!scenario) {
    error = "internal: no grid scenario";
    return false;
  }
  Renderer renderer(camera, *scenario);
  OutputFile csv(dir / "annotations.csv", error);
  if (!csv.ok()) return false;
  std::fprintf(csv.get(), "image,label,x1,y1,x2,y2,x3,y3,x4,y4\n");
  std::mt19937_64 rng(hash_mix(seed));
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<VisibleMarking> seen;
  std::vector<Occluder> occluders;
  cv::Mat image;
  annotations = 0;
  const double length = scenario->road.length();
  for (std::size_t k = 0; k < options.frames; ++k) {
    Conditions c;
    const double pick = unit(rng);
    c.light = pick < 0.5    ? Illumination::kDay
              : pick < 0.7  ? Illumination::kDusk
              : pick < 0.85 ? Illumination::kNight
                            : Illumination::kWetGlare;
    c.paint_wear = 0.7 * unit(rng);
    c.shadows = unit(rng) < 0.6;
    c.occluder_probability = 0.3;
    c.noise_sigma = 1.0 + 3.0 * unit(rng);
    c.seed = hash_mix(seed * 1000003 + k);
    const double speed = 5.0 + 10.0 * unit(rng);
    const double t = 12.0 * unit(rng);
    // Somewhere on the route with at least one marking in view; the car
    // off the lane centre and turned a little, as real drivers are.
    Pose2 pose;
    for (int attempt = 0; attempt < 20; ++attempt) {
      const double car_s = length * unit(rng);
      const Pose2 centre = scenario->road.at(car_s);
      const double side = (unit(rng) - 0.5) * 1.0;
      pose = {centre.x - std::sin(centre.yaw) * side, centre.y + std::cos(centre.yaw) * side,
              wrap_angle(centre.yaw + (unit(rng) - 0.5) * 0.08)};
      occluders_at(c, t, scenario->road, car_s, pose, 3.5, occluders);
      renderer.visible_markings(pose, options.visible_near_m, options.visible_far_m, occluders, seen);
      if (!seen.empty()) break;
    }
    renderer.render(pose, speed, c, k, occluders, image);
    const std::filesystem::path png = dir / "images" / (std::to_string(1000000 + k).substr(1) + ".png");
    if (!io::write_png(png.string(), image, error)) return false;
    for (const VisibleMarking& v : seen) write_quad_row(csv.get(), k, v, true);
    annotations += seen.size();
    if (options.progress && options.frames >= 50 && (k + 1) % (options.frames / 10) == 0)
      std::fprintf(stderr, "markloop-sim: training set %zu / %zu images\n", k + 1, options.frames);
  }
  if (!csv.close()) return false;
  return perception::save_camera_model(camera, (dir / "camera.yaml").string(), error);
}

}  // namespace markloop::sim
