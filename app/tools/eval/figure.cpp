#include "app/tools/eval/figure.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "app/perception/marking_classes.hpp"
#include "app/tools/common/tool_files.hpp"
#include "app/tools/common/trajectory.hpp"

namespace markloop::eval {

namespace {

struct Rgb {
  int r, g, b;
};

// One colour per marking class (index = Label), distinct on white.
constexpr std::array<Rgb, perception::kMarkingClassCount> kClassColours = {{
    {31, 119, 180},
    {255, 127, 14},
    {148, 103, 189},
    {140, 86, 75},
    {227, 119, 194},
    {188, 189, 34},
    {23, 190, 207},
    {174, 199, 232},
    {255, 187, 120},
    {197, 176, 213},
    {196, 156, 148},
    {247, 182, 210},
    {219, 219, 141},
    {158, 218, 229},
    {99, 99, 99},
    {57, 59, 121},
}};
constexpr Rgb kRoute{40, 40, 40};
constexpr Rgb kCorrected{31, 119, 180};
constexpr Rgb kCorrect{0, 160, 60};
constexpr Rgb kWrong{220, 30, 30};

// Maps world metres (x east, y north) to picture pixels (y down), keeping the
// aspect ratio, with room for the title above and the legend on the right.
class Layout {
 public:
  static constexpr int kMaxWidth = 1000, kMaxHeight = 800;
  static constexpr int kTitle = 64, kLegend = 180, kMargin = 24, kScaleBar = 36;

  explicit Layout(const FigureContent& c) {
    double min_x = std::numeric_limits<double>::max(), min_y = min_x;
    double max_x = std::numeric_limits<double>::lowest(), max_y = max_x;
    const auto extend = [&](double x, double y) {
      min_x = std::min(min_x, x), max_x = std::max(max_x, x);
      min_y = std::min(min_y, y), max_y = std::max(max_y, y);
    };
    for (const Pose2& p : *c.route) extend(p.x, p.y);
    for (const WorldMarking& m : *c.markings) extend(m.x, m.y);
    if (min_x > max_x) min_x = max_x = min_y = max_y = 0.0;  // nothing to draw
    min_x_ = min_x, max_y_ = max_y;
    const double span_x = std::max(max_x - min_x, 1.0), span_y = std::max(max_y - min_y, 1.0);
    const double plot_w = kMaxWidth - kLegend - 2 * kMargin;
    const double plot_h = kMaxHeight - kTitle - kScaleBar - 2 * kMargin;
    scale_ = std::min(plot_w / span_x, plot_h / span_y);
    plot_width_ = static_cast<int>(std::ceil(span_x * scale_));
    plot_height_ = static_cast<int>(std::ceil(span_y * scale_));
    width_ = std::max(plot_width_ + kLegend + 2 * kMargin, 520);
    height_ = std::max(plot_height_ + kTitle + kScaleBar + 2 * kMargin, 320);
  }

  double px(double x) const { return kMargin + (x - min_x_) * scale_; }
  double py(double y) const { return kTitle + kMargin + (max_y_ - y) * scale_; }
  int width() const { return width_; }
  int height() const { return height_; }
  int legend_x() const { return kMargin + plot_width_ + kMargin; }
  int scale_bar_y() const { return kTitle + kMargin + plot_height_ + kScaleBar / 2 + 6; }
  double pixels_per_metre() const { return scale_; }

  // A round length (1, 2 or 5 times a power of ten) about a fifth of the plot.
  double scale_bar_m() const {
    const double target = std::max(plot_width_, 50) / 5.0 / scale_;
    const double power = std::pow(10.0, std::floor(std::log10(target)));
    for (const double step : {5.0, 2.0, 1.0})
      if (step * power <= target) return step * power;
    return power;
  }

 private:
  double min_x_ = 0, max_y_ = 0, scale_ = 1;
  int plot_width_ = 0, plot_height_ = 0, width_ = 0, height_ = 0;
};

std::string length_text(double metres) {
  char text[32];
  if (metres >= 1000.0)
    std::snprintf(text, sizeof text, "%g km", metres / 1000.0);
  else
    std::snprintf(text, sizeof text, "%g m", metres);
  return text;
}

// Classes that occur in the world, in label order, for the legend.
std::vector<Label> classes_present(const std::vector<WorldMarking>& markings) {
  std::array<bool, perception::kMarkingClassCount> present{};
  for (const WorldMarking& m : markings) present[m.label] = true;
  std::vector<Label> labels;
  for (std::size_t i = 0; i < present.size(); ++i)
    if (present[i]) labels.push_back(static_cast<Label>(i));
  return labels;
}

std::string xml_escaped(std::string_view text) {
  std::string out;
  for (const char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

std::string svg_colour(Rgb c) {
  char text[16];
  std::snprintf(text, sizeof text, "#%02x%02x%02x", c.r, c.g, c.b);
  return text;
}

cv::Scalar bgr(Rgb c) {
  return {double(c.b), double(c.g), double(c.r)};
}

void svg_header(std::FILE* f, const Layout& layout, const FigureContent& c) {
  std::fprintf(f,
               "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
               "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"%d\" height=\"%d\" "
               "viewBox=\"0 0 %d %d\" font-family=\"sans-serif\">\n"
               "<rect width=\"100%%\" height=\"100%%\" fill=\"white\"/>\n",
               layout.width(), layout.height(), layout.width(), layout.height());
  std::fprintf(f, "<text x=\"%d\" y=\"26\" font-size=\"18\" font-weight=\"bold\">%s</text>\n",
               Layout::kMargin, xml_escaped(c.title).c_str());
  std::fprintf(f, "<text x=\"%d\" y=\"50\" font-size=\"13\">%s</text>\n", Layout::kMargin,
               xml_escaped(c.subtitle).c_str());
}

// Route: one polyline, decimated to about a pixel per point.
void svg_route(std::FILE* f, const Layout& layout, const std::vector<Pose2>& route, Rgb colour = kRoute) {
  std::fprintf(f, "<polyline fill=\"none\" stroke=\"%s\" stroke-width=\"1.2\" points=\"",
               svg_colour(colour).c_str());
  double last_x = -1e9, last_y = -1e9;
  for (std::size_t i = 0; i < route.size(); ++i) {
    const double x = layout.px(route[i].x), y = layout.py(route[i].y);
    if (i + 1 < route.size() && std::hypot(x - last_x, y - last_y) < 1.0) continue;
    std::fprintf(f, "%.1f,%.1f ", x, y);
    last_x = x, last_y = y;
  }
  std::fprintf(f, "\"/>\n");
}

void svg_markings_and_loops(std::FILE* f, const Layout& layout, const FigureContent& c) {
  for (const WorldMarking& m : *c.markings)
    std::fprintf(f, "<circle cx=\"%.1f\" cy=\"%.1f\" r=\"3\" fill=\"%s\"/>\n", layout.px(m.x), layout.py(m.y),
                 svg_colour(kClassColours[m.label]).c_str());
  const auto& route = *c.route;
  for (const LoopOutcome& loop : *c.loops) {
    if (loop.verdict == Verdict::Unjudged) continue;
    const Pose2& q = route[loop.pair.query];
    const Pose2& m = route[loop.pair.match];
    const std::string colour = svg_colour(loop.verdict == Verdict::Correct ? kCorrect : kWrong);
    std::fprintf(f,
                 "<line x1=\"%.1f\" y1=\"%.1f\" x2=\"%.1f\" y2=\"%.1f\" stroke=\"%s\" "
                 "stroke-width=\"1.5\"><title>frame %u - frame %u</title></line>\n",
                 layout.px(q.x), layout.py(q.y), layout.px(m.x), layout.py(m.y), colour.c_str(),
                 loop.pair.query, loop.pair.match);
    for (const Pose2* p : {&q, &m})
      std::fprintf(
          f, "<circle cx=\"%.1f\" cy=\"%.1f\" r=\"4\" fill=\"none\" stroke=\"%s\" stroke-width=\"1.5\"/>\n",
          layout.px(p->x), layout.py(p->y), colour.c_str());
  }
}

void svg_scale_bar(std::FILE* f, const Layout& layout) {
  const double bar_m = layout.scale_bar_m();
  const double bar_px = bar_m * layout.pixels_per_metre();
  const int bar_y = layout.scale_bar_y();
  std::fprintf(f,
               "<path d=\"M %d %d v 6 h %.1f v -6\" fill=\"none\" stroke=\"black\" stroke-width=\"1.5\"/>\n"
               "<text x=\"%.1f\" y=\"%d\" font-size=\"12\">%s</text>\n",
               Layout::kMargin, bar_y - 6, bar_px, Layout::kMargin + bar_px + 8, bar_y + 4,
               length_text(bar_m).c_str());
}

void svg_legend(std::FILE* f, const Layout& layout, const std::vector<WorldMarking>& markings,
                bool corrected) {
  int y = Layout::kTitle + Layout::kMargin + 10;
  const int x = layout.legend_x();
  const auto legend_line = [&](Rgb colour, const char* text) {
    std::fprintf(f,
                 "<line x1=\"%d\" y1=\"%d\" x2=\"%d\" y2=\"%d\" stroke=\"%s\" stroke-width=\"2\"/>"
                 "<text x=\"%d\" y=\"%d\" font-size=\"12\">%s</text>\n",
                 x, y, x + 22, y, svg_colour(colour).c_str(), x + 30, y + 4, text);
    y += 20;
  };
  legend_line(kRoute, "route (truth)");
  if (corrected) legend_line(kCorrected, "pose graph");
  legend_line(kCorrect, "correct loop");
  legend_line(kWrong, "wrong loop");
  y += 6;
  for (const Label label : classes_present(markings)) {
    std::fprintf(f,
                 "<circle cx=\"%d\" cy=\"%d\" r=\"4\" fill=\"%s\"/>"
                 "<text x=\"%d\" y=\"%d\" font-size=\"12\">%s</text>\n",
                 x + 11, y, svg_colour(kClassColours[label]).c_str(), x + 30, y + 4,
                 xml_escaped(perception::marking_class_name(label)).c_str());
    y += 17;
  }
}

// A point of the world in the picture's pixels.
cv::Point pixel(const Layout& layout, double x, double y) {
  return cv::Point(static_cast<int>(std::lround(layout.px(x))), static_cast<int>(std::lround(layout.py(y))));
}

void png_route_markings_and_loops(cv::Mat& image, const Layout& layout, const FigureContent& c) {
  std::vector<cv::Point> polyline;
  for (const Pose2& p : *c.route) {
    const cv::Point q = pixel(layout, p.x, p.y);
    if (polyline.empty() || polyline.back() != q) polyline.push_back(q);
  }
  if (polyline.size() > 1) cv::polylines(image, polyline, false, bgr(kRoute), 1, cv::LINE_AA);
  for (const WorldMarking& m : *c.markings)
    cv::circle(image, pixel(layout, m.x, m.y), 3, bgr(kClassColours[m.label]), cv::FILLED, cv::LINE_AA);
  for (const LoopOutcome& loop : *c.loops) {
    if (loop.verdict == Verdict::Unjudged) continue;
    const cv::Scalar colour = bgr(loop.verdict == Verdict::Correct ? kCorrect : kWrong);
    const Pose2& q = (*c.route)[loop.pair.query];
    const Pose2& m = (*c.route)[loop.pair.match];
    cv::line(image, pixel(layout, q.x, q.y), pixel(layout, m.x, m.y), colour, 2, cv::LINE_AA);
    cv::circle(image, pixel(layout, q.x, q.y), 4, colour, 1, cv::LINE_AA);
    cv::circle(image, pixel(layout, m.x, m.y), 4, colour, 1, cv::LINE_AA);
  }
}

void png_scale_bar(cv::Mat& image, const Layout& layout) {
  const double bar_m = layout.scale_bar_m();
  const int bar_px = static_cast<int>(std::lround(bar_m * layout.pixels_per_metre()));
  const cv::Point left{Layout::kMargin, layout.scale_bar_y()};
  cv::line(image, left - cv::Point(0, 6), left, {0, 0, 0}, 1);
  cv::line(image, left, left + cv::Point(bar_px, 0), {0, 0, 0}, 1);
  cv::line(image, left + cv::Point(bar_px, 0), left + cv::Point(bar_px, -6), {0, 0, 0}, 1);
  cv::putText(image, length_text(bar_m), left + cv::Point(bar_px + 8, 4), cv::FONT_HERSHEY_SIMPLEX, 0.45,
              {0, 0, 0}, 1, cv::LINE_AA);
}

void png_legend(cv::Mat& image, const Layout& layout, const std::vector<WorldMarking>& markings,
                bool corrected) {
  int y = Layout::kTitle + Layout::kMargin + 10;
  const int x = layout.legend_x();
  const auto legend_line = [&](Rgb colour, const char* text) {
    cv::line(image, {x, y}, {x + 22, y}, bgr(colour), 2, cv::LINE_AA);
    cv::putText(image, text, {x + 30, y + 5}, cv::FONT_HERSHEY_SIMPLEX, 0.45, {0, 0, 0}, 1, cv::LINE_AA);
    y += 20;
  };
  legend_line(kRoute, "route (truth)");
  if (corrected) legend_line(kCorrected, "pose graph");
  legend_line(kCorrect, "correct loop");
  legend_line(kWrong, "wrong loop");
  y += 6;
  for (const Label label : classes_present(markings)) {
    cv::circle(image, {x + 11, y}, 4, bgr(kClassColours[label]), cv::FILLED, cv::LINE_AA);
    cv::putText(image, std::string(perception::marking_class_name(label)), {x + 30, y + 5},
                cv::FONT_HERSHEY_SIMPLEX, 0.45, {0, 0, 0}, 1, cv::LINE_AA);
    y += 17;
  }
}

// Encoded in memory, then written as every output is: a failed write says
// why (a full disk), where imwrite only returns false.
Status write_encoded_png(const std::string& path, const cv::Mat& image) {
  std::vector<std::uint8_t> png;
  bool encoded = false;
  try {
    encoded = cv::imencode(".png", image, png);
  } catch (const cv::Exception& e) {
    return error(path + ": cannot encode the PNG: " + e.what());
  }
  if (!encoded) return error(path + ": cannot encode the PNG");
  return tools::write_whole_file(path, png.data(), png.size());
}

}  // namespace

Result<std::vector<Pose2>> corrected_on_route(const std::string& path, const std::vector<Pose2>& route,
                                              const std::vector<double>& times) {
  Result<std::vector<tools::TimedPose>> tum = tools::load_tum(path);
  if (!tum) return tum.error();
  std::vector<Pose2> estimate, truth;
  std::size_t frame = 0;
  const double half_frame = times.size() > 1 ? 0.5 * (times[1] - times[0]) : 0.05;
  for (const tools::TimedPose& p : *tum) {
    while (frame < times.size() && times[frame] < p.t - half_frame) ++frame;
    if (frame >= times.size() || frame >= route.size()) break;
    if (std::abs(times[frame] - p.t) > half_frame) continue;
    estimate.push_back(p.pose);
    truth.push_back(route[frame]);
  }
  if (estimate.size() < 2) return error(path + ": fewer than 2 poses at the drive's frame times");
  return tools::transformed(estimate, tools::align_se2(estimate, truth));
}

Status write_svg(const std::string& path, const FigureContent& c) {
  const Layout layout(c);
  tools::OutputFile file;
  if (Status opened = file.open(path); !opened) return opened;
  std::FILE* f = file.get();
  svg_header(f, layout, c);
  svg_route(f, layout, *c.route);
  if (c.corrected != nullptr) svg_route(f, layout, *c.corrected, kCorrected);
  svg_markings_and_loops(f, layout, c);
  svg_scale_bar(f, layout);
  svg_legend(f, layout, *c.markings, c.corrected != nullptr);
  std::fprintf(f, "</svg>\n");
  return file.close();
}

Status write_png(const std::string& path, const FigureContent& c) {
  const Layout layout(c);
  cv::Mat image(layout.height(), layout.width(), CV_8UC3, cv::Scalar(255, 255, 255));
  cv::putText(image, c.title, {Layout::kMargin, 26}, cv::FONT_HERSHEY_SIMPLEX, 0.65, {0, 0, 0}, 2,
              cv::LINE_AA);
  cv::putText(image, c.subtitle, {Layout::kMargin, 50}, cv::FONT_HERSHEY_SIMPLEX, 0.45, {0, 0, 0}, 1,
              cv::LINE_AA);
  png_route_markings_and_loops(image, layout, c);
  if (c.corrected != nullptr) {
    std::vector<cv::Point> line;
    for (const Pose2& p : *c.corrected)
      line.emplace_back(int(std::lround(layout.px(p.x))), int(std::lround(layout.py(p.y))));
    cv::polylines(image, line, false, bgr(kCorrected), 1, cv::LINE_AA);
  }
  png_scale_bar(image, layout);
  png_legend(image, layout, *c.markings, c.corrected != nullptr);
  return write_encoded_png(path, image);
}

}  // namespace markloop::eval
