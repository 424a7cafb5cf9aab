#include "app/tools/posegraph/picture.hpp"

#include <algorithm>
#include <cstdio>
#include <limits>

#include "app/tools/common/tool_files.hpp"

namespace markloop::posegraph {

namespace {

constexpr double kWidth = 1000.0, kHeight = 800.0, kMargin = 40.0, kTitle = 40.0;

// World metres (x east, y north) to pixels (y down), aspect kept.
class Frame {
 public:
  explicit Frame(const PictureContent& c) {
    for (const auto* poses : {&c.truth, &c.odometry, &c.corrected})
      for (const Pose2& p : *poses) {
        min_x_ = std::min(min_x_, p.x), max_x_ = std::max(max_x_, p.x);
        min_y_ = std::min(min_y_, p.y), max_y_ = std::max(max_y_, p.y);
      }
    const double span = std::max({max_x_ - min_x_, max_y_ - min_y_, 1.0});
    scale_ = std::min((kWidth - 2 * kMargin) / std::max(max_x_ - min_x_, 1e-3 * span),
                      (kHeight - 2 * kMargin - kTitle) / std::max(max_y_ - min_y_, 1e-3 * span));
  }
  double x(double wx) const { return kMargin + (wx - min_x_) * scale_; }
  double y(double wy) const { return kHeight - kMargin - (wy - min_y_) * scale_; }

 private:
  double min_x_ = std::numeric_limits<double>::max(), min_y_ = min_x_;
  double max_x_ = std::numeric_limits<double>::lowest(), max_y_ = max_x_;
  double scale_ = 1.0;
};

void polyline(std::FILE* f, const Frame& frame, std::span<const Pose2> poses, const char* colour,
              double width) {
  if (poses.empty()) return;
  std::fprintf(f, "<polyline fill=\"none\" stroke=\"%s\" stroke-width=\"%.1f\" points=\"", colour, width);
  // A point every 0.5 px is all the picture can show.
  double last_x = -1e9, last_y = -1e9;
  for (const Pose2& p : poses) {
    const double px = frame.x(p.x), py = frame.y(p.y);
    if (std::abs(px - last_x) + std::abs(py - last_y) < 0.5) continue;
    std::fprintf(f, "%.1f,%.1f ", px, py);
    last_x = px, last_y = py;
  }
  std::fprintf(f, "\"/>\n");
}

void legend(std::FILE* f, int row, const char* colour, const char* text) {
  const double y = kTitle + 18.0 * row;
  std::fprintf(f, "<line x1=\"%g\" y1=\"%g\" x2=\"%g\" y2=\"%g\" stroke=\"%s\" stroke-width=\"3\"/>\n",
               kWidth - 220, y, kWidth - 190, y, colour);
  std::fprintf(f, "<text x=\"%g\" y=\"%g\" font-size=\"13\" font-family=\"sans-serif\">%s</text>\n",
               kWidth - 182, y + 4, text);
}

}  // namespace

Status write_picture_svg(const std::string& path, const PictureContent& c) {
  tools::OutputFile file;
  if (Status opened = file.open(path); !opened) return opened;
  std::FILE* f = file.get();
  const Frame frame(c);
  std::fprintf(f,
               "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"%g\" height=\"%g\">\n"
               "<rect width=\"100%%\" height=\"100%%\" fill=\"white\"/>\n"
               "<text x=\"%g\" y=\"24\" font-size=\"16\" font-family=\"sans-serif\">%s</text>\n",
               kWidth, kHeight, kMargin, c.title.c_str());
  polyline(f, frame, c.truth, "#282828", 4.0);
  polyline(f, frame, c.odometry, "#ff7f0e", 1.5);
  polyline(f, frame, c.corrected, "#1f77b4", 1.5);
  for (std::size_t i = 0; i < c.loops.size(); ++i) {
    const LoopMeasurement& m = c.loops[i];
    // On the odometry, where each loop pulled: on the corrected trajectory
    // a used loop's two ends meet.
    if (m.query >= c.odometry.size() || m.match >= c.odometry.size()) continue;
    const bool rejected = i < c.loop_rejected.size() && c.loop_rejected[i];
    const Pose2 &a = c.odometry[m.query], &b = c.odometry[m.match];
    std::fprintf(f,
                 "<line x1=\"%.1f\" y1=\"%.1f\" x2=\"%.1f\" y2=\"%.1f\" stroke=\"%s\" stroke-width=\"1\"/>\n",
                 frame.x(a.x), frame.y(a.y), frame.x(b.x), frame.y(b.y), rejected ? "#dc1e1e" : "#00a03c");
  }
  int row = 0;
  if (!c.truth.empty()) legend(f, row++, "#282828", "truth");
  legend(f, row++, "#ff7f0e", "odometry");
  legend(f, row++, "#1f77b4", "corrected");
  legend(f, row++, "#00a03c", "loop edge");
  legend(f, row, "#dc1e1e", "loop edge rejected");
  std::fprintf(f, "</svg>\n");
  return file.close();
}

}  // namespace markloop::posegraph
