// The simulator's camera: renders the road as the car's camera sees it, from
// the world's persistent road surface, lines and markings.
//
// Fast by construction: at start-up every pixel's ground point (vehicle
// frame) and ground footprint are computed once from the calibration, and
// every marking class is drawn once into a template bitmap (with
// anisotropic mip levels). Per frame, each strip of road or paint near the
// car is projected to an image bounding box and only the pixels in it are
// shaded; textures are value noise hashed from world coordinates, so a place
// looks the same on every pass. Conditions (light, shadows, worn paint,
// vehicles ahead, sensor noise, motion blur) are deterministic in their seed.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string_view>
#include <unordered_map>
#include <vector>

#include <opencv2/core.hpp>

#include "app/perception/camera_model.hpp"
#include "sim/noise.hpp"
#include "sim/world.hpp"

namespace markloop::sim {

enum class Illumination : std::uint8_t { kDay, kDusk, kNight, kWetGlare };
std::optional<Illumination> illumination_from_name(std::string_view name);
std::string_view illumination_name(Illumination light);

struct Conditions {
  Illumination light = Illumination::kDay;
  double paint_wear = 0.35;           // worst wear of any marking, 0 (fresh) .. 1
  bool shadows = true;                // tree/building shadows (sunny light only)
  double occluder_probability = 0.3;  // share of 12 s windows with a vehicle ahead
  double noise_sigma = 2.0;           // sensor noise, grey levels at full light
  double exposure_s = 0.004;          // motion blur: ground travelled while exposed
  std::uint64_t seed = 1;             // sensor noise, vehicles, sun position
};

// A vehicle ahead, in the vehicle frame: the centre of its rear on the road.
struct Occluder {
  double ahead_m = 0.0;
  double left_m = 0.0;
  double width_m = 1.8;
  double height_m = 1.5;
};
// The vehicles ahead at time t (a deterministic schedule per seed), driving
// on `road`: `along_m` ahead of the car's arc length `car_s` (wrapping round
// a closed lap of `lap_m`), in the car's lane or the one to its left; placed
// in the frame of the car at `pose`.
void occluders_at(const Conditions& conditions, double time_s, const Path& road, double car_s,
                  const Pose2& pose, double lane_width_m, std::vector<Occluder>& out);

// A marking as it appears in one frame: corners in the order of the
// roadmarks dataset (near-left, near-right, far-right, far-left, as seen in
// the image), pixels.
struct VisibleMarking {
  std::uint32_t id = 0;
  Label label = 0;
  std::array<std::array<float, 2>, 4> quad{};
  double ahead_m = 0.0;  // distance of the centre in front of the car
};

struct RenderCounters {
  std::uint64_t frames = 0;
  std::uint64_t strips_drawn = 0;
  std::uint64_t markings_drawn = 0;
};

class Renderer {
 public:
  // Keeps references to `camera` and `scenario`; both must outlive it.
  Renderer(const perception::CameraModel& camera, const Scenario& scenario);

  int width() const { return width_; }
  int height() const { return height_; }

  // Draws the view from `pose` (true pose, world frame) into `image`
  // (CV_8UC1, camera size; allocated here only when it has another size).
  void render(const Pose2& pose, double speed_mps, const Conditions& conditions, std::uint64_t frame,
              std::span<const Occluder> occluders, cv::Mat& image);

  // Markings whose whole footprint projects inside the image, whose centre
  // lies min_ahead..max_ahead metres in front and that no vehicle hides.
  void visible_markings(const Pose2& pose, double min_ahead_m, double max_ahead_m,
                        std::span<const Occluder> occluders, std::vector<VisibleMarking>& out) const;

  const RenderCounters& counters() const { return counters_; }

 private:
  struct Template {
    // levels[kr * kLevels + kc]: rows (along) reduced 2^kr, columns 2^kc.
    std::vector<cv::Mat> levels;
  };
  static constexpr int kLevels = 6;
  static constexpr double kTexel = 0.02;  // metres per template texel at level 0

  void build_pixel_table();
  void build_templates();
  template <typename Visit>
  void for_each_near(double x, double y, double radius, bool markings, Visit&& visit) const;
  bool image_box(const Pose2& local, double half_length, double half_width, cv::Rect& box) const;
  void paint_strip(const Pose2& local, const Strip& strip, const Pose2& pose, double wear);
  void paint_marking(const Pose2& local, const Marking& marking, const Pose2& pose, double wear);
  // The steps of render(), in order.
  void cover_road(const Pose2& pose, const Pose2& to_vehicle);
  void cache_light(Illumination illumination);
  void shade_ground(const Pose2& pose, const Conditions& conditions);
  void paint_lines_and_markings(const Pose2& pose, const Pose2& to_vehicle, double wear);
  void shade_image(const Pose2& pose, const Conditions& conditions);
  void draw_vehicles(std::span<const Occluder> occluders, Illumination illumination);
  void blur_motion(double speed_mps, const Conditions& conditions);
  void expose(const Conditions& conditions, std::uint64_t frame, cv::Mat& image);

  const perception::CameraModel& camera_;
  const Scenario& scenario_;
  int width_ = 0, height_ = 0;
  // Per pixel, from the calibration.
  std::vector<float> ground_x_, ground_y_;        // vehicle frame; NaN above the horizon
  std::vector<float> footprint_x_, footprint_y_;  // ground metres one pixel spans
  std::vector<float> fine_detail_;                // weight of sub-decimetre texture
  std::vector<int> horizon_row_;                  // per column: first row that sees the road
  double nearest_ground_m_ = 0.0;
  double view_slope_ = 0.0;            // widest |y|/x the camera sees on the ground
  std::vector<float> column_bearing_;  // per column: bearing of its ray, radians left
  NoiseTile noise_{0xA5F0};            // the world's textures, all scales
  // Per illumination (recomputed when it changes): light and haze per pixel.
  std::vector<float> base_light_, haze_;
  int cached_light_ = -1;
  // Per frame.
  std::vector<float> road_, albedo_, light_;
  cv::Mat shaded_;  // CV_32F
  // Templates: one per class, then the bike lane's word (half the bike
  // markings, chosen per marking, carry it instead of the bicycle).
  static constexpr std::size_t kBikeWordTemplate = kClassCount;
  std::array<Template, kClassCount + 1> templates_;
  // Spatial index of the world: cell -> indices.
  double cell_m_ = 20.0;
  std::unordered_map<std::int64_t, std::vector<std::uint32_t>> strip_cells_, marking_cells_;
  mutable std::vector<std::uint32_t> near_;
  RenderCounters counters_;
};

}  // namespace markloop::sim
