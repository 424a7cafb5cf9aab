#include "sim/render.hpp"

#include <algorithm>
#include <cmath>
#include <ctime>
#include <limits>
#include <numbers>

#include <opencv2/imgproc.hpp>

#include "sim/noise.hpp"

namespace markloop::sim {

namespace {

constexpr double kPi = std::numbers::pi;
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr double kFarGround = 400.0;   // beyond this a pixel shows only haze
constexpr double kStripRange = 110.0;  // road and lines drawn up to here
constexpr double kMarkingRange = 80.0;

// Seeds of the world's textures: fixed, so every drive of every seed sees
// the same asphalt and the same tree shadows at the same place.
constexpr std::uint64_t kWearSeed = 0xA5F5;
constexpr std::uint64_t kSkylineSeed = 0xA5F6;

struct Vec2 {
  double x, y;
};

// Sutherland-Hodgman: keeps the part of `poly` where a*x + b*y <= c.
int clip(const Vec2* in, int n, Vec2* out, double a, double b, double c) {
  int m = 0;
  for (int i = 0; i < n; ++i) {
    const Vec2& p = in[i];
    const Vec2& q = in[(i + 1) % n];
    const double dp = a * p.x + b * p.y - c, dq = a * q.x + b * q.y - c;
    if (dp <= 0) out[m++] = p;
    if ((dp < 0) != (dq < 0) && dp != dq) {
      const double t = dp / (dp - dq);
      out[m++] = {p.x + t * (q.x - p.x), p.y + t * (q.y - p.y)};
    }
  }
  return m;
}

float sample_bilinear(const cv::Mat& m, float row, float col) {
  const int r0 = static_cast<int>(std::floor(row)), c0 = static_cast<int>(std::floor(col));
  const float fr = row - static_cast<float>(r0), fc = col - static_cast<float>(c0);
  const auto at = [&](int r, int c) {
    return (r < 0 || c < 0 || r >= m.rows || c >= m.cols) ? 0.0F : m.at<float>(r, c);
  };
  const float a = at(r0, c0) + (at(r0, c0 + 1) - at(r0, c0)) * fc;
  const float b = at(r0 + 1, c0) + (at(r0 + 1, c0 + 1) - at(r0 + 1, c0)) * fc;
  return a + (b - a) * fr;
}

int mip_level(float footprint_m, double texel_m) {
  const float ratio = footprint_m / static_cast<float>(texel_m);
  if (!(ratio >= 2.0F)) return 0;
  return std::min(std::ilogb(ratio), 5);
}

constexpr Label kBikeLabel = 8;

// Template canvas for a marking L long (along) and W wide (across), at
// `texel` metres per pixel: row 0 is the far end, column 0 the left side.
struct Canvas {
  cv::Mat image;  // CV_8U
  double length, width, texel;
  Canvas(double l, double w, double t)
      : image(std::max(1, static_cast<int>(std::lround(l / t))),
              std::max(1, static_cast<int>(std::lround(w / t))), CV_8U, cv::Scalar(0)),
        length(l),
        width(w),
        texel(t) {}
  // (along, left) metres from the centre -> canvas point with 4 fractional bits.
  cv::Point at(double a, double b) const {
    return {static_cast<int>(std::lround((width / 2 - b) / texel * 16)),
            static_cast<int>(std::lround((length / 2 - a) / texel * 16))};
  }
  void polygon(std::initializer_list<Vec2> corners) {
    std::vector<cv::Point> pts;
    for (const Vec2& c : corners) pts.push_back(at(c.x, c.y));
    cv::fillPoly(image, std::vector<std::vector<cv::Point>>{pts}, cv::Scalar(255), cv::LINE_AA, 4);
  }
  // Shaft from `from` to the head's base, head ending at `to`.
  void arrow(Vec2 from, Vec2 to, double shaft_width, double head_length, double head_width) {
    const double dx = to.x - from.x, dy = to.y - from.y, len = std::hypot(dx, dy);
    const double ux = dx / len, uy = dy / len, nx = -uy, ny = ux;
    const Vec2 base{to.x - ux * head_length, to.y - uy * head_length};
    const double s = shaft_width / 2, h = head_width / 2;
    polygon({{from.x + nx * s, from.y + ny * s},
             {base.x + nx * s + ux * 0.02, base.y + ny * s + uy * 0.02},
             {base.x - nx * s + ux * 0.02, base.y - ny * s + uy * 0.02},
             {from.x - nx * s, from.y - ny * s}});
    polygon({{base.x + nx * h, base.y + ny * h}, to, {base.x - nx * h, base.y - ny * h}});
  }
  void bar(Vec2 from, Vec2 to, double w) { arrow(from, {to.x + 1e-3, to.y}, w, 0.0, 0.0); }
};

// Text as painted on the road: glyphs drawn upright, then stretched to the
// footprint (letters about 2.5 times taller than wide, read from the car).
cv::Mat road_text(const char* text, const Canvas& canvas) {
  int baseline = 0;
  const int font = cv::FONT_HERSHEY_DUPLEX;
  const double scale = 4.0;
  const int thickness = 9;
  const cv::Size size = cv::getTextSize(text, font, scale, thickness, &baseline);
  cv::Mat glyphs(size.height + baseline + 20, size.width + 20, CV_8U, cv::Scalar(0));
  cv::putText(glyphs, text, {10, size.height + 10}, font, scale, cv::Scalar(255), thickness, cv::LINE_AA);
  std::vector<cv::Point> ink;
  cv::findNonZero(glyphs, ink);
  const cv::Rect tight = cv::boundingRect(ink);
  cv::Mat out;
  cv::resize(glyphs(tight), out, canvas.image.size(), 0, 0, cv::INTER_AREA);
  return out;
}

// Left (+1) or right (-1) turn, as US streets paint it: a shaft on the
// other side that bends at its far end into an arm across the lane, the
// head pointing to the turn's side.
void draw_turn_arrow(Canvas& c, double m) {
  const double l = c.length / 2, w = c.width / 2;
  const double shaft = -m * (w - 0.35);
  c.bar({-l, shaft}, {l - 1.0, shaft}, 0.3);
  c.bar({l - 1.05, shaft}, {l - 0.45, shaft + 0.5 * m}, 0.3);
  c.arrow({l - 0.5, shaft + 0.45 * m}, {l - 0.45, m * w}, 0.3, 0.7, 0.8);
}

// Forward and left (+1) or right (-1), as US streets paint it: a short
// through arrow, and an arm that leaves its shaft low and bends to the side,
// its head across.
void draw_forward_and_turn_arrow(Canvas& c, double m) {
  const double l = c.length / 2, w = c.width / 2;
  const double shaft = -m * (w - 0.4);
  c.arrow({-l, shaft}, {l, shaft}, 0.3, 0.8, 0.8);
  c.bar({-l + 0.3, shaft}, {-l + 0.8, shaft + 0.5 * m}, 0.3);
  c.arrow({-l + 0.75, shaft + 0.45 * m}, {-l + 0.8, m * w}, 0.3, 0.6, 0.7);
}

// Bicycle with rider, painted upright to the driver: wheels side by side
// across the lane.
void draw_bicycle(Canvas& c) {
  cv::Mat side(120, 220, CV_8U, cv::Scalar(0));
  const auto aa = cv::LINE_AA;
  cv::circle(side, {50, 80}, 34, cv::Scalar(255), 8, aa);
  cv::circle(side, {170, 80}, 34, cv::Scalar(255), 8, aa);
  cv::line(side, {50, 80}, {95, 40}, cv::Scalar(255), 8, aa);
  cv::line(side, {95, 40}, {150, 40}, cv::Scalar(255), 8, aa);
  cv::line(side, {150, 40}, {170, 80}, cv::Scalar(255), 8, aa);
  cv::line(side, {95, 40}, {110, 80}, cv::Scalar(255), 8, aa);
  cv::line(side, {50, 80}, {110, 80}, cv::Scalar(255), 8, aa);
  cv::line(side, {110, 80}, {150, 40}, cv::Scalar(255), 8, aa);
  cv::circle(side, {118, 12}, 10, cv::Scalar(255), cv::FILLED, aa);
  cv::line(side, {92, 30}, {145, 25}, cv::Scalar(255), 6, aa);
  cv::resize(side, c.image, c.image.size(), 0, 0, cv::INTER_AREA);
}

// Railway crossing (MUTCD): a large X, an R in the triangle either side.
void draw_railway_crossing(Canvas& c) {
  const double l = c.length / 2, w = c.width / 2, texel = c.texel;
  const double stroke = 0.4, r_length = 1.1, r_width = 0.55, r_inner = 0.7;
  c.bar({-l, -w}, {l, w}, stroke);
  c.bar({-l, w}, {l, -w}, stroke);
  Canvas letter(r_length, r_width, texel);
  const cv::Mat r = road_text("R", letter);
  const int rows = r.rows, cols = r.cols;
  const int row0 = static_cast<int>(std::lround((l - r_length / 2) / texel));
  for (const double left : {r_inner + r_width, -r_inner}) {  // the letter's left edge
    const int col0 = static_cast<int>(std::lround((w - left) / texel));
    if (row0 < 0 || col0 < 0 || row0 + rows > c.image.rows || col0 + cols > c.image.cols) continue;
    cv::Mat area = c.image(cv::Rect(col0, row0, cols, rows));
    cv::max(area, r, area);
  }
}

// Diamond outline.
void draw_diamond(Canvas& c) {
  const double l = c.length / 2, w = c.width / 2;
  const double t = 0.15;
  c.bar({-l + 0.1, 0}, {0, w - t}, t);
  c.bar({0, w - t}, {l - 0.1, 0}, t);
  c.bar({l - 0.1, 0}, {0, -w + t}, t);
  c.bar({0, -w + t}, {-l + 0.1, 0}, t);
}

// Crosswalk: 0.5 m stripes every metre across the road.
void draw_crosswalk(Canvas& c) {
  const double l = c.length / 2, w = c.width / 2;
  for (double b = -w + 0.25; b + 0.25 <= w + 1e-6; b += 1.0)
    c.polygon({{-l, b + 0.25}, {l, b + 0.25}, {l, b - 0.25}, {-l, b - 0.25}});
}

// The painted words, by label; nullptr for a marking that is no word.
const char* road_word(Label label) {
  switch (label) {
    case 5:
      return "STOP";
    case 6:
      return "PED";
    case 7:
      return "XING";
    case 10:
      return "25";
    case 11:
      return "35";
    case 12:
      return "40";
    default:
      return nullptr;
  }
}

// bike_word: the bike marking drawn as the word BIKE instead of the bicycle.
cv::Mat draw_class(Label label, bool bike_word, double length, double width, double texel) {
  Canvas c(length, width, texel);
  const char* word = label == kBikeLabel && bike_word ? "BIKE" : road_word(label);
  if (word != nullptr) {
    c.image = road_text(word, c);
  } else if (label == 0) {  // forward
    c.arrow({-length / 2, 0}, {length / 2, 0}, 0.3, 2.2, 0.9);
  } else if (label == 1 || label == 2) {  // left, right turn
    draw_turn_arrow(c, label == 1 ? 1.0 : -1.0);
  } else if (label == 3 || label == 4) {  // forward & left, forward & right
    draw_forward_and_turn_arrow(c, label == 3 ? 1.0 : -1.0);
  } else if (label == kBikeLabel) {
    draw_bicycle(c);
  } else if (label == 9) {
    draw_railway_crossing(c);
  } else if (label == 13) {
    draw_diamond(c);
  } else if (label == 15) {
    draw_crosswalk(c);
  } else {  // the stop line (14), and any other class a filled footprint
    c.image.setTo(cv::Scalar(255));
  }
  cv::Mat f;
  c.image.convertTo(f, CV_32F, 1.0 / 255.0);
  return f;
}

struct Light {
  float gain, sky_top, sky_horizon, haze_distance;
};
Light light_of(Illumination l) {
  switch (l) {
    case Illumination::kDay:
      return {1.0F, 0.62F, 0.86F, 350.0F};
    case Illumination::kDusk:
      return {0.42F, 0.16F, 0.42F, 160.0F};
    case Illumination::kNight:
      return {0.0F, 0.02F, 0.04F, 60.0F};
    case Illumination::kWetGlare:
      return {0.9F, 0.7F, 0.98F, 220.0F};
  }
  return {1.0F, 0.6F, 0.8F, 300.0F};
}

}  // namespace

std::optional<Illumination> illumination_from_name(std::string_view name) {
  if (name == "day") return Illumination::kDay;
  if (name == "dusk") return Illumination::kDusk;
  if (name == "night") return Illumination::kNight;
  if (name == "wet-glare") return Illumination::kWetGlare;
  return std::nullopt;
}

std::string_view illumination_name(Illumination light) {
  switch (light) {
    case Illumination::kDay:
      return "day";
    case Illumination::kDusk:
      return "dusk";
    case Illumination::kNight:
      return "night";
    case Illumination::kWetGlare:
      return "wet-glare";
  }
  return "?";
}

void occluders_at(const Conditions& conditions, double time_s, const Path& road, double car_s,
                  const Pose2& pose, double lane_width_m, std::vector<Occluder>& out) {
  out.clear();
  constexpr double kWindow = 12.0;
  const auto window = static_cast<std::int64_t>(std::floor(time_s / kWindow));
  const std::uint64_t h = hash2(window, 0x0CC1, conditions.seed);
  if (unit_from_hash(h) >= conditions.occluder_probability) return;
  const double start = static_cast<double>(window) * kWindow + 4.0 * unit_from_hash(hash_mix(h + 1));
  const double duration = 3.0 + 5.0 * unit_from_hash(hash_mix(h + 2));
  if (time_s < start || time_s > start + duration) return;
  const double phase = (time_s - start) / duration;
  const double along = 8.0 + 10.0 * unit_from_hash(hash_mix(h + 3)) + 4.0 * std::sin(phase * kPi);
  const double lane = (hash_mix(h + 4) & 1) != 0 ? lane_width_m : 0.0;
  double s = car_s + along;
  if (s > road.length()) s -= road.length();  // a closed lap goes on; a route's end holds
  const Pose2 centre = road.at(s);
  const Pose2 local = compose(inverse(pose), Pose2{centre.x - std::sin(centre.yaw) * lane,
                                                   centre.y + std::cos(centre.yaw) * lane, 0.0});
  if (local.x < 3.0) return;  // round a corner, behind the camera's view
  Occluder o;
  o.ahead_m = local.x;
  o.left_m = local.y;
  o.width_m = 1.7 + 0.3 * unit_from_hash(hash_mix(h + 5));
  o.height_m = 1.4 + 0.5 * unit_from_hash(hash_mix(h + 6));
  out.push_back(o);
}

Renderer::Renderer(const perception::CameraModel& camera, const Scenario& scenario)
    : camera_(camera), scenario_(scenario), width_(camera.width()), height_(camera.height()) {
  build_pixel_table();
  build_templates();
  const auto key = [this](double x, double y) {
    return hash2(static_cast<std::int64_t>(std::floor(x / cell_m_)),
                 static_cast<std::int64_t>(std::floor(y / cell_m_)), 0);
  };
  for (std::uint32_t i = 0; i < scenario_.strips.size(); ++i)
    strip_cells_[static_cast<std::int64_t>(key(scenario_.strips[i].x, scenario_.strips[i].y))].push_back(i);
  for (std::uint32_t i = 0; i < scenario_.markings.size(); ++i)
    marking_cells_[static_cast<std::int64_t>(key(scenario_.markings[i].x, scenario_.markings[i].y))]
        .push_back(i);
  const std::size_t pixels = static_cast<std::size_t>(width_) * height_;
  road_.resize(pixels);
  albedo_.resize(pixels);
  light_.resize(pixels);
  base_light_.resize(pixels);
  haze_.resize(pixels);
  column_bearing_.resize(static_cast<std::size_t>(width_));
  const double fx = camera.is_pinhole() ? camera.intrinsics().fx : width_ / 2.0;
  const double cx = camera.is_pinhole() ? camera.intrinsics().cx : width_ / 2.0;
  for (int c = 0; c < width_; ++c)
    column_bearing_[static_cast<std::size_t>(c)] = static_cast<float>(std::atan((cx - c) / fx));
  shaded_.create(height_, width_, CV_32F);
  near_.reserve(1 << 16);
}

void Renderer::build_pixel_table() {
  const std::size_t pixels = static_cast<std::size_t>(width_) * height_;
  ground_x_.assign(pixels, kNaN);
  ground_y_.assign(pixels, kNaN);
  footprint_x_.assign(pixels, 0.0F);
  footprint_y_.assign(pixels, 0.0F);
  fine_detail_.assign(pixels, 0.0F);
  horizon_row_.assign(static_cast<std::size_t>(width_), height_);
  nearest_ground_m_ = std::numeric_limits<double>::infinity();
  for (int r = 0; r < height_; ++r)
    for (int c = 0; c < width_; ++c) {
      Eigen::Vector2d g;
      if (!camera_.image_to_ground({c, r}, g) || !(g.x() > 0.0) || g.x() > kFarGround) continue;
      const std::size_t i = static_cast<std::size_t>(r) * width_ + c;
      ground_x_[i] = static_cast<float>(g.x());
      ground_y_[i] = static_cast<float>(g.y());
      horizon_row_[c] = std::min(horizon_row_[c], r);
      nearest_ground_m_ = std::min(nearest_ground_m_, g.x());
      view_slope_ = std::max(view_slope_, std::abs(g.y()) / g.x());
    }
  // Footprint: how far the ground point moves to the next pixel down/right.
  for (int r = 0; r < height_; ++r)
    for (int c = 0; c < width_; ++c) {
      const std::size_t i = static_cast<std::size_t>(r) * width_ + c;
      if (std::isnan(ground_x_[i])) continue;
      float fx = 0.0F, fy = 0.0F;
      for (const std::size_t j :
           {r + 1 < height_ ? i + width_ : i - width_, c + 1 < width_ ? i + 1 : i - 1}) {
        if (j >= ground_x_.size() || std::isnan(ground_x_[j])) continue;
        fx = std::max(fx, std::abs(ground_x_[j] - ground_x_[i]));
        fy = std::max(fy, std::abs(ground_y_[j] - ground_y_[i]));
      }
      if (fx == 0.0F) fx = 5.0F;  // the row below the horizon: very far
      footprint_x_[i] = fx;
      footprint_y_[i] = std::max(fy, 1e-4F);
      // Texture finer than a pixel would alias: fade it out with distance.
      fine_detail_[i] = 1.0F - smoothstep(0.02F, 0.08F, std::max(fx, fy));
    }
  if (!std::isfinite(nearest_ground_m_)) nearest_ground_m_ = 1.0;
}

void Renderer::build_templates() {
  for (std::size_t index = 0; index < templates_.size(); ++index) {
    const bool bike_word = index == kBikeWordTemplate;
    const auto label = static_cast<Label>(bike_word ? kBikeLabel : index);
    const auto size = marking_size(label, 3.5, 2);
    const cv::Mat base = draw_class(label, bike_word, size[0], size[1], kTexel);
    Template& t = templates_[index];
    t.levels.resize(kLevels * kLevels);
    for (int kr = 0; kr < kLevels; ++kr)
      for (int kc = 0; kc < kLevels; ++kc) {
        const int rows = std::max(1, base.rows >> kr), cols = std::max(1, base.cols >> kc);
        if (kr == 0 && kc == 0)
          t.levels[0] = base;
        else
          cv::resize(base, t.levels[kr * kLevels + kc], {cols, rows}, 0, 0, cv::INTER_AREA);
      }
  }
}

template <typename Visit>
void Renderer::for_each_near(double x, double y, double radius, bool markings, Visit&& visit) const {
  const auto& cells = markings ? marking_cells_ : strip_cells_;
  const auto c0x = static_cast<std::int64_t>(std::floor((x - radius) / cell_m_));
  const auto c1x = static_cast<std::int64_t>(std::floor((x + radius) / cell_m_));
  const auto c0y = static_cast<std::int64_t>(std::floor((y - radius) / cell_m_));
  const auto c1y = static_cast<std::int64_t>(std::floor((y + radius) / cell_m_));
  for (std::int64_t cx = c0x; cx <= c1x; ++cx)
    for (std::int64_t cy = c0y; cy <= c1y; ++cy) {
      const auto it = cells.find(static_cast<std::int64_t>(hash2(cx, cy, 0)));
      if (it == cells.end()) continue;
      for (const std::uint32_t i : it->second) visit(i);
    }
}

bool Renderer::image_box(const Pose2& local, double half_length, double half_width, cv::Rect& box) const {
  const double c = std::cos(local.yaw), s = std::sin(local.yaw);
  std::array<Vec2, 16> a{}, b{};
  a[0] = {local.x - c * half_length + s * half_width, local.y - s * half_length - c * half_width};
  a[1] = {local.x + c * half_length + s * half_width, local.y + s * half_length - c * half_width};
  a[2] = {local.x + c * half_length - s * half_width, local.y + s * half_length + c * half_width};
  a[3] = {local.x - c * half_length - s * half_width, local.y - s * half_length + c * half_width};
  // Keep the part the camera can see, so distortion is never evaluated far
  // outside the field of view.
  const double near = std::max(nearest_ground_m_ - 0.5, 0.3);
  int n = clip(a.data(), 4, b.data(), -1, 0, -near);
  n = clip(b.data(), n, a.data(), 1, 0, kFarGround);
  const double slope = view_slope_ + 0.1;
  n = clip(a.data(), n, b.data(), -slope, 1, 1.0);   // y <= slope x + 1
  n = clip(b.data(), n, a.data(), -slope, -1, 1.0);  // -y <= slope x + 1
  if (n < 3) return false;
  double u0 = 1e9, v0 = 1e9, u1 = -1e9, v1 = -1e9;
  for (int i = 0; i < n; ++i) {
    const Vec2 p = a[i], q = a[(i + 1) % n];
    for (int k = 0; k < 4; ++k) {  // edges bow under lens distortion
      const double t = k / 4.0;
      Eigen::Vector2d pixel;
      if (!camera_.ground_to_image({p.x + t * (q.x - p.x), p.y + t * (q.y - p.y)}, pixel)) return false;
      u0 = std::min(u0, pixel.x());
      u1 = std::max(u1, pixel.x());
      v0 = std::min(v0, pixel.y());
      v1 = std::max(v1, pixel.y());
    }
  }
  const int x0 = std::max(0, static_cast<int>(std::floor(u0)) - 2);
  const int y0 = std::max(0, static_cast<int>(std::floor(v0)) - 2);
  const int x1 = std::min(width_, static_cast<int>(std::ceil(u1)) + 3);
  const int y1 = std::min(height_, static_cast<int>(std::ceil(v1)) + 3);
  if (x1 <= x0 || y1 <= y0) return false;
  box = {x0, y0, x1 - x0, y1 - y0};
  return true;
}

void Renderer::paint_strip(const Pose2& local, const Strip& strip, const Pose2& pose, double wear) {
  cv::Rect box;
  if (!image_box(local, strip.half_length, strip.half_width, box)) return;
  ++counters_.strips_drawn;
  const auto c = static_cast<float>(std::cos(local.yaw)), s = static_cast<float>(std::sin(local.yaw));
  const auto lx = static_cast<float>(local.x), ly = static_cast<float>(local.y);
  const float hl = strip.half_length, hw = strip.half_width;
  const bool road = strip.kind == StripKind::kRoad;
  const float paint = strip.kind == StripKind::kYellowLine ? 0.55F : 0.82F;
  const double pc = std::cos(pose.yaw), ps = std::sin(pose.yaw);
  const auto level = static_cast<float>(wear * 0.5);
  for (int r = box.y; r < box.y + box.height; ++r) {
    const std::size_t row = static_cast<std::size_t>(r) * width_;
    for (int col = box.x; col < box.x + box.width; ++col) {
      const std::size_t i = row + col;
      const float gx = ground_x_[i];
      if (std::isnan(gx)) continue;
      const float dx = gx - lx, dy = ground_y_[i] - ly;
      const float a = c * dx + s * dy, b = -s * dx + c * dy;
      const float fb = std::abs(s) * footprint_x_[i] + std::abs(c) * footprint_y_[i];
      // Strips abut end to end: a hard edge along them leaves no seam
      // between neighbours; across, the edge is antialiased.
      if (std::abs(a) > hl) continue;
      const float cover = std::clamp((hw - std::abs(b)) / fb + 0.5F, 0.0F, 1.0F);
      if (cover <= 0.0F) continue;
      if (road) {
        road_[i] = std::max(road_[i], cover);
        continue;
      }
      float amount = cover;
      if (level > 0.0F) {
        const double wx = pose.x + pc * gx - ps * ground_y_[i];
        const double wy = pose.y + ps * gx + pc * ground_y_[i];
        const float n = value_noise(wx * 8.0, wy * 8.0, kWearSeed);
        amount *= smoothstep(level - 0.2F, level, n);
      }
      albedo_[i] += (paint - albedo_[i]) * amount;
    }
  }
}

void Renderer::paint_marking(const Pose2& local, const Marking& marking, const Pose2& pose, double wear) {
  const double hl = marking.length_m / 2, hw = marking.width_m / 2;
  cv::Rect box;
  if (!image_box(local, hl, hw, box)) return;
  ++counters_.markings_drawn;
  const bool bike_word =
      marking.label == kBikeLabel && unit_from_hash(hash2(marking.id, 0xB1CE, kWearSeed)) < 0.5F;
  const Template& t =
      templates_[bike_word ? kBikeWordTemplate : std::min<std::size_t>(marking.label, kClassCount - 1)];
  const auto c = static_cast<float>(std::cos(local.yaw)), s = static_cast<float>(std::sin(local.yaw));
  const auto lx = static_cast<float>(local.x), ly = static_cast<float>(local.y);
  const double pc = std::cos(pose.yaw), ps = std::sin(pose.yaw);
  // Each marking has its own wear, the same on every pass.
  const float level = static_cast<float>(wear) * unit_from_hash(hash2(marking.id, 0x3EA2, kWearSeed));
  const float paint = 0.82F;
  const auto fhl = static_cast<float>(hl), fhw = static_cast<float>(hw);
  for (int r = box.y; r < box.y + box.height; ++r) {
    const std::size_t row = static_cast<std::size_t>(r) * width_;
    for (int col = box.x; col < box.x + box.width; ++col) {
      const std::size_t i = row + col;
      const float gx = ground_x_[i];
      if (std::isnan(gx)) continue;
      const float dx = gx - lx, dy = ground_y_[i] - ly;
      const float a = c * dx + s * dy, b = -s * dx + c * dy;
      const float fa = std::abs(c) * footprint_x_[i] + std::abs(s) * footprint_y_[i];
      const float fb = std::abs(s) * footprint_x_[i] + std::abs(c) * footprint_y_[i];
      if (std::abs(a) > fhl + fa || std::abs(b) > fhw + fb) continue;
      const int kr = mip_level(fa, kTexel), kc = mip_level(fb, kTexel);
      const cv::Mat& m = t.levels[kr * kLevels + kc];
      const float tr = (fhl - a) / (2 * fhl) * static_cast<float>(m.rows) - 0.5F;
      const float tc = (fhw - b) / (2 * fhw) * static_cast<float>(m.cols) - 0.5F;
      float amount = sample_bilinear(m, tr, tc);
      if (amount <= 0.002F) continue;
      if (level > 0.0F) {
        const double wx = pose.x + pc * gx - ps * ground_y_[i];
        const double wy = pose.y + ps * gx + pc * ground_y_[i];
        const float n = 0.7F * value_noise(wx * 7.0, wy * 7.0, kWearSeed) +
                        0.3F * value_noise(wx * 25.0, wy * 25.0, kWearSeed + 1);
        amount *= smoothstep(level - 0.2F, level, n);
      }
      albedo_[i] += (paint - albedo_[i]) * amount;
    }
  }
}

void Renderer::render(const Pose2& pose, double speed_mps, const Conditions& conditions, std::uint64_t frame,
                      std::span<const Occluder> occluders, cv::Mat& image) {
  ++counters_.frames;
  const Pose2 to_vehicle = inverse(pose);
  cover_road(pose, to_vehicle);
  cache_light(conditions.light);
  shade_ground(pose, conditions);
  paint_lines_and_markings(pose, to_vehicle, conditions.paint_wear);
  shade_image(pose, conditions);
  draw_vehicles(occluders, conditions.light);
  blur_motion(speed_mps, conditions);
  expose(conditions, frame, image);
}

// 1. Road surface coverage; near_ keeps the strips near the view for step 3.
void Renderer::cover_road(const Pose2& pose, const Pose2& to_vehicle) {
  const double pc = std::cos(pose.yaw), ps = std::sin(pose.yaw);
  std::fill(road_.begin(), road_.end(), 0.0F);
  near_.clear();
  for_each_near(pose.x + pc * kStripRange / 2, pose.y + ps * kStripRange / 2, kStripRange / 2 + cell_m_,
                false, [&](std::uint32_t i) { near_.push_back(i); });
  for (const std::uint32_t i : near_) {
    const Strip& strip = scenario_.strips[i];
    if (strip.kind != StripKind::kRoad) continue;
    const Pose2 local = compose(to_vehicle, Pose2{strip.x, strip.y, strip.heading});
    if (local.x < -5.0 || local.x > kStripRange) continue;
    paint_strip(local, strip, pose, 0.0);
  }
}

// 2a. Light and haze per ground pixel, recomputed when the light changes.
void Renderer::cache_light(Illumination illumination) {
  if (cached_light_ == static_cast<int>(illumination)) return;
  cached_light_ = static_cast<int>(illumination);
  const Light light = light_of(illumination);
  const bool night = illumination == Illumination::kNight;
  const std::size_t pixels = road_.size();
  for (std::size_t i = 0; i < pixels; ++i) {
    const float gx = ground_x_[i];
    if (std::isnan(gx)) continue;
    float l = light.gain;
    if (night) {
      // Headlights: a cone ahead, falling off with distance.
      const float spread = ground_y_[i] / (0.45F * gx + 1.2F);
      l = 0.03F + 1.5F * std::exp(-spread * spread) / (1.0F + (gx / 16.0F) * (gx / 16.0F));
    }
    base_light_[i] = l;
    haze_[i] = 1.0F - std::exp(-gx / light.haze_distance);
  }
}

// 2b. Base texture and light, per ground pixel.
void Renderer::shade_ground(const Pose2& pose, const Conditions& conditions) {
  const bool wet = conditions.light == Illumination::kWetGlare;
  const bool sunny = conditions.light == Illumination::kDay || wet;
  const double pc = std::cos(pose.yaw), ps = std::sin(pose.yaw);
  const std::size_t pixels = road_.size();
  const bool cast_shadows = sunny && conditions.shadows;
  for (std::size_t i = 0; i < pixels; ++i) {
    const float gx = ground_x_[i];
    if (std::isnan(gx)) continue;
    const float gy = ground_y_[i];
    const double wx = pose.x + pc * gx - ps * gy;
    const double wy = pose.y + ps * gx + pc * gy;
    const float fine = fine_detail_[i];
    const float road = road_[i];
    float albedo = 0.0F;
    if (road > 0.0F) {
      float asphalt = 0.24F + 0.05F * (noise_(wx * 1.4 + 101.3, wy * 1.4 + 57.1) - 0.5F);
      if (fine > 0.0F) asphalt += fine * 0.09F * (noise_(wx * 25.0, wy * 25.0) - 0.5F);
      if (wet) asphalt *= 0.62F;
      albedo = asphalt * road;
    }
    if (road < 1.0F) {
      float verge = 0.40F + 0.12F * (noise_(wx * 0.35 + 511.7, wy * 0.35 + 233.9) - 0.5F);
      if (fine > 0.0F) verge += fine * 0.08F * (noise_(wx * 6.0 + 733.3, wy * 6.0 + 911.1) - 0.5F);
      albedo += verge * (1.0F - road);
    }
    albedo_[i] = albedo;
    float l = base_light_[i];
    if (cast_shadows) {
      // Crowns 4 m across; ragged edges only where a pixel is small enough.
      float n = noise_(wx * 0.25 + 317.5, wy * 0.25 + 421.5);
      if (n > 0.6F) {
        if (fine > 0.0F) n += 0.12F * fine * (noise_(wx * 0.9 + 619.5, wy * 0.9 + 127.5) - 0.5F);
        l *= 1.0F - 0.55F * smoothstep(0.70F, 0.75F, n);
      }
    }
    light_[i] = l;
  }
}

// 3. Lines and markings.
void Renderer::paint_lines_and_markings(const Pose2& pose, const Pose2& to_vehicle, double wear) {
  const double pc = std::cos(pose.yaw), ps = std::sin(pose.yaw);
  for (const std::uint32_t i : near_) {
    const Strip& strip = scenario_.strips[i];
    if (strip.kind == StripKind::kRoad) continue;
    const Pose2 local = compose(to_vehicle, Pose2{strip.x, strip.y, strip.heading});
    if (local.x < -2.0 || local.x > kStripRange) continue;
    paint_strip(local, strip, pose, wear);
  }
  near_.clear();
  for_each_near(pose.x + pc * kMarkingRange / 2, pose.y + ps * kMarkingRange / 2, kMarkingRange / 2 + cell_m_,
                true, [&](std::uint32_t i) { near_.push_back(i); });
  for (const std::uint32_t i : near_) {
    const Marking& m = scenario_.markings[i];
    const Pose2 local = compose(to_vehicle, Pose2{m.x, m.y, m.heading});
    if (local.x < -8.0 || local.x > kMarkingRange) continue;
    paint_marking(local, m, pose, wear);
  }
}

// 4. Light, haze, glare and the sky.
void Renderer::shade_image(const Pose2& pose, const Conditions& conditions) {
  const Light light = light_of(conditions.light);
  const bool wet = conditions.light == Illumination::kWetGlare;
  const bool night = conditions.light == Illumination::kNight;
  const bool pinhole = camera_.is_pinhole();
  const double fx = pinhole ? camera_.intrinsics().fx : width_ / 2.0;
  const double cx = pinhole ? camera_.intrinsics().cx : width_ / 2.0;
  const double sun_azimuth = 2 * kPi * unit_from_hash(hash_mix(conditions.seed ^ 0x5011));
  const double sun_bearing = wrap_angle(sun_azimuth - pose.yaw);
  const float sun_col = static_cast<float>(cx + fx * std::tan(sun_bearing));
  const bool glare = wet && std::abs(sun_bearing) < 0.6;
  for (int r = 0; r < height_; ++r) {
    float* out = shaded_.ptr<float>(r);
    for (int c = 0; c < width_; ++c) {
      const std::size_t i = static_cast<std::size_t>(r) * width_ + c;
      const float gx = ground_x_[i];
      if (std::isnan(gx)) {
        // Sky, with a skyline of buildings fixed to the world's bearings.
        const int horizon = horizon_row_[c] < height_ ? horizon_row_[c] : height_;
        const float t = horizon > 0 ? static_cast<float>(r) / static_cast<float>(horizon) : 1.0F;
        float v = light.sky_top + (light.sky_horizon - light.sky_top) * std::min(t, 1.0F);
        const double bearing = pose.yaw + column_bearing_[static_cast<std::size_t>(c)];
        const auto building = static_cast<std::int64_t>(std::floor(bearing * 40.0));
        const std::uint64_t h = hash2(building, 0, kSkylineSeed);
        const float tall = 8.0F + 50.0F * unit_from_hash(h);
        if (static_cast<float>(horizon - r) < tall)
          v = (night ? 0.03F : light.gain * (0.28F + 0.2F * unit_from_hash(hash_mix(h))));
        out[c] = v;
        continue;
      }
      float v = albedo_[i] * light_[i];
      if (glare) {
        const float d = (static_cast<float>(c) - sun_col) / 90.0F;
        v += 0.7F * std::exp(-d * d) * std::min(gx / 40.0F, 1.0F);
      }
      if (wet) v += 0.05F;
      out[c] = v + (light.sky_horizon - v) * haze_[i];
    }
  }
}

// 5. Vehicles ahead hide the road.
void Renderer::draw_vehicles(std::span<const Occluder> occluders, Illumination illumination) {
  const Light light = light_of(illumination);
  const bool night = illumination == Illumination::kNight;
  for (const Occluder& o : occluders) {
    Eigen::Vector2d left, right;
    if (!camera_.ground_to_image({o.ahead_m, o.left_m + o.width_m / 2}, left) ||
        !camera_.ground_to_image({o.ahead_m, o.left_m - o.width_m / 2}, right))
      continue;
    const double px_per_m = (right.x() - left.x()) / o.width_m;
    const double bottom = (left.y() + right.y()) / 2;
    const cv::Rect body(
        cv::Point(static_cast<int>(left.x()), static_cast<int>(bottom - o.height_m * px_per_m)),
        cv::Point(static_cast<int>(right.x()), static_cast<int>(bottom)));
    const float g = night ? 0.02F : light.gain;
    cv::rectangle(shaded_, body, cv::Scalar(0.09 * g + 0.01), cv::FILLED);
    const int bh = body.height;
    cv::rectangle(shaded_, cv::Rect(body.x + body.width / 8, body.y + bh / 10, body.width * 3 / 4, bh / 3),
                  cv::Scalar(0.2 * g + 0.02), cv::FILLED);  // rear window
    const float lamp = night ? 0.95F : 0.3F * g;
    cv::rectangle(shaded_, cv::Rect(body.x + 2, body.y + bh / 2, body.width / 7, bh / 8), cv::Scalar(lamp),
                  cv::FILLED);
    cv::rectangle(shaded_, cv::Rect(body.x + body.width * 6 / 7 - 2, body.y + bh / 2, body.width / 7, bh / 8),
                  cv::Scalar(lamp), cv::FILLED);
  }
}

// 6. Motion blur: the near road slides down the image while exposed.
void Renderer::blur_motion(double speed_mps, const Conditions& conditions) {
  const double travel = speed_mps * conditions.exposure_s;  // metres during exposure
  const int first_near_row = height_ / 2;
  const std::size_t centre = static_cast<std::size_t>(height_ - 1) * width_ + width_ / 2;
  const int blur = static_cast<int>(std::lround(travel / std::max(1e-3F, footprint_x_[centre])));
  if (blur >= 2) {
    cv::Mat near_rows = shaded_.rowRange(first_near_row, height_);
    cv::blur(near_rows, near_rows, {1, std::min(blur, 9)}, {-1, -1}, cv::BORDER_REPLICATE);
  }
}

// 7. Sensor noise (more gain in low light, more noise) and quantisation.
void Renderer::expose(const Conditions& conditions, std::uint64_t frame, cv::Mat& image) {
  const bool night = conditions.light == Illumination::kNight;
  if (image.rows != height_ || image.cols != width_ || image.type() != CV_8UC1)
    image.create(height_, width_, CV_8UC1);
  const float sigma =
      static_cast<float>(conditions.noise_sigma) * (night                                     ? 3.0F
                                                    : conditions.light == Illumination::kDusk ? 2.0F
                                                                                              : 1.0F);
  std::uint64_t state = hash2(static_cast<std::int64_t>(frame), 0x4015E, conditions.seed);
  const float gain = night ? 2.2F : conditions.light == Illumination::kDusk ? 1.6F : 1.0F;
  for (int r = 0; r < height_; ++r) {
    const float* in = shaded_.ptr<float>(r);
    std::uint8_t* out = image.ptr<std::uint8_t>(r);
    for (int c = 0; c < width_; ++c) {
      state = hash_mix(state);
      // Sum of four uniforms: close enough to Gaussian for sensor noise.
      const float u = static_cast<float>((state & 0xFFFF) + ((state >> 16) & 0xFFFF) +
                                         ((state >> 32) & 0xFFFF) + (state >> 48)) *
                          (1.0F / 65536.0F) -
                      2.0F;
      const float v = in[c] * gain * 255.0F + sigma * 1.732F * u;
      out[c] = static_cast<std::uint8_t>(std::clamp(v + 0.5F, 0.0F, 255.0F));
    }
  }
}

void Renderer::visible_markings(const Pose2& pose, double min_ahead_m, double max_ahead_m,
                                std::span<const Occluder> occluders, std::vector<VisibleMarking>& out) const {
  out.clear();
  const Pose2 to_vehicle = inverse(pose);
  const double pc = std::cos(pose.yaw), ps = std::sin(pose.yaw);
  near_.clear();
  for_each_near(pose.x + pc * max_ahead_m / 2, pose.y + ps * max_ahead_m / 2, max_ahead_m / 2 + cell_m_, true,
                [&](std::uint32_t i) { near_.push_back(i); });
  std::sort(near_.begin(), near_.end());
  for (const std::uint32_t i : near_) {
    const Marking& m = scenario_.markings[i];
    const Pose2 local = compose(to_vehicle, Pose2{m.x, m.y, m.heading});
    if (local.x < min_ahead_m || local.x > max_ahead_m) continue;
    const double c = std::cos(local.yaw), s = std::sin(local.yaw);
    const double hl = m.length_m / 2, hw = m.width_m / 2;
    // near-left, near-right, far-right, far-left (a along, b left)
    const double corners[4][2] = {{-hl, hw}, {-hl, -hw}, {hl, -hw}, {hl, hw}};
    VisibleMarking v;
    v.id = m.id;
    v.label = m.label;
    v.ahead_m = local.x;
    bool inside = true;
    for (int k = 0; k < 4 && inside; ++k) {
      const double a = corners[k][0], b = corners[k][1];
      Eigen::Vector2d pixel;
      inside = camera_.ground_to_image({local.x + c * a - s * b, local.y + s * a + c * b}, pixel) &&
               pixel.x() >= 0 && pixel.y() >= 0 && pixel.x() <= width_ - 1.0 && pixel.y() <= height_ - 1.0;
      v.quad[k] = {static_cast<float>(pixel.x()), static_cast<float>(pixel.y())};
    }
    if (!inside) continue;
    // Hidden when its centre is behind a vehicle (the vehicle is nearer).
    bool hidden = false;
    for (const Occluder& o : occluders)
      if (local.x > o.ahead_m && std::abs(local.y * o.ahead_m / local.x - o.left_m) < o.width_m / 2 + 0.3)
        hidden = true;
    if (!hidden) out.push_back(v);
  }
}

}  // namespace markloop::sim
