#include "sim/town.hpp"

#include <algorithm>
#include <cmath>
#include <random>
#include <string>

#include "app/perception/marking_classes.hpp"

namespace markloop::sim {

namespace {

constexpr double kLineHalfWidth = 0.075;
constexpr double kDashPeriod = 12.0, kDashLength = 3.0;  // US practice: 3 m line, 9 m gap
// Strips are short: the renderer finds them by their centres.
constexpr double kRoadPiece = 4.0, kLinePiece = 4.0;
constexpr double kShoulder = 0.6;
constexpr double kMarkingGap = 1.0;       // bare road between markings in a lane
constexpr double kExitClearance = 8.0;    // nothing painted just past a crossing
constexpr double kRightTurnRadius = 6.0;  // stays on the road surface round the corner
constexpr double kLeftTurnRadius = 12.0;  // from about the stop line, across the box

std::uint64_t mix(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31);
}

std::uint64_t mix(std::uint64_t a, std::uint64_t b) {
  return mix(a ^ mix(b + 0x51ED));
}

Label label_of(std::string_view name) {
  return *perception::marking_class_from_name(name);
}

void add_line(Path& path, double x0, double y0, double x1, double y1) {
  const int steps = std::max(1, static_cast<int>(std::hypot(x1 - x0, y1 - y0) / 0.5));
  for (int i = 0; i <= steps; ++i) path.add_point(x0 + (x1 - x0) * i / steps, y0 + (y1 - y0) * i / steps);
}

void add_arc(Path& path, double cx, double cy, double radius, double a0, double a1) {
  const int steps = std::max(2, static_cast<int>(std::abs(a1 - a0) * radius / 0.5));
  for (int i = 0; i <= steps; ++i) {
    const double a = a0 + (a1 - a0) * i / steps;
    path.add_point(cx + radius * std::cos(a), cy + radius * std::sin(a));
  }
}

// One street of the town.
struct Street {
  bool column = false;
  std::size_t index = 0;
  double at = 0.0;  // x of a column, y of a row
  int lanes = 1;    // per direction
};

// The pose `along` the street's axis, `right` metres to the right of
// direction d (+1: east or north, -1: west or south), heading as d does.
Pose2 street_pose(const Street& s, int d, double along, double right) {
  const double ux = s.column ? 0.0 : d, uy = s.column ? d : 0.0;
  const double x = s.column ? s.at : along, y = s.column ? along : s.at;
  return {x + uy * right, y - ux * right, std::atan2(uy, ux)};
}

// A stretch of a street between intersection boxes, or between a box and
// the street's end, along its axis.
struct Stretch {
  double lo = 0.0, hi = 0.0;
  bool box_at_lo = false, box_at_hi = false;
  double length() const { return hi - lo; }
};

std::vector<Stretch> stretches_of(const Town& town, const Street& s) {
  const std::vector<double>& crossings = s.column ? town.ys : town.xs;
  std::vector<Stretch> out;
  Stretch next{crossings.front() - town.overhang_m, 0.0, false, false};
  for (std::size_t k = 0; k < crossings.size(); ++k) {
    const double half = town.half_width(!s.column, k);
    next.hi = crossings[k] - half;
    next.box_at_hi = true;
    out.push_back(next);
    next = {crossings[k] + half, 0.0, true, false};
  }
  next.hi = crossings.back() + town.overhang_m;
  out.push_back(next);
  return out;
}

std::vector<Street> streets_of(const Town& town) {
  std::vector<Street> streets;
  for (std::size_t i = 0; i < town.xs.size(); ++i)
    streets.push_back({true, i, town.xs[i], town.column_lanes[i]});
  for (std::size_t j = 0; j < town.ys.size(); ++j)
    streets.push_back({false, j, town.ys[j], town.row_lanes[j]});
  return streets;
}

// Cuts [from, to] along the street into strips of at most `piece` metres,
// `right` of the axis (as seen heading east or north).
void add_strips(std::vector<Strip>& strips, const Street& s, double from, double to, double right,
                double half_width, double piece, StripKind kind) {
  const int count = std::max(1, static_cast<int>(std::ceil((to - from) / piece - 1e-9)));
  const double length = (to - from) / count;
  // Road pieces overlap a little: no seams between them.
  const double overlap = kind == StripKind::kRoad ? 0.05 : 0.0;
  for (int k = 0; k < count; ++k) {
    const Pose2 p = street_pose(s, 1, from + (k + 0.5) * length, right);
    strips.push_back(
        {p.x, p.y, p.yaw, static_cast<float>(length / 2 + overlap), static_cast<float>(half_width), kind});
  }
}

// Road surface along the whole street; edge lines, a double yellow centre
// line and dashed lane lines along each stretch, from behind the stop lines.
void lay_street_strips(const Town& town, const Street& s, std::vector<Strip>& strips) {
  const double w = town.lane_width_m;
  const std::vector<Stretch> stretches = stretches_of(town, s);
  add_strips(strips, s, stretches.front().lo, stretches.back().hi, 0.0, s.lanes * w + kShoulder, kRoadPiece,
             StripKind::kRoad);
  for (const Stretch& st : stretches) {
    const double from = st.lo + (st.box_at_lo ? LegLayout::kLinesFrom : 0.0);
    const double to = st.hi - (st.box_at_hi ? LegLayout::kLinesFrom : 0.0);
    if (to <= from) continue;
    for (const double side : {-1.0, 1.0}) {
      add_strips(strips, s, from, to, side * (s.lanes * w - 0.1), kLineHalfWidth, kLinePiece,
                 StripKind::kWhiteLine);
      add_strips(strips, s, from, to, side * 0.12, kLineHalfWidth, kLinePiece, StripKind::kYellowLine);
      for (int k = 1; k < s.lanes; ++k)
        for (double a = from; a + 0.5 < to; a += kDashPeriod)
          add_strips(strips, s, a, std::min(a + kDashLength, to), side * k * w, kLineHalfWidth, kLinePiece,
                     StripKind::kWhiteLine);
    }
  }
}

// Draws from relative weights over named classes.
class ClassMix {
 public:
  ClassMix(std::initializer_list<std::pair<std::string_view, double>> weights) {
    std::vector<double> w;
    for (const auto& [name, weight] : weights) {
      labels_.push_back(label_of(name));
      w.push_back(weight);
    }
    pick_ = std::discrete_distribution<std::size_t>(w.begin(), w.end());
  }
  Label operator()(std::mt19937_64& rng) { return labels_[pick_(rng)]; }

 private:
  std::vector<Label> labels_;
  std::discrete_distribution<std::size_t> pick_;
};

// Paints the markings of every street, stretch by stretch and direction by
// direction. In a look-alike town every stretch of one direction draws the
// same layout (the hard case for false loops).
class TownPainter {
 public:
  TownPainter(const Town& town, std::uint64_t seed, bool look_alike, Scenario& scenario)
      : town_(town), seed_(seed), look_alike_(look_alike), scenario_(scenario) {}

  void paint(const Street& s) {
    const std::vector<Stretch> stretches = stretches_of(town_, s);
    for (std::size_t k = 0; k < stretches.size(); ++k)
      for (const int d : {1, -1}) {
        const std::uint64_t key = look_alike_ ? (s.column ? 2 : 4) + (d > 0 ? 1 : 0)
                                              : mix(mix(s.column ? 1 : 2, s.index), k * 2 + (d > 0 ? 1 : 0));
        std::mt19937_64 rng(mix(seed_, key));
        paint_stretch(s, stretches[k], d, rng);
      }
  }

 private:
  using Occupied = std::vector<std::vector<std::array<double, 2>>>;  // per lane, stretches along
  static constexpr int kAcross = -1;                                 // a marking across the road

  void paint_stretch(const Street& s, const Stretch& st, int d, std::mt19937_64& rng);
  void paint_approach(const Street& s, const Stretch& st, int d, std::mt19937_64& rng, Occupied& occupied);
  void paint_between(const Street& s, const Stretch& st, int d, std::mt19937_64& rng, Occupied& occupied);
  bool lay(const Street& s, const Stretch& st, int d, Label label, double t, int lane, Occupied& occupied);

  const Town& town_;
  const std::uint64_t seed_;
  const bool look_alike_;
  Scenario& scenario_;
  std::uniform_real_distribution<double> unit_{0.0, 1.0};
  const Label crosswalk_ = label_of("crosswalk"), stop_line_ = label_of("stopline");
};

void TownPainter::paint_stretch(const Street& s, const Stretch& st, int d, std::mt19937_64& rng) {
  Occupied occupied(static_cast<std::size_t>(s.lanes));
  const bool box_ahead = d > 0 ? st.box_at_hi : st.box_at_lo;
  if (box_ahead) paint_approach(s, st, d, rng, occupied);
  paint_between(s, st, d, rng, occupied);
}

// The arrow in approach lane `lane` of `lanes`: the left lane turns left,
// the right one goes on or turns right; a single lane does either.
Label approach_arrow(int lane, int lanes, std::mt19937_64& rng) {
  static ClassMix single{
      {"forward&left", 0.35}, {"forward&right", 0.35}, {"forward", 0.15}, {"leftturn", 0.15}};
  static ClassMix left{{"leftturn", 0.6}, {"forward&left", 0.4}};
  static ClassMix right{{"forward", 0.35}, {"forward&right", 0.45}, {"rightturn", 0.2}};
  static ClassMix middle{{"forward", 1.0}};
  if (lanes == 1) return single(rng);
  if (lane == lanes - 1) return left(rng);
  return lane == 0 ? right(rng) : middle(rng);
}

// Before the box ahead: the leg's crosswalk, a stop line per lane, an arrow
// per lane, and on half the approaches a second arrow further back.
void TownPainter::paint_approach(const Street& s, const Stretch& st, int d, std::mt19937_64& rng,
                                 Occupied& occupied) {
  const double w = town_.lane_width_m;
  const auto between = [&](const std::array<double, 2>& range) {
    return range[0] + (range[1] - range[0]) * unit_(rng);
  };
  const double crosswalk_length = marking_size(crosswalk_, w, 2)[0];
  const double stop_line_length = marking_size(stop_line_, w, 1)[0];
  const double crosswalk_end = st.length() - between(LegLayout::kCrosswalkFrom);
  lay(s, st, d, crosswalk_, crosswalk_end - crosswalk_length / 2, kAcross, occupied);
  const double stop_line_end = crosswalk_end - crosswalk_length - between(LegLayout::kStopLineGap);
  for (int lane = 0; lane < s.lanes; ++lane)
    lay(s, st, d, stop_line_, stop_line_end - stop_line_length / 2, lane, occupied);
  const double arrow_end = stop_line_end - stop_line_length - between(LegLayout::kArrowGap);
  const bool twice = unit_(rng) < 0.5;
  const double back = 12.0 + 10.0 * unit_(rng);
  for (int lane = 0; lane < s.lanes; ++lane) {
    const Label arrow = approach_arrow(lane, s.lanes, rng);
    const double length = marking_size(arrow, w, 1)[0];
    lay(s, st, d, arrow, arrow_end - length / 2, lane, occupied);
    if (twice) lay(s, st, d, arrow, arrow_end - 1.5 * length - back, lane, occupied);
  }
}

// Between the crossings: none to three markings of the lanes' own.
void TownPainter::paint_between(const Street& s, const Stretch& st, int d, std::mt19937_64& rng,
                                Occupied& occupied) {
  static ClassMix between{{"25", 1.0},  {"35", 1.2},   {"40", 0.6},      {"diamond", 0.6}, {"bike", 1.0},
                          {"ped", 0.4}, {"xing", 0.4}, {"forward", 0.6}, {"rail", 0.2}};
  std::discrete_distribution<int> how_many{0.25, 0.35, 0.25, 0.15};
  const bool box_behind = d > 0 ? st.box_at_lo : st.box_at_hi;
  const double from = box_behind ? LegLayout::kLinesFrom + kExitClearance : 5.0;
  const double to = st.length() - 5.0;
  const int count = how_many(rng);
  for (int n = 0; n < count && to > from; ++n) {
    const Label label = between(rng);
    const auto lane = static_cast<int>(rng() % static_cast<std::uint64_t>(s.lanes));
    for (int attempt = 0; attempt < 8; ++attempt)
      if (lay(s, st, d, label, from + (to - from) * unit_(rng), lane, occupied)) break;
  }
}

// Lays `label` centred `t` metres into the stretch (in direction d) in
// `lane`, or across the road; refused where it would lie within
// kMarkingGap of another marking in its lane(s) or off the stretch.
bool TownPainter::lay(const Street& s, const Stretch& st, int d, Label label, double t, int lane,
                      Occupied& occupied) {
  const double w = town_.lane_width_m;
  const auto size = marking_size(label, w, lane == kAcross ? 2 * s.lanes : 1);
  const std::array<double, 2> span{t - size[0] / 2, t + size[0] / 2};
  if (span[0] < 0.0 || span[1] > st.length()) return false;
  const int first = lane == kAcross ? 0 : lane, last = lane == kAcross ? s.lanes - 1 : lane;
  for (int k = first; k <= last; ++k)
    for (const auto& [begin, end] : occupied[static_cast<std::size_t>(k)])
      if (span[1] + kMarkingGap > begin && span[0] - kMarkingGap < end) return false;
  for (int k = first; k <= last; ++k) occupied[static_cast<std::size_t>(k)].push_back(span);
  const double along = d > 0 ? st.lo + t : st.hi - t;
  const double right = lane == kAcross ? 0.0 : (s.lanes - lane - 0.5) * w;
  const Pose2 at = street_pose(s, d, along, right);
  Marking m;
  m.id = static_cast<std::uint32_t>(scenario_.markings.size());
  m.label = label;
  m.x = at.x;
  m.y = at.y;
  m.heading = at.yaw;
  m.lane = lane == kAcross ? 0 : lane;
  m.length_m = size[0];
  m.width_m = label == crosswalk_ ? 2 * s.lanes * w - 0.4 : size[1];
  scenario_.markings.push_back(m);
  return true;
}

// The world coordinate of grid coordinate g on streets at `at`: linear
// between crossings, along the end stubs beyond them.
double grid_coordinate(const std::vector<double>& at, double overhang, double g) {
  const double last = static_cast<double>(at.size() - 1);
  if (g <= 0.0) return at.front() + g * overhang;
  if (g >= last) return at.back() + (g - last) * overhang;
  const auto k = static_cast<std::size_t>(g);
  return at[k] + (g - static_cast<double>(k)) * (at[k + 1] - at[k]);
}

// A route as moves from `start`: "E3 N1.5 W2" drives 3 blocks east, 1.5
// north, 2 west.
std::vector<GridPoint> moves(GridPoint start, std::string_view steps) {
  std::vector<GridPoint> route{start};
  while (!steps.empty()) {
    const std::size_t space = steps.find(' ');
    const std::string step(steps.substr(0, space));
    steps = space == std::string_view::npos ? std::string_view() : steps.substr(space + 1);
    const double blocks = std::stod(step.substr(1));
    GridPoint next = route.back();
    (step[0] == 'E'   ? next.i
     : step[0] == 'W' ? next.i
                      : next.j) += (step[0] == 'W' || step[0] == 'S') ? -blocks : blocks;
    route.push_back(next);
  }
  return route;
}

// A grid of `columns` x `rows` streets, the gaps between crossings drawn
// from the ranges along x and along y, a street two lanes per direction
// with probability `two_lanes`.
Town grid_town(std::mt19937_64& rng, std::size_t columns, std::size_t rows, std::array<double, 2> x_gaps,
               std::array<double, 2> y_gaps, double two_lanes) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  Town town;
  const auto lay_out = [&](std::vector<double>& at, std::vector<int>& lanes, std::size_t count,
                           std::array<double, 2> gaps) {
    std::uniform_real_distribution<double> gap(gaps[0], gaps[1]);
    for (std::size_t k = 0; k < count; ++k) {
      at.push_back(k == 0 ? 0.0 : at.back() + gap(rng));
      lanes.push_back(unit(rng) < two_lanes ? 2 : 1);
    }
  };
  lay_out(town.xs, town.column_lanes, columns, x_gaps);
  lay_out(town.ys, town.row_lanes, rows, y_gaps);
  return town;
}

struct TownPlan {
  Town town;
  std::vector<GridPoint> route;
  std::string description;
  bool look_alike = false;
};

// Lays the town's streets and markings into `scenario`.
void lay_town(const Town& town, std::uint64_t seed, bool look_alike, Scenario& scenario) {
  TownPainter painter(town, seed, look_alike, scenario);
  for (const Street& s : streets_of(town)) {
    lay_street_strips(town, s, scenario.strips);
    painter.paint(s);
  }
}

// First east along row 1, north, and west along row 3; then four blocks
// of those rows, each between another pair of columns, re-entered by a
// turn and left by a turn; the first move south crosses row 1. The
// blocks east-west are 67 to 135 m long, so the four overlaps 50 to 120 m.
TownPlan turn_ins_plan(std::mt19937_64& rng) {
  TownPlan plan{grid_town(rng, 6, 4, {67.0, 135.0}, {60.0, 90.0}, 0.3), {}, {}, false};
  plan.route = moves({-0.3, 1}, "E5.3 N2 W5 S3 E1 N1 E1 S1 E1 N1 E1 N1 W1 N1 W1 S1 W1 N1 W1 N0.5");
  plan.description = "a 3 km town drive: 4 streets re-entered by a turn for a block (50-120 m)";
  return plan;
}

// Two blocks of the first street, then a block each of two others, driven
// back the other way.
TownPlan opposite_plan(std::mt19937_64& rng) {
  TownPlan plan{grid_town(rng, 5, 3, {90.0, 135.0}, {75.0, 125.0}, 0.3), {}, {}, false};
  plan.route = moves({-0.3, 0}, "E4.3 N2 W2 S1 E1 S1 W2 N2 E2 S1 W1 S0.5");
  plan.description = "a 2 km town drive: 3 stretches driven again the opposite way (70-250 m)";
  return plan;
}

TownPlan closing_plan(std::mt19937_64& rng) {
  TownPlan plan{grid_town(rng, 5, 4, {75.0, 130.0}, {75.0, 130.0}, 0.3), {}, {}, false};
  plan.route = moves({0.4, 0}, "E3.6 N1 W1 N2 W3 S3 E1.4");
  plan.description = "a 1.5 km town loop that ends on its first street for a block (about 100 m)";
  return plan;
}

// Two long avenues (two lanes each way), every block alike: out along one,
// back along the other, then 300 m of the first again.
TownPlan avenue_plan(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> gap(85.0, 115.0);
  TownPlan plan{{}, {}, {}, true};
  const double block = gap(rng);
  for (int i = 0; i < 10; ++i) {
    plan.town.xs.push_back(i * block);
    plan.town.column_lanes.push_back(1);
  }
  plan.town.ys = {0.0, 120.0};
  plan.town.row_lanes = {2, 2};
  plan.route = moves({-0.3, 0}, "E9.3 N1 W9 S1 E3");
  plan.description = "2.4 km along two look-alike avenues (every block the same), then 300 m again";
  return plan;
}

// A serpentine over rows about 4 km long, each driven once, until `km`.
TownPlan far_plan(std::mt19937_64& rng, double km) {
  TownPlan plan{grid_town(rng, 41, 1, {75.0, 125.0}, {75.0, 125.0}, 0.3), {}, {}, false};
  plan.description =
      "a " + std::to_string(std::lround(km)) + " km town serpentine that never comes back (--laps N: N km)";
  Town& town = plan.town;
  const double row = town.xs.back() - town.xs.front(), last = static_cast<double>(town.xs.size() - 1);
  std::uniform_real_distribution<double> gap(75.0, 125.0), unit(0.0, 1.0);
  plan.route.push_back({-0.3, 0.0});
  double left = km * 1000.0 - 0.3 * town.overhang_m;
  for (std::size_t j = 0;; ++j) {
    const bool east = j % 2 == 0;
    const double along = std::min(left, row) / row * last;
    plan.route.push_back({east ? along : last - along, static_cast<double>(j)});
    left -= row;
    if (left <= 0.0) break;
    town.ys.push_back(town.ys.back() + gap(rng));
    town.row_lanes.push_back(unit(rng) < 0.3 ? 2 : 1);
    const double up = std::min(left, town.ys[j + 1] - town.ys[j]);
    plan.route.push_back({east ? last : 0.0, static_cast<double>(j) + up / (town.ys[j + 1] - town.ys[j])});
    left -= up;
    if (left <= 0.0) break;
  }
  return plan;
}

std::optional<TownPlan> plan_for(std::string_view name, std::uint64_t seed, const WorldConfig& config) {
  std::mt19937_64 rng(mix(seed, 0x70A1));
  if (name == "turn-ins") return turn_ins_plan(rng);
  if (name == "opposite") return opposite_plan(rng);
  if (name == "closing") return closing_plan(rng);
  if (name == "avenue") return avenue_plan(rng);
  if (name == "far") return far_plan(rng, config.route_km > 0 ? config.route_km : 20.0);
  return std::nullopt;
}

}  // namespace

std::vector<std::string> town_scenario_names() {
  return {"turn-ins", "opposite", "closing", "avenue", "far"};
}

std::optional<TownScenario> make_town(std::string_view name, std::uint64_t seed, const WorldConfig& config) {
  std::optional<TownPlan> plan = plan_for(name, seed, config);
  if (!plan) return std::nullopt;
  TownScenario out;
  out.town = std::move(plan->town);
  out.town.lane_width_m = config.lane_width_m;
  out.route = std::move(plan->route);
  Scenario& s = out.scenario;
  s.name = std::string(name);
  s.description = std::move(plan->description);
  s.road = town_path(out.town, out.route);
  lay_town(out.town, seed, plan->look_alike, s);
  return out;
}

double Town::half_width(bool column, std::size_t index) const {
  return (column ? column_lanes[index] : row_lanes[index]) * lane_width_m + kShoulder;
}

std::array<double, 4> Town::box(std::size_t i, std::size_t j) const {
  const double hx = half_width(true, i), hy = half_width(false, j);
  return {xs[i] - hx, ys[j] - hy, xs[i] + hx, ys[j] + hy};
}

Path town_path(const Town& town, const std::vector<GridPoint>& route) {
  struct Corner {
    double x, y, radius;
  };
  const auto place = [&](const GridPoint& g) {
    return std::array<double, 2>{grid_coordinate(town.xs, town.overhang_m, g.i),
                                 grid_coordinate(town.ys, town.overhang_m, g.j)};
  };
  // Lane 0 of the street from a to b lies right of its axis.
  const auto lane_offset = [&](const GridPoint& a, const GridPoint& b) {
    const bool column = a.i == b.i;
    const int lanes = column ? town.column_lanes[static_cast<std::size_t>(std::lround(a.i))]
                             : town.row_lanes[static_cast<std::size_t>(std::lround(a.j))];
    const int d = (column ? b.j > a.j : b.i > a.i) ? 1 : -1;
    const Pose2 p = street_pose({column, 0, 0.0, lanes}, d, 0.0, (lanes - 0.5) * town.lane_width_m);
    return std::array<double, 3>{p.x, p.y, p.yaw};
  };
  std::vector<Corner> corners;
  for (std::size_t k = 0; k < route.size(); ++k) {
    const auto at = place(route[k]);
    const auto in = k > 0 ? lane_offset(route[k - 1], route[k]) : lane_offset(route[0], route[1]);
    const auto out = k + 1 < route.size() ? lane_offset(route[k], route[k + 1]) : in;
    const double turn = wrap_angle(out[2] - in[2]);
    if (k > 0 && k + 1 < route.size() && std::abs(turn) < 1e-6) continue;  // straight on
    // Where the two lanes' centres cross: the offsets are at right angles.
    const bool turning = std::abs(turn) > 1e-6;
    corners.push_back({at[0] + in[0] + (turning ? out[0] : 0.0), at[1] + in[1] + (turning ? out[1] : 0.0),
                       turn > 0 ? kLeftTurnRadius : kRightTurnRadius});
  }
  Path path;
  std::array<double, 2> last{corners.front().x, corners.front().y};
  path.add_point(last[0], last[1]);
  for (std::size_t k = 1; k + 1 < corners.size(); ++k) {
    const Corner &prev = corners[k - 1], &here = corners[k], &next = corners[k + 1];
    const double in_len = std::hypot(here.x - prev.x, here.y - prev.y);
    const double out_len = std::hypot(next.x - here.x, next.y - here.y);
    const double ux = (here.x - prev.x) / in_len, uy = (here.y - prev.y) / in_len;
    const double vx = (next.x - here.x) / out_len, vy = (next.y - here.y) / out_len;
    const double turn = std::atan2(ux * vy - uy * vx, ux * vx + uy * vy);
    const double cut = here.radius * std::tan(std::abs(turn) / 2);
    add_line(path, last[0], last[1], here.x - ux * cut, here.y - uy * cut);
    const double side = turn > 0 ? 1.0 : -1.0;  // a left turn's centre lies on the left
    const double cx = here.x - ux * cut - uy * here.radius * side;
    const double cy = here.y - uy * cut + ux * here.radius * side;
    const double start = std::atan2(here.y - uy * cut - cy, here.x - ux * cut - cx);
    add_arc(path, cx, cy, here.radius, start, start + turn);
    last = {here.x + vx * cut, here.y + vy * cut};
  }
  add_line(path, last[0], last[1], corners.back().x, corners.back().y);
  return path;
}

}  // namespace markloop::sim
