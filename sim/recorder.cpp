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

#include "app/common/units.hpp"
#include "app/io/y4m.hpp"
#include "app/tools/common/still_image.hpp"
#include "app/tools/common/tool_files.hpp"
#include "dbc/markloop_messages.hpp"
#include "drivers/can/candump_log.hpp"
#include "sim/noise.hpp"

namespace markloop::sim {

namespace {

// A checked output file: the first failure is remembered in `error`.
class OutputFile {
 public:
  OutputFile(const std::filesystem::path& path, std::string& error) : error_(error) {
    if (const Status opened = file_.open(path.string()); !opened && error_.empty()) error_ = opened.message();
  }
  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;
  bool ok() const { return file_.get() != nullptr; }
  std::FILE* get() { return file_.get(); }
  // The first failure remembered when this file's close fails or it never
  // opened after one.
  Status close() {
    if (!ok()) return error_.empty() ? Status() : Status(error(error_));
    const Status closed = file_.close();
    if (!closed && error_.empty()) error_ = closed.message();
    return closed ? Status() : Status(error(error_));
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

// odometry.log: VehicleOdometry frames every period from 0 to end_time_s;
// returns how many it wrote.
Result<std::size_t> write_odometry(const Scenario& scenario, const RecordOptions& options,
                                   double end_time_s) {
  const std::filesystem::path path = std::filesystem::path(options.out_dir) / "odometry.log";
  std::string problem;
  OutputFile log(path, problem);
  if (!log.ok()) return error(problem);
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
    const double yaw_rate_dps = wrap_angle(after.yaw - before.yaw) / span * kDegreesPerRadian;
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
    if (n == 0 || std::fwrite(line, 1, n, log.get()) != n) return error(tools::write_error(path.string()));
  }
  if (!log.close()) return error(problem);
  return messages;
}

Status make_out_dir(const std::filesystem::path& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) return error(dir.string() + ": cannot create the directory: " + ec.message());
  return {};
}

Status save_camera(const perception::CameraModel& camera, const std::filesystem::path& dir) {
  return perception::save_camera_model(camera, (dir / "camera.yaml").string());
}

// markings.txt: its record count, then the records gathered in `part`
// (removed afterwards).
Status write_markings_txt(const std::filesystem::path& dir, const std::filesystem::path& part_path,
                          std::size_t record_count) {
  std::string problem;
  OutputFile markings(dir / "markings.txt", problem);
  if (!markings.ok()) return error(problem);
  std::fprintf(markings.get(), "%zu\n", record_count);
  std::FILE* part = std::fopen(part_path.c_str(), "r");
  if (part == nullptr) return error(part_path.string() + ": cannot read: " + std::strerror(errno));
  char buffer[1 << 16];
  for (std::size_t n; (n = std::fread(buffer, 1, sizeof buffer, part)) > 0;)
    std::fwrite(buffer, 1, n, markings.get());
  const bool read_ok = std::ferror(part) == 0;
  std::fclose(part);
  if (!read_ok) return error(part_path.string() + ": cannot read: " + std::strerror(errno));
  if (!markings.close()) return error(problem);
  std::error_code ec;
  std::filesystem::remove(part_path, ec);
  return {};
}

// markings.csv: the world's markings.
Status write_world_csv(const std::filesystem::path& dir, const Scenario& scenario) {
  std::string problem;
  OutputFile world(dir / "markings.csv", problem);
  if (!world.ok()) return error(problem);
  std::fprintf(world.get(), "id,class,x,y,heading\n");
  const auto& classes = marking_class_names();
  for (const Marking& m : scenario.markings)
    std::fprintf(world.get(), "%u,%s,%.4f,%.4f,%.6f\n", m.id, classes.at(m.label).c_str(), m.x, m.y,
                 m.heading);
  if (!world.close()) return error(problem);
  return {};
}

// The files a drive writes frame by frame, and the renderer behind
// frames.y4m and visible.csv. The first failure of any file is in error_.
class DriveRecorder {
 public:
  DriveRecorder(const Scenario& scenario, const perception::CameraModel& camera, const RecordOptions& options)
      : scenario_(scenario),
        camera_(camera),
        options_(options),
        dir_(options.out_dir),
        records_path_(dir_ / "markings.txt.part"),
        lap_seconds_(scenario.road.length() / options.drive.speed_mps),
        image_(camera.height(), camera.width(), CV_8UC1) {}

  Status open();
  Status record(std::size_t k, const DriveFrame& frame);
  Status close_frame_files();
  // After close_frame_files: the files of the whole drive.
  Status finish(RecordSummary& summary);

  RecordSummary& summary() { return summary_; }

 private:
  Status open_render_outputs();
  Status render(std::size_t k, const DriveFrame& frame);
  Status failed() const { return error(error_); }

  const Scenario& scenario_;
  const perception::CameraModel& camera_;
  const RecordOptions& options_;
  const std::filesystem::path dir_;
  // The legacy markings.txt starts with its record count: the records go to
  // a side file first, so memory stays bounded however long the drive.
  const std::filesystem::path records_path_;
  const double lap_seconds_;
  std::string error_;
  std::optional<OutputFile> poses_, truth_, visible_, records_;
  std::optional<Renderer> renderer_;
  io::Y4mWriter video_;
  std::size_t record_count_ = 0;
  std::vector<VisibleMarking> seen_;
  std::vector<Occluder> occluders_;
  cv::Mat image_;
  RecordSummary summary_;
};

Status DriveRecorder::open() {
  poses_.emplace(dir_ / "poses.txt", error_);
  truth_.emplace(dir_ / "frames.csv", error_);
  if (!poses_->ok() || !truth_->ok()) return failed();
  std::fprintf(truth_->get(), "frame,t,x,y,yaw\n");
  if (options_.render)
    if (Status opened = open_render_outputs(); !opened) return opened;
  records_.emplace(records_path_, error_);
  if (!records_->ok()) return failed();
  return {};
}

Status DriveRecorder::open_render_outputs() {
  const auto fps_num = static_cast<int>(std::lround(options_.drive.fps * 1000));
  renderer_.emplace(camera_, scenario_);
  if (!video_.open((dir_ / "frames.y4m").string(), camera_.width(), camera_.height(), fps_num, 1000))
    return error(video_.error());
  visible_.emplace(dir_ / "visible.csv", error_);
  if (!visible_->ok()) return failed();
  std::fprintf(visible_->get(), "frame,id,class,x1,y1,x2,y2,x3,y3,x4,y4\n");
  return {};
}

Status DriveRecorder::record(std::size_t k, const DriveFrame& frame) {
  write_kitti_pose(poses_->get(), frame.estimate.pose);
  std::fprintf(truth_->get(), "%u,%.3f,%.4f,%.4f,%.6f\n", frame.estimate.frame, frame.estimate.t,
               frame.truth.x, frame.truth.y, frame.truth.yaw);
  const auto& classes = marking_class_names();
  for (const auto& obs : frame.observations) {
    std::fprintf(records_->get(), "%u %.4f 1.5 %.4f %s\n", frame.estimate.frame, -obs.y, obs.x,
                 classes.at(obs.label).c_str());
    ++record_count_;
  }
  if (renderer_)
    if (Status rendered = render(k, frame); !rendered) return rendered;
  ++summary_.frames;
  return {};
}

// Frame k into frames.y4m and its visible markings into visible.csv.
Status DriveRecorder::render(std::size_t k, const DriveFrame& frame) {
  const double t = frame.estimate.t;
  const int day = scenario_.days > 1 ? std::min(scenario_.days - 1, static_cast<int>(t / lap_seconds_)) : 0;
  const Conditions conditions = conditions_for_day(options_.conditions, day);
  const double road_length = scenario_.road.length();
  const double car_s = std::fmod(
      std::clamp(options_.drive.speed_mps * t, 0.0, road_length * scenario_.laps - 1e-6), road_length);
  occluders_at(conditions, t, scenario_.road, car_s, frame.truth, 3.5, occluders_);
  const double start = thread_cpu_seconds();
  const bool covered = t >= options_.lens_covered_from_s && t < options_.lens_covered_until_s;
  if (covered) {
    cv::RNG sensor(options_.seed + k);
    sensor.fill(image_, cv::RNG::NORMAL, 4.0, conditions.noise_sigma);
  } else {
    renderer_->render(frame.truth, options_.drive.speed_mps, conditions, k, occluders_, image_);
  }
  summary_.render_seconds += thread_cpu_seconds() - start;
  if (!video_.write_frame({image_.data, image_.total()})) return error(video_.error());
  renderer_->visible_markings(frame.truth, options_.visible_near_m, options_.visible_far_m, occluders_,
                              seen_);
  if (covered) seen_.clear();
  for (const VisibleMarking& v : seen_) write_quad_row(visible_->get(), k, v, false);
  summary_.visible_rows += seen_.size();
  return {};
}

Status DriveRecorder::close_frame_files() {
  if (!poses_->close() || !truth_->close()) return failed();
  if (options_.render) {
    if (!video_.close()) return error(video_.error());
    if (!visible_->close()) return failed();
  }
  return {};
}

Status DriveRecorder::finish(RecordSummary& summary) {
  const double end_time = summary_.frames > 0 ? double(summary_.frames - 1) / options_.drive.fps : 0.0;
  const Result<std::size_t> messages = write_odometry(scenario_, options_, end_time);
  if (!messages) return messages.error();
  summary_.odometry_messages = *messages;
  if (!records_->close()) return failed();
  if (Status written = write_markings_txt(dir_, records_path_, record_count_); !written) return written;
  if (Status written = write_world_csv(dir_, scenario_); !written) return written;
  summary_.detections = record_count_;
  summary = summary_;
  return save_camera(camera_, dir_);
}

// Every 10 % of `frames` on stderr.
void report_progress(const RecordOptions& options, std::size_t done, std::size_t frames,
                     std::size_t& next_report) {
  if (options.progress && frames >= 50 && done * 10 >= next_report * frames) {
    std::fprintf(stderr, "markloop-sim: %zu %% (%zu / %zu frames)\n", next_report * 10, done, frames);
    ++next_report;
  }
}

// A world of the training set's own: dense rows of every class in equal
// shares, on the city streets.
std::optional<Scenario> training_world(std::uint64_t seed) {
  WorldConfig world;
  world.row_spacing_min_m = 9.0;
  world.row_spacing_max_m = 22.0;
  world.marking_probability = 0.8;
  std::array<double, kClassCount> equal;
  equal.fill(1.0);
  world.class_weights = equal;
  return make_scenario("grid", seed, world);
}

// What one training image is taken under, drawn from `rng`.
struct TrainingShot {
  Conditions conditions;
  double speed = 0.0;
  double t = 0.0;
};

TrainingShot random_shot(std::mt19937_64& rng, std::uint64_t seed, std::size_t k) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  TrainingShot shot;
  Conditions& c = shot.conditions;
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
  shot.speed = 5.0 + 10.0 * unit(rng);
  shot.t = 12.0 * unit(rng);
  return shot;
}

// Somewhere on the route with at least one marking in view (in `seen`); the
// car off the lane centre and turned a little, as real drivers are.
Pose2 place_car(const Scenario& scenario, const Renderer& renderer, const TrainingSetOptions& options,
                const TrainingShot& shot, std::mt19937_64& rng, std::vector<Occluder>& occluders,
                std::vector<VisibleMarking>& seen) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const double length = scenario.road.length();
  Pose2 pose;
  for (int attempt = 0; attempt < 20; ++attempt) {
    const double car_s = length * unit(rng);
    const Pose2 centre = scenario.road.at(car_s);
    const double side = (unit(rng) - 0.5) * 1.0;
    pose = {centre.x - std::sin(centre.yaw) * side, centre.y + std::cos(centre.yaw) * side,
            wrap_angle(centre.yaw + (unit(rng) - 0.5) * 0.08)};
    occluders_at(shot.conditions, shot.t, scenario.road, car_s, pose, 3.5, occluders);
    renderer.visible_markings(pose, options.visible_near_m, options.visible_far_m, occluders, seen);
    if (!seen.empty()) break;
  }
  return pose;
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

Result<RecordSummary> record_drive(const Scenario& scenario, const perception::CameraModel& camera,
                                   const RecordOptions& options) {
  if (Status made = make_out_dir(options.out_dir); !made) return made.error();
  Drive drive(scenario, options.drive, options.seed * 7919 + 17);
  const std::size_t frames =
      options.max_frames > 0 ? std::min(options.max_frames, drive.frame_count()) : drive.frame_count();
  DriveRecorder recorder(scenario, camera, options);
  if (Status opened = recorder.open(); !opened) return opened.error();
  DriveFrame frame;
  std::size_t next_report = 1;
  for (std::size_t k = 0; k < frames && drive.next(frame); ++k) {
    if (Status recorded = recorder.record(k, frame); !recorded) return recorded.error();
    report_progress(options, recorder.summary().frames, frames, next_report);
  }
  if (Status closed = recorder.close_frame_files(); !closed) return closed.error();
  RecordSummary summary;
  if (Status finished = recorder.finish(summary); !finished) return finished.error();
  return summary;
}

Result<std::size_t> record_training_set(const perception::CameraModel& camera,
                                        const TrainingSetOptions& options) {
  const std::filesystem::path dir(options.out_dir);
  if (Status made = make_out_dir(dir / "images"); !made) return made.error();
  const std::uint64_t seed = options.seed + kTrainingSeedOffset;
  const std::optional<Scenario> scenario = training_world(seed);
  if (!scenario) return error("internal: no grid scenario");
  Renderer renderer(camera, *scenario);
  std::string problem;
  OutputFile csv(dir / "annotations.csv", problem);
  if (!csv.ok()) return error(problem);
  std::fprintf(csv.get(), "image,label,x1,y1,x2,y2,x3,y3,x4,y4\n");
  std::mt19937_64 rng(hash_mix(seed));
  std::vector<VisibleMarking> seen;
  std::vector<Occluder> occluders;
  cv::Mat image;
  std::size_t annotations = 0;
  for (std::size_t k = 0; k < options.frames; ++k) {
    const TrainingShot shot = random_shot(rng, seed, k);
    const Pose2 pose = place_car(*scenario, renderer, options, shot, rng, occluders, seen);
    renderer.render(pose, shot.speed, shot.conditions, k, occluders, image);
    const std::filesystem::path png = dir / "images" / (std::to_string(1000000 + k).substr(1) + ".png");
    if (Status written = io::write_png(png.string(), image); !written) return written.error();
    for (const VisibleMarking& v : seen) write_quad_row(csv.get(), k, v, true);
    annotations += seen.size();
    if (options.progress && options.frames >= 50 && (k + 1) % (options.frames / 10) == 0)
      std::fprintf(stderr, "markloop-sim: training set %zu / %zu images\n", k + 1, options.frames);
  }
  if (!csv.close()) return error(problem);
  if (Status saved = save_camera(camera, dir); !saved) return saved.error();
  return annotations;
}

}  // namespace markloop::sim
