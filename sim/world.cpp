#include "sim/world.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <unordered_map>

#include "sim/town.hpp"

namespace markloop::sim {

namespace {

constexpr double kPi = std::numbers::pi;

// Index by Label. The first 14 weights are the mix the simulator has always
// drawn (arrows dominate); the legacy scenarios keep it exactly, so their
// worlds do not change with the renderer.
constexpr std::array<double, kClassCount> kLegacyWeights = {
    0.18, 0.15, 0.10, 0.05, 0.05,  // forward, leftturn, rightturn, forward&left, forward&right
    0.05, 0.05, 0.05,              // stop, ped, xing
    0.08, 0.02,                    // bike, rail
    0.05, 0.10, 0.05,              // 25, 35, 40
    0.02,                          // diamond
    0.0,  0.0,                     // stopline, crosswalk
};

std::uint64_t mix(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31);
}

// Arc of a circle from angle a0 to a1 (radians), centre (cx, cy).
void add_arc(Path& path, double cx, double cy, double radius, double a0, double a1) {
  const int steps = std::max(2, static_cast<int>(std::abs(a1 - a0) * radius / 0.5));
  for (int i = 0; i <= steps; ++i) {
    const double a = a0 + (a1 - a0) * i / steps;
    path.add_point(cx + radius * std::cos(a), cy + radius * std::sin(a));
  }
}

void add_line(Path& path, double x0, double y0, double x1, double y1) {
  const int steps = std::max(1, static_cast<int>(std::hypot(x1 - x0, y1 - y0) / 0.5));
  for (int i = 0; i <= steps; ++i) path.add_point(x0 + (x1 - x0) * i / steps, y0 + (y1 - y0) * i / steps);
}

// Counter-clockwise rounded rectangle starting mid bottom edge.
Path rounded_rectangle(double width, double height, double radius) {
  Path p;
  const double w = width / 2, h = height / 2, r = radius;
  add_line(p, 0, -h, w - r, -h);
  add_arc(p, w - r, -h + r, r, -kPi / 2, 0);
  add_line(p, w, -h + r, w, h - r);
  add_arc(p, w - r, h - r, r, 0, kPi / 2);
  add_line(p, w - r, h, -w + r, h);
  add_arc(p, -w + r, h - r, r, kPi / 2, kPi);
  add_line(p, -w, h - r, -w, -h + r);
  add_arc(p, -w + r, -h + r, r, kPi, 1.5 * kPi);
  add_line(p, -w + r, -h, 0, -h);
  return p;
}

// The point `left` metres to the left of a pose (to its right when
// negative), heading as the pose does.
Pose2 beside(const Pose2& p, double left) {
  return {p.x - std::sin(p.yaw) * left, p.y + std::cos(p.yaw) * left, p.yaw};
}

// A closed tour through street corners, with every corner rounded. Returns
// the arc length where each street's straight part starts (after the
// corner) and a key naming that street, so markings can be laid per street.
struct StreetStart {
  double s;
  std::uint64_t street_key;
};
Path rounded_tour(const std::vector<std::array<double, 2>>& corners, double radius,
                  std::vector<StreetStart>& streets) {
  Path p;
  const std::size_t n = corners.size();
  // Start in the middle of the first street so the tour closes on a straight.
  const auto& c0 = corners[0];
  const auto& c1 = corners[1];
  std::array<double, 2> last = {(c0[0] + c1[0]) / 2, (c0[1] + c1[1]) / 2};
  p.add_point(last[0], last[1]);
  for (std::size_t k = 1; k <= n; ++k) {
    const auto& prev = corners[k - 1];
    const auto& here = corners[k % n];
    const auto& next = corners[(k + 1) % n];
    const double in_x = here[0] - prev[0], in_y = here[1] - prev[1];
    const double out_x = next[0] - here[0], out_y = next[1] - here[1];
    const double in_len = std::hypot(in_x, in_y), out_len = std::hypot(out_x, out_y);
    const double ux = in_x / in_len, uy = in_y / in_len, vx = out_x / out_len, vy = out_y / out_len;
    const double turn = std::atan2(ux * vy - uy * vx, ux * vx + uy * vy);
    const double cut = std::abs(turn) < 1e-6 ? 0.0 : radius * std::tan(std::abs(turn) / 2);
    add_line(p, last[0], last[1], here[0] - ux * cut, here[1] - uy * cut);
    last = {here[0] + vx * cut, here[1] + vy * cut};
    if (cut > 0) {
      const double side = turn > 0 ? 1.0 : -1.0;  // left turn: centre on the left
      const double cx = here[0] - ux * cut - uy * radius * side;
      const double cy = here[1] - uy * cut + ux * radius * side;
      const double start = std::atan2((here[1] - uy * cut) - cy, (here[0] - ux * cut) - cx);
      add_arc(p, cx, cy, radius, start, start + turn);
    }
    // The street from `here` to `next`, named by its two ends (direction matters).
    const auto q = [](double v) { return static_cast<std::uint64_t>(std::llround(v + 1e6)); };
    streets.push_back({p.length(), mix(q(here[0]) * 31 + q(here[1]) * 17 + q(next[0]) * 7 + q(next[1]))});
    if (k == n) {
      streets.pop_back();
      add_line(p, last[0], last[1], (c0[0] + c1[0]) / 2, (c0[1] + c1[1]) / 2);
    }
  }
  return p;
}

// The route is judged a metre at a time.
constexpr double kStep = 1.0;
constexpr double kMinGap = 30.0;  // closer along the route is the same pass
constexpr double kLineHalfWidth = 0.075;

// A cell of a spatial hash of the route's samples.
std::int64_t cell_key(std::int64_t cx, std::int64_t cy) {
  return cx * 73856093LL ^ cy * 19349663LL;
}

// Per metre of the route: whether it revisits an earlier stretch, beside
// it (within `radius`), not before or after it, heading within 45 degrees.
std::vector<std::uint8_t> find_revisits(const std::vector<Pose2>& poses, double radius) {
  const std::size_t samples = poses.size();
  std::vector<std::uint8_t> revisit(samples, 0);
  const double cell = std::max(radius, 1.0);
  std::unordered_map<std::int64_t, std::vector<std::uint32_t>> grid;
  for (std::size_t i = 0; i < samples; ++i) {
    const Pose2& p = poses[i];
    const auto cx = static_cast<std::int64_t>(std::floor(p.x / cell));
    const auto cy = static_cast<std::int64_t>(std::floor(p.y / cell));
    for (std::int64_t dx = -1; dx <= 1 && !revisit[i]; ++dx)
      for (std::int64_t dy = -1; dy <= 1 && !revisit[i]; ++dy) {
        const auto it = grid.find(cell_key(cx + dx, cy + dy));
        if (it == grid.end()) continue;
        for (const std::uint32_t j : it->second) {
          if (static_cast<double>(i - j) * kStep < kMinGap) continue;
          const Pose2& q = poses[j];
          const double ex = p.x - q.x, ey = p.y - q.y;
          const double along = ex * std::cos(q.yaw) + ey * std::sin(q.yaw);
          const double across = -ex * std::sin(q.yaw) + ey * std::cos(q.yaw);
          if (std::abs(along) <= 0.6 * kStep && std::abs(across) < radius &&
              std::cos(wrap_angle(p.yaw - q.yaw)) > std::cos(kPi / 4)) {
            revisit[i] = 1;
            break;
          }
        }
      }
    grid[cell_key(cx, cy)].push_back(static_cast<std::uint32_t>(i));
  }
  return revisit;
}

// Per metre of the route: whether it lies inside an intersection, where
// another stretch of it crosses (heading 45 to 135 degrees off). Real roads
// paint no markings there: they would lie across the other road's.
std::vector<std::uint8_t> find_crossings(const std::vector<Pose2>& poses, int lanes, double w) {
  const std::size_t samples = poses.size();
  std::vector<std::uint8_t> crossing(samples, 0);
  const double reach = lanes * w / 2 + 0.6;      // the road's half width, shoulders included
  const double to_centre = (lanes - 1) * w / 2;  // from the route's lane to the road's middle
  std::vector<Pose2> centres(samples);
  std::unordered_map<std::int64_t, std::vector<std::uint32_t>> grid;
  const auto cell_of = [&](double v) { return static_cast<std::int64_t>(std::floor(v / reach)); };
  for (std::size_t i = 0; i < samples; ++i) {
    centres[i] = beside(poses[i], to_centre);
    grid[cell_key(cell_of(centres[i].x), cell_of(centres[i].y))].push_back(static_cast<std::uint32_t>(i));
  }
  for (std::size_t i = 0; i < samples; ++i) {
    const auto& [x, y, yaw] = centres[i];
    for (std::int64_t dx = -1; dx <= 1 && !crossing[i]; ++dx)
      for (std::int64_t dy = -1; dy <= 1 && !crossing[i]; ++dy) {
        const auto it = grid.find(cell_key(cell_of(x) + dx, cell_of(y) + dy));
        if (it == grid.end()) continue;
        for (const std::uint32_t j : it->second) {
          const double apart = std::abs(static_cast<double>(i) - static_cast<double>(j)) * kStep;
          if (apart < kMinGap || std::hypot(centres[j].x - x, centres[j].y - y) >= reach) continue;
          if (std::abs(std::cos(wrap_angle(centres[j].yaw - yaw))) < std::cos(kPi / 4)) {
            crossing[i] = 1;
            break;
          }
        }
      }
  }
  return crossing;
}

// The route a metre at a time, and what each metre is.
struct RouteSamples {
  std::vector<Pose2> poses;
  std::vector<std::uint8_t> revisit;   // runs along an earlier stretch
  std::vector<std::uint8_t> crossing;  // inside an intersection

  RouteSamples(const Path& road, const WorldConfig& config, int lanes) {
    const auto samples = static_cast<std::size_t>(road.length() / kStep) + 1;
    poses.resize(samples);
    for (std::size_t i = 0; i < samples; ++i) poses[i] = road.at(static_cast<double>(i) * kStep);
    revisit = find_revisits(poses, config.revisit_radius_m);
    crossing = find_crossings(poses, lanes, config.lane_width_m);
  }
  std::size_t size() const { return poses.size(); }
  // The sample nearest arc length s.
  std::size_t at(double s) const {
    const std::size_t samples = poses.size();
    const auto i = static_cast<std::size_t>(std::clamp(s / kStep, 0.0, double(samples - 1)) + 0.5);
    return std::min(i, samples - 1);
  }
  bool is_new(double s) const { return revisit[at(s)] == 0; }
  // Whether a marking `half_length` either side of s, and a metre more,
  // stays clear of every intersection.
  bool clear_of_crossings(double s, double half_length) const {
    for (std::size_t i = at(s - half_length - 1.0); i <= at(s + half_length + 1.0); ++i)
      if (crossing[i]) return false;
    return true;
  }
};

// A line strip and its metre of route, for the markings' check against
// lines of other stretches of road.
struct LinePiece {
  std::size_t strip;
  std::size_t sample;
};

// An oriented strip `left` of p. On a curve a strip off the centre line
// spans a longer arc than its metre of route: lengthen it by the curvature
// so neighbours still overlap at their outer edges.
void add_strip(std::vector<Strip>& strips, const Pose2& p, double curvature, double left, double half_length,
               double half_width, StripKind kind) {
  const double stretch = 1.0 + std::abs(curvature) * (std::abs(left) + half_width);
  const Pose2 at = beside(p, left);
  strips.push_back(
      {at.x, at.y, at.yaw, static_cast<float>(half_length * stretch), static_cast<float>(half_width), kind});
}

// Road surface and lines along the new metres of the route; returns the
// line strips.
std::vector<LinePiece> lay_road(Scenario& scenario, const RouteSamples& route, int lanes, double w) {
  const Path& road = scenario.road;
  const std::size_t samples = route.size();
  constexpr double kDashPeriod = 12.0, kDashLength = 3.0;  // US practice: 3 m line, 9 m gap
  std::vector<LinePiece> line_pieces;
  double curvature = 0.0;
  const auto line_at = [&](std::size_t i, const Pose2& p, double left, double half_length, StripKind kind) {
    line_pieces.push_back({scenario.strips.size(), i});
    add_strip(scenario.strips, p, curvature, left, half_length, kLineHalfWidth, kind);
  };
  for (std::size_t i = 0; i + 1 < samples; ++i) {
    if (route.revisit[i]) continue;
    const double s = (static_cast<double>(i) + 0.5) * kStep;
    const Pose2 p = road.at(s);
    curvature = wrap_angle(road.at(s + kStep).yaw - road.at(s - kStep).yaw) / (2 * kStep);
    const double half = kStep / 2 + 0.05;  // overlap: no seams
    // Road surface in 2 m pieces (fewer, larger boxes to draw).
    if (i % 2 == 0 && (i + 1 >= samples || !route.revisit[i + 1]))
      add_strip(scenario.strips, road.at(s + kStep / 2), curvature, (lanes - 1) * w / 2, kStep + 0.05,
                lanes * w / 2 + 0.6, StripKind::kRoad);
    else if (i % 2 == 0 || (i > 0 && route.revisit[i - 1]))
      add_strip(scenario.strips, p, curvature, (lanes - 1) * w / 2, half, lanes * w / 2 + 0.6,
                StripKind::kRoad);
    line_at(i, p, -w / 2 + 0.1, half, StripKind::kWhiteLine);              // edge
    line_at(i, p, (lanes - 0.5) * w - 0.1, half, StripKind::kYellowLine);  // centre
    if (std::fmod(s, kDashPeriod) < kDashLength)
      for (int k = 0; k + 1 < lanes; ++k) line_at(i, p, (k + 0.5) * w, half - 0.05, StripKind::kWhiteLine);
  }
  return line_pieces;
}

struct RowSegment {
  double begin_s;
  double end_s;
  std::uint64_t seed;  // the row layout of this stretch
};

// A marking's own frame: along and across it from its centre.
struct MarkingFrame {
  explicit MarkingFrame(const Pose2& p) : at(p), c(std::cos(p.yaw)), sn(std::sin(p.yaw)) {}
  std::array<double, 2> offset(double x, double y) const {
    return {(x - at.x) * c + (y - at.y) * sn, -(x - at.x) * sn + (y - at.y) * c};
  }
  Pose2 at;
  double c, sn;
};

// Lays the marking rows along the road. Each segment draws its rows from
// its own generator, so segments with the same seed look the same
// (repeated city blocks).
class MarkingLayer {
 public:
  MarkingLayer(Scenario& scenario, const WorldConfig& config, const std::array<double, kClassCount>& weights,
               const RouteSamples& route, std::vector<LinePiece> line_pieces)
      : scenario_(scenario),
        config_(config),
        route_(route),
        line_pieces_(std::move(line_pieces)),
        lanes_(std::max(1, config.lanes)),
        w_(config.lane_width_m),
        pick_class_(weights.begin(), weights.end()),
        crosswalk_(*perception::marking_class_from_name("crosswalk")),
        laid_in_lane_(static_cast<std::size_t>(lanes_),
                      {std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity()}) {}

  void lay(const RowSegment& segment) {
    std::mt19937_64 rng(segment.seed);
    std::uniform_real_distribution<double> spacing(config_.row_spacing_min_m, config_.row_spacing_max_m);
    const double end = std::min(segment.end_s, scenario_.road.length() - 5.0);
    for (double s = segment.begin_s + spacing(rng) / 2; s < end; s += spacing(rng)) lay_row(s, rng);
  }

 private:
  // A marking is not painted over, nor within kMarkingGap of, one laid
  // before in its lane (a crosswalk: in any lane): rows a few metres apart
  // would otherwise lay 6 m arrows over each other, and a crosswalk over
  // the row beside it.
  static constexpr double kMarkingGap = 1.0;
  // A marking lies flat in its lane: the lane straight under it (its
  // centre strays under kMaxBend from the marking's axis) and no line of
  // another stretch of road (a corner's arc, a road joining at a shallow
  // angle) within kLineClearance of it. Real roads paint markings on
  // straight approaches, not round a corner, where a 6 m arrow's ends stray
  // 0.2 m and more towards its lane's lines and the corner's arc crosses
  // the next street.
  static constexpr double kMaxBend = 0.1, kLineClearance = 0.3;
  static constexpr double kOwnStretch = 2.0;  // its own lines (a stop line meets one) are judged by the bend

  void lay_row(double s, std::mt19937_64& rng);
  bool clear_of_lanes(int first, int last, const std::array<double, 2>& stretch) const;
  bool lies_flat(double s, double left, const Pose2& at, double half_length, double half_width) const;
  bool line_near(const MarkingFrame& marking, std::size_t first, std::size_t last, double half_length,
                 double half_width) const;

  Scenario& scenario_;
  const WorldConfig& config_;
  const RouteSamples& route_;
  const std::vector<LinePiece> line_pieces_;
  const int lanes_;
  const double w_;
  std::uniform_real_distribution<double> unit_{0.0, 1.0};
  std::discrete_distribution<int> pick_class_;
  const Label crosswalk_;
  // The stretch along the route of the last marking laid in each lane.
  std::vector<std::array<double, 2>> laid_in_lane_;
  std::uint32_t next_id_ = 0;
};

// One row at arc length s: per lane, a marking or none. The random draws
// stay as if every marking were laid: the rows after one left out (in an
// intersection, too close to another) are the same with or without it.
void MarkingLayer::lay_row(double s, std::mt19937_64& rng) {
  const Pose2 centre = scenario_.road.at(s);
  const bool lay = route_.is_new(s);
  bool any = false;
  for (int lane = 0; lane < lanes_; ++lane) {
    const bool last_chance = lane == lanes_ - 1 && !any;
    if (!last_chance && unit_(rng) >= config_.marking_probability) continue;
    any = true;
    const auto label = static_cast<Label>(pick_class_(rng));
    if (!lay) continue;
    const auto size = marking_size(label, w_, lanes_);
    const std::array<double, 2> stretch{s - size[0] / 2, s + size[0] / 2};  // along the route
    const int first_lane = label == crosswalk_ ? 0 : lane;
    const int last_lane = label == crosswalk_ ? lanes_ - 1 : lane;
    // A crosswalk spans the whole road: it takes the row.
    const double left = label == crosswalk_ ? (lanes_ - 1) * w_ / 2 : lane * w_;
    const Pose2 at = beside(centre, left);
    if (!route_.clear_of_crossings(s, size[0] / 2) || !clear_of_lanes(first_lane, last_lane, stretch) ||
        !lies_flat(s, left, at, size[0] / 2, size[1] / 2)) {
      if (label == crosswalk_) break;
      continue;
    }
    for (int k = first_lane; k <= last_lane; ++k) laid_in_lane_[static_cast<std::size_t>(k)] = stretch;
    Marking m;
    m.id = next_id_++;
    m.label = label;
    m.x = at.x;
    m.y = at.y;
    m.heading = at.yaw;
    m.lane = label == crosswalk_ ? 0 : lane;
    m.length_m = size[0];
    m.width_m = size[1];
    scenario_.markings.push_back(m);
    if (label == crosswalk_) break;
  }
}

bool MarkingLayer::clear_of_lanes(int first, int last, const std::array<double, 2>& stretch) const {
  for (int k = first; k <= last; ++k) {
    const auto& [begin, end] = laid_in_lane_[static_cast<std::size_t>(k)];
    if (stretch[1] + kMarkingGap > begin && stretch[0] - kMarkingGap < end) return false;
  }
  return true;
}

// Whether a marking's footprint (centre, heading, half sizes) lies flat in
// its lane.
bool MarkingLayer::lies_flat(double s, double left, const Pose2& at, double half_length,
                             double half_width) const {
  const MarkingFrame marking(at);
  const std::size_t first = route_.at(s - half_length), last = route_.at(s + half_length);
  for (std::size_t i = first; i <= last; ++i) {
    const Pose2 lane_centre = beside(route_.poses[i], left);
    if (std::abs(marking.offset(lane_centre.x, lane_centre.y)[1]) > kMaxBend) return false;
  }
  return !line_near(marking, first, last, half_length, half_width);
}

// Whether a line of another stretch of road (not the samples first..last
// under the marking, give or take kOwnStretch) lies within kLineClearance
// of the marking.
bool MarkingLayer::line_near(const MarkingFrame& marking, std::size_t first, std::size_t last,
                             double half_length, double half_width) const {
  const double margin = kLineClearance + kLineHalfWidth;
  const auto inside = [&](double x, double y) {
    const auto [along, across] = marking.offset(x, y);
    return std::abs(along) <= half_length + margin && std::abs(across) <= half_width + margin;
  };
  const double reach = half_length + half_width + margin + kStep;
  const auto own = static_cast<std::size_t>(kOwnStretch / kStep);
  for (const LinePiece& piece : line_pieces_) {
    if (piece.sample + own >= first && piece.sample <= last + own) continue;
    const Strip& line = scenario_.strips[piece.strip];
    if (std::abs(line.x - marking.at.x) > reach || std::abs(line.y - marking.at.y) > reach) continue;
    const double hx = std::cos(line.heading) * line.half_length;
    const double hy = std::sin(line.heading) * line.half_length;
    if (inside(line.x, line.y) || inside(line.x + hx, line.y + hy) || inside(line.x - hx, line.y - hy))
      return true;
  }
  return false;
}

// Lays road surface, lane lines and marking rows along one lap of
// scenario.road, skipping stretches that revisit an earlier one.
void lay_world(Scenario& scenario, const WorldConfig& config, const std::array<double, kClassCount>& weights,
               const std::vector<RowSegment>& segments) {
  const int lanes = std::max(1, config.lanes);
  const RouteSamples route(scenario.road, config, lanes);
  std::vector<LinePiece> line_pieces = lay_road(scenario, route, lanes, config.lane_width_m);
  MarkingLayer layer(scenario, config, weights, route, std::move(line_pieces));
  for (const RowSegment& segment : segments) layer.lay(segment);
}

std::array<double, kClassCount> weights_for(const WorldConfig& config,
                                            const std::array<double, kClassCount>& fallback) {
  return config.class_weights ? *config.class_weights : fallback;
}

}  // namespace

const std::vector<std::string>& marking_class_names() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> n;
    for (const std::string_view c : perception::kMarkingClassNames) n.emplace_back(c);
    return n;
  }();
  return names;
}

std::array<double, 2> marking_size(Label label, double lane_width_m, int lanes) {
  // Length along the lane x width across, metres (US MUTCD / EU practice:
  // a forward arrow 6 m, letters 2.4 m tall, stop lines 0.3-0.6 m wide; the
  // turn and combined arrows as short and wide as the real images' city
  // streets paint them).
  switch (label) {
    case 0:
      return {6.0, 0.9};  // forward
    case 1:
      return {2.6, 2.2};  // leftturn (short, as in the real images)
    case 2:
      return {2.6, 2.2};  // rightturn
    case 3:
      return {2.6, 2.2};  // forward&left (short, as in the real images)
    case 4:
      return {2.6, 2.2};  // forward&right
    case 5:
      return {2.4, 2.8};  // STOP
    case 6:
      return {2.4, 2.2};  // PED
    case 7:
      return {2.4, 2.8};  // XING
    case 8:
      return {1.8, 1.4};  // bicycle with rider, or the word BIKE
    case 9:
      return {4.6, 2.6};  // railway crossing X (R either side)
    case 10:
    case 11:
    case 12:
      return {2.4, 1.6};  // 25 35 40
    case 13:
      return {6.0, 1.0};  // diamond
    case 14:
      return {0.45, lane_width_m - 0.3};  // stop line
    case 15:
      return {3.0, lanes * lane_width_m - 0.4};  // crosswalk
    default:
      return {1.0, 1.0};
  }
}

std::array<double, kClassCount> default_class_weights() {
  std::array<double, kClassCount> w = kLegacyWeights;
  w[14] = 0.06;  // stop line
  w[15] = 0.04;  // crosswalk
  return w;
}

Result<std::array<double, kClassCount>> parse_class_weights(std::string_view text) {
  std::array<double, kClassCount> weights{};
  double total = 0.0;
  while (!text.empty()) {
    const std::size_t comma = text.find(',');
    const std::string_view item = text.substr(0, comma);
    text = comma == std::string_view::npos ? std::string_view() : text.substr(comma + 1);
    const std::size_t eq = item.find('=');
    if (eq == std::string_view::npos) {
      // append(), not operator+: GCC 12 warns falsely (-Wrestrict) on "'" + string.
      return error(std::string("'").append(item).append("': expected NAME=WEIGHT"));
    }
    const auto label = perception::marking_class_from_name(item.substr(0, eq));
    if (!label) {
      return error("unknown marking class '" + std::string(item.substr(0, eq)) + "'");
    }
    const std::string number(item.substr(eq + 1));
    char* end = nullptr;
    const double value = std::strtod(number.c_str(), &end);
    // Relative weights: a million to one is already "never".
    if (number.empty() || *end != '\0' || !std::isfinite(value) || value < 0 || value > 1e6) {
      return error(std::string("'").append(item).append("': weight must be a number in 0..1e6"));
    }
    weights[*label] = value;
    total += value;
  }
  if (total <= 0) {
    return error("class weights must not all be zero");
  }
  return weights;
}

void Path::add_point(double x, double y) {
  if (!xs_.empty()) {
    const double step = std::hypot(x - xs_.back(), y - ys_.back());
    if (step < 1e-9) return;
    cumulative_.push_back(cumulative_.back() + step);
  } else {
    cumulative_.push_back(0.0);
  }
  xs_.push_back(x);
  ys_.push_back(y);
}

Pose2 Path::at(double s) const {
  if (xs_.size() < 2) return {};
  s = std::clamp(s, 0.0, length());
  const auto it = std::upper_bound(cumulative_.begin(), cumulative_.end(), s);
  const std::size_t i = std::min<std::size_t>(
      static_cast<std::size_t>(std::max<std::ptrdiff_t>(it - cumulative_.begin() - 1, 0)), xs_.size() - 2);
  const double span = cumulative_[i + 1] - cumulative_[i];
  const double f = span > 0 ? (s - cumulative_[i]) / span : 0.0;
  const double dx = xs_[i + 1] - xs_[i];
  const double dy = ys_[i + 1] - ys_[i];
  // The heading turns smoothly, as a car's does: near a point shared with a
  // neighbouring segment it blends the two directions over half the shorter
  // segment's length either side (a polyline's own direction would jump at
  // every point of a curve).
  const auto direction = [&](std::size_t j) { return std::atan2(ys_[j + 1] - ys_[j], xs_[j + 1] - xs_[j]); };
  const auto length_of = [&](std::size_t j) { return cumulative_[j + 1] - cumulative_[j]; };
  const double own = std::atan2(dy, dx);
  const double from_start = s - cumulative_[i], to_end = span - from_start;
  double yaw = own;
  if (i > 0) {
    const double zone = 0.5 * std::min(span, length_of(i - 1));
    if (from_start < zone) yaw = own + 0.5 * (1.0 - from_start / zone) * wrap_angle(direction(i - 1) - own);
  }
  if (i + 2 < xs_.size()) {
    const double zone = 0.5 * std::min(span, length_of(i + 1));
    if (to_end < zone) yaw = own + 0.5 * (1.0 - to_end / zone) * wrap_angle(direction(i + 1) - own);
  }
  yaw = wrap_angle(yaw);
  return {xs_[i] + f * dx, ys_[i] + f * dy, yaw};
}

std::vector<std::string> scenario_names() {
  std::vector<std::string> names{"loop", "ring", "figure8", "long", "grid", "two-days"};
  for (std::string& town : town_scenario_names()) names.push_back(std::move(town));
  return names;
}

namespace {

// City streets on a grid of identical 120 m x 80 m blocks, toured so that
// several streets are driven two or three times in the same direction.
Path city_tour(std::vector<StreetStart>& streets) {
  constexpr double bx = 120.0, by = 80.0;
  std::vector<std::array<double, 2>> corners;
  const auto go = [&](double i, double j) { corners.push_back({i * bx, j * by}); };
  // Outer 3x2 rectangle, then two loops through the inner north-south streets.
  go(0, 0);
  go(3, 0);
  go(3, 2);
  go(0, 2);
  go(0, 0);
  go(1, 0);
  go(1, 2);
  go(0, 2);
  go(0, 0);
  go(2, 0);
  go(2, 2);
  go(0, 2);
  return rounded_tour(corners, 12.0, streets);
}

// One row layout per street, chosen among two per street direction: most
// blocks look exactly like another block (the hard case for false loops).
std::vector<RowSegment> street_segments(const std::vector<StreetStart>& streets, double length,
                                        std::uint64_t seed) {
  std::vector<RowSegment> segments;
  // The tour starts half way along its last street.
  segments.push_back({0.0, streets.front().s, mix(seed * 4 + streets.back().street_key % 2)});
  for (std::size_t i = 0; i < streets.size(); ++i) {
    const double end = i + 1 < streets.size() ? streets[i + 1].s : length;
    const std::uint64_t pattern = streets[i].street_key % 2;
    segments.push_back({streets[i].s, end, mix(seed * 4 + pattern)});
  }
  return segments;
}

}  // namespace

std::optional<Scenario> make_scenario(std::string_view name, std::uint64_t seed, const WorldConfig& config) {
  if (std::optional<TownScenario> town = make_town(name, seed, config)) return std::move(town->scenario);
  Scenario s;
  s.name = std::string(name);
  std::vector<RowSegment> segments;
  std::array<double, kClassCount> weights = weights_for(config, kLegacyWeights);
  if (name == "loop") {
    s.description = "a 1.2 km city block driven twice";
    s.road = rounded_rectangle(400, 200, 20);
    s.laps = 2;
  } else if (name == "ring") {
    s.description = "a 3.1 km ring road driven twice";
    add_arc(s.road, 0, 0, 500, -kPi / 2, 1.5 * kPi);
    s.laps = 2;
  } else if (name == "figure8") {
    s.description = "a figure eight of two 150 m circles driven twice";
    add_arc(s.road, 0, 150, 150, -kPi / 2, 1.5 * kPi);
    add_arc(s.road, 0, -150, 150, kPi / 2, -1.5 * kPi);
    s.laps = 2;
  } else if (name == "long") {
    s.description = "a 6 km block driven in laps (10 by default: 60 km)";
    s.road = rounded_rectangle(2000, 1000, 30);
    s.laps = 10;
  } else if (name == "grid" || name == "two-days") {
    std::vector<StreetStart> streets;
    s.road = city_tour(streets);
    segments = street_segments(streets, s.road.length(), seed);
    weights = weights_for(config, default_class_weights());
    if (name == "grid") {
      s.description = "a 2.3 km tour of look-alike city blocks, streets driven up to 3 times";
    } else {
      s.description = "the city tour driven on two days (by day, then at dusk)";
      s.laps = 2;
      s.days = 2;
    }
  } else {
    return std::nullopt;
  }
  if (segments.empty()) segments.push_back({0.0, s.road.length(), seed});
  WorldConfig laid = config;
  if (name == "grid" || name == "two-days") {
    // City streets: markings at every few tens of metres.
    laid.row_spacing_min_m = config.row_spacing_min_m * 0.6;
    laid.row_spacing_max_m = config.row_spacing_max_m * 0.5;
  }
  lay_world(s, laid, weights, segments);
  return s;
}

Scenario make_route_scenario(std::string name, Path route, std::uint64_t seed, const WorldConfig& config) {
  Scenario s;
  s.name = std::move(name);
  s.description = "a route from a pose file";
  s.road = std::move(route);
  lay_world(s, config, weights_for(config, default_class_weights()), {{0.0, s.road.length(), seed}});
  return s;
}

}  // namespace markloop::sim
