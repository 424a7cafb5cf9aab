#include "app/tools/common/trajectory.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "app/tools/common/tool_files.hpp"

namespace markloop::tools {

namespace {

// A trajectory file of a day's driving at 1 kHz stays well under this.
constexpr std::size_t kMaxTrajectoryBytes = std::size_t{512} << 20;

std::string where(const std::string& path, std::size_t line) {
  return path + ":" + std::to_string(line) + ": ";
}

// Up to `n` numbers separated by blanks; false on anything else.
bool parse_numbers(std::string_view line, double* out, std::size_t n) {
  std::string text(line);
  const char* p = text.c_str();
  for (std::size_t i = 0; i < n; ++i) {
    char* end = nullptr;
    out[i] = std::strtod(p, &end);
    if (end == p || !std::isfinite(out[i])) return false;
    p = end;
  }
  while (*p == ' ' || *p == '\t') ++p;
  return *p == '\0';
}

}  // namespace

Status write_tum(const std::string& path, std::span<const Pose2> poses, double fps) {
  OutputFile file;
  if (Status opened = file.open(path); !opened) return opened;
  for (std::size_t k = 0; k < poses.size(); ++k) {
    const Pose2& p = poses[k];
    std::fprintf(file.get(), "%.6f %.6f %.6f 0 0 0 %.9f %.9f\n", static_cast<double>(k) / fps, p.x, p.y,
                 std::sin(0.5 * p.yaw), std::cos(0.5 * p.yaw));
  }
  return file.close();
}

Status write_kitti(const std::string& path, std::span<const Pose2> poses) {
  OutputFile file;
  if (Status opened = file.open(path); !opened) return opened;
  // Ground frame (x ahead, y left) to camera axes: as markloop-sim's poses.txt.
  for (const Pose2& p : poses) {
    const double c = std::cos(p.yaw), s = std::sin(p.yaw);
    std::fprintf(file.get(), "%.9f 0 %.9f %.6f 0 1 0 0 %.9f 0 %.9f %.6f\n", c, -s, -p.y, s, c, p.x);
  }
  return file.close();
}

Result<std::vector<TimedPose>> load_tum(const std::string& path) {
  const Result<std::string> read = read_input(path, kMaxTrajectoryBytes, "a TUM trajectory");
  if (!read) return read.error();
  std::vector<TimedPose> poses;
  Lines lines(*read);
  std::string_view line;
  while (lines.next(line)) {
    const std::size_t start = line.find_first_not_of(" \t");
    if (start == std::string_view::npos || line[start] == '#') continue;
    double v[8];
    if (!parse_numbers(line, v, 8))
      return error(where(path, lines.number()) + "expected 8 numbers 't x y z qx qy qz qw'");
    const double norm = std::sqrt(v[4] * v[4] + v[5] * v[5] + v[6] * v[6] + v[7] * v[7]);
    if (std::abs(norm - 1.0) > 1e-3)
      return error(where(path, lines.number()) + "quaternion is not of unit length");
    if (!poses.empty() && v[0] <= poses.back().t)
      return error(where(path, lines.number()) + "time does not rise above the line before's");
    // Yaw of the rotation about z (the plane's heading), whatever tilt it has.
    const double yaw = std::atan2(2.0 * (v[7] * v[6] + v[4] * v[5]), 1.0 - 2.0 * (v[5] * v[5] + v[6] * v[6]));
    poses.push_back({v[0], Pose2{v[1], v[2], yaw}});
  }
  if (poses.empty()) return error(path + ": no pose in it");
  return poses;
}

Pose2 align_se2(std::span<const Pose2> from, std::span<const Pose2> to) {
  const std::size_t n = std::min(from.size(), to.size());
  if (n < 2) return {};
  double fx = 0, fy = 0, tx = 0, ty = 0;
  for (std::size_t i = 0; i < n; ++i) fx += from[i].x, fy += from[i].y, tx += to[i].x, ty += to[i].y;
  const double inv_n = 1.0 / static_cast<double>(n);
  fx *= inv_n, fy *= inv_n, tx *= inv_n, ty *= inv_n;
  // The rotation maximising sum <R a_i, b_i>: angle of sum (a_i . b_i, a_i x b_i).
  double dot = 0, cross = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double ax = from[i].x - fx, ay = from[i].y - fy, bx = to[i].x - tx, by = to[i].y - ty;
    dot += ax * bx + ay * by;
    cross += ax * by - ay * bx;
  }
  const double angle = std::atan2(cross, dot);
  const double c = std::cos(angle), s = std::sin(angle);
  return {tx - (c * fx - s * fy), ty - (s * fx + c * fy), angle};
}

std::vector<Pose2> transformed(std::span<const Pose2> poses, const Pose2& transform) {
  std::vector<Pose2> out;
  out.reserve(poses.size());
  for (const Pose2& p : poses) out.push_back(compose(transform, p));
  return out;
}

}  // namespace markloop::tools
