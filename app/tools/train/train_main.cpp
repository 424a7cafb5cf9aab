// markloop-train: trains the marking classifier on the detector's own
// candidates in annotated images (real and simulated), evaluates it on
// clips held apart, and writes the model as a model file
// (app/perception/model/README.md).
//
// Every candidate the detector proposes in a training image is labelled by
// the annotation whose quadrilateral contains its centre (the class), or
// "reject" when none does; candidates on annotations of classes markloop
// does not know (X-crossing, hump, ...) are left out. Fixed seeds: the same
// command gives the same model.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <functional>
#include <limits>
#include <map>
#include <numeric>
#include <optional>
#include <random>
#include <span>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <Eigen/Core>
#if defined(__SSE__)
#include <xmmintrin.h>
#endif
#include <opencv2/imgproc.hpp>

#include "app/common/cli.hpp"
#include "app/io/y4m.hpp"
#include "app/perception/camera_model.hpp"
#include "app/perception/marking_classes.hpp"
#include "app/perception/marking_classifier.hpp"
#include "app/perception/marking_detector.hpp"
#include "app/perception/model/model_file.hpp"
#include "app/tools/common/still_image.hpp"
#include "app/tools/common/tool_files.hpp"
#include "app/tools/train/dataset.hpp"
#include "platform/files.hpp"

namespace {

using namespace markloop::perception;
using markloop::cli::fail;

constexpr const char* kUsageHead =
    "usage: markloop-train --real DIR --real-camera FILE [--sim DIR]... [--sim-drive-train DIR]...\n"
    "                      [--sim-test DIR]... [--sim-drive DIR]...\n"
    "                      [--folds N] [--seed N] [--members N] [--epochs N] [--hidden N]\n"
    "                      [--out FILE.bin] [--dump DIR]\n"
    "       markloop-train --real DIR --real-camera FILE [--sim-test DIR]... [--sim-drive DIR]...\n"
    "                      --scores DIR [--scores DIR]...\n"
    "       markloop-train --evaluate-builtin [--real DIR --real-camera FILE]\n"
    "                      [--sim-test DIR]... [--sim-drive DIR]...\n"
    "\n"
    "Trains the road-marking classifier on the detector's candidates in annotated\n"
    "images and writes it as a model file (app/perception/model/marking_mlp.bin).\n"
    "\n";

// The options; a description's further lines follow its "\n"s.
constexpr std::array<markloop::cli::OptionSpec, 19> kOptions = {{
    {"--real", "DIR", "real images: DIR/annotations.csv + DIR/images/ (roadmarks-honda)"},
    {"--real-camera", "FILE", "calibration (and detector region) of the real camera"},
    {"--sim", "DIR", "simulator training set (markloop-sim training-set), with\nDIR/camera.yaml; repeatable"},
    {"--sim-test", "DIR", "simulator set held apart: only evaluated; repeatable"},
    {"--sim-drive", "DIR",
     "simulator drive (markloop-sim drive: visible.csv, frames.y4m)\n"
     "held apart: every 5th frame evaluated; repeatable"},
    {"--sim-drive-train", "DIR", "simulator drive trained on (every 5th frame); repeatable"},
    {"--folds", "N",
     "cross-validation by clip on the real images (default 4; 0: none):\n"
     "clip c (60-frame block) is validated in fold c mod N by a model\n"
     "trained without it"},
    {"--seed", "N", "random seed (default 1)"},
    {"--members", "N",
     "networks in the ensemble, 1..4 (default 3): trained alike\n"
     "from seeds S, S+100, ... (S: --seed); probabilities averaged"},
    {"--epochs", "N", "training epochs (default 60)"},
    {"--hidden", "N", "hidden units (default 64)"},
    {"--reject-weight", "W", "factor on the reject class's loss weight (default 1)"},
    {"--real-weight", "W", "factor on the loss weight of the real images' samples (default 1)"},
    {"--weight-decay", "W", "L2 weight decay (default 1e-4)"},
    {"--weight-average", "D",
     "write the weights' running average instead of the last step's:\n"
     "each step it moves 1-D of the way to the weights, more early on\n"
     "(at least 9/(10+step)), so it spans the last 1/(1-D) steps or the\n"
     "last tenth of training, whichever is fewer (default 0: off)"},
    {"--out", "FILE.bin",
     "write the model trained on all training data (format:\n"
     "app/perception/model/README.md), and FILE.txt: how it was trained"},
    {"--dump", "DIR",
     "also write every candidate (patch, features, label, fold) for\n"
     "train_cnn.py, and the MLPs' probabilities: the real images' from\n"
     "the cross-validation, the test sets' from the final model (DIR/mlp/)"},
    {"--scores", "DIR",
     "train nothing: judge the probabilities in DIR (DIR/train0.probs.f32:\n"
     "the real images' cross-validation, DIR/testK.probs.f32: the K-th\n"
     "test set), blended over every --scores given as the detector\n"
     "blends (geometric mean, normalised): the first the MLPs' (DIR/mlp),\n"
     "each further one a network's (DIR/cnn/seedS); the sets must be\n"
     "given as to the run that wrote them"},
    {"--evaluate-builtin", "",
     "train nothing: judge the model compiled into this program (the\n"
     "MLPs blended with the networks, as the detector classifies) on\n"
     "the sets given (real images: a training fit, not a validation)"},
}};

constexpr const char* kUsageTail =
    "\n"
    "Diagnostics, set in the environment:\n"
    "  MARKLOOP_TRAIN_SHOW_MISSES=1  per evaluation, how the missed markings were classified\n"
    "  MARKLOOP_TRAIN_LIST_MISSED=1  each missed marking: image, class, what its candidate got\n"
    "                                (class, score; cut by the view's edge or a piece of a larger one)\n"
    "  MARKLOOP_TRAIN_LIST_FALSE=1   each wrong detection: image, label, centre in pixels\n"
    "  MARKLOOP_TRAIN_SHOW_FIT=1     also score the final model on the real images it was trained on\n"
    "\n"
    "Annotation files are read whole: annotations.csv up to 64 MiB, a drive's visible.csv\n"
    "and frames.csv up to 256 MiB each, images up to 256 MiB each.\n"
    "Exit status: 0 on success; 1 when an output cannot be written; 2 on bad options or input.\n";

// The help text: the option lines as cli::options_help writes them, a
// description's further lines indented to its first.
std::string usage() {
  std::size_t column = 0;  // where options_help starts the descriptions
  for (const auto& o : kOptions)
    column = std::max(column, o.name.size() + (o.value_name.empty() ? 0 : o.value_name.size() + 1));
  column += 4;
  const std::string lines = markloop::cli::options_help(kOptions);
  std::string text = kUsageHead;
  for (std::size_t start = 0; start < lines.size();) {
    const std::size_t end = lines.find('\n', start);
    const std::string_view line(lines.data() + start, end - start);
    if (!line.starts_with("  -")) text.append(column, ' ');
    text.append(line).append("\n");
    start = end + 1;
  }
  return text + kUsageTail;
}

// The classes the targets are judged on: enough real examples to measure.
constexpr std::array<std::string_view, 11> kMainClasses = {
    "leftturn", "forward", "rightturn", "35", "xing", "ped", "rail", "bike", "stop", "40", "forward&right"};

struct Sample {
  Features features;
  int label;  // class index or kRejectClass
  int image;  // index into the images of its set
  int clip;   // real: 60-frame block; sim: -1
  bool real;
  bool augmented;               // a shifted, rotated or mirrored copy: training only
  bool clipped;                 // cut by the edge of the view: trained on, not reported...
  bool partial;                 // ... unless only by its near edge (DetectorConfig)
  bool beyond_region;           // centred in the view's guard band: trained on, not reported
  std::array<float, 2> centre;  // quad centre in the image, pixels
  std::array<int, 4> box;       // bird's-eye box: col0, row0, col1, row1
  std::array<float, kPatchCols * kPatchRows> grey{};  // the patch the features came from
  std::array<std::uint8_t, kPatchCols * kPatchRows> paint{};
};

void keep_patch(const PatchScratch& scratch, Sample& s) {
  s.grey = scratch.grey;
  for (std::size_t i = 0; i < s.paint.size(); ++i) s.paint[i] = paint_level(scratch.paint[i]);
}

constexpr int kJitters = 6;
constexpr int kRotations = 2;
constexpr float kMaxRotationDeg = 15.0f;

// Copies of a marking as the car would see it turning or changing lanes:
// the bird's-eye neighbourhood rotated by up to 15 degrees, the box fitted
// again to the paint.
void add_rotated(const MarkingDetector& detector, const Candidate& c, const Sample& s,
                 std::vector<Sample>& out, std::mt19937& rng) {
  const cv::Mat& bev = detector.birdseye_image();
  const cv::Mat& mask = detector.paint_mask();
  const auto& region = detector.config().region;
  std::uniform_real_distribution<float> angle(-kMaxRotationDeg, kMaxRotationDeg);
  const cv::Point2f centre(0.5f * static_cast<float>(c.col0 + c.col1),
                           0.5f * static_cast<float>(c.row0 + c.row1));
  for (int k = 0; k < kRotations; ++k) {
    const cv::Mat rotation = cv::getRotationMatrix2D(centre, angle(rng), 1.0);
    cv::Mat bev_r, mask_r;
    cv::warpAffine(bev, bev_r, rotation, bev.size(), cv::INTER_LINEAR, cv::BORDER_CONSTANT);
    cv::warpAffine(mask, mask_r, rotation, mask.size(), cv::INTER_NEAREST, cv::BORDER_CONSTANT);
    // The rotated box's bounds, tightened to the paint inside them.
    std::vector<cv::Point2f> corners = {{static_cast<float>(c.col0), static_cast<float>(c.row0)},
                                        {static_cast<float>(c.col1), static_cast<float>(c.row0)},
                                        {static_cast<float>(c.col1), static_cast<float>(c.row1)},
                                        {static_cast<float>(c.col0), static_cast<float>(c.row1)}};
    cv::transform(corners, corners, rotation);
    cv::Rect bounds = cv::boundingRect(corners) & cv::Rect(0, 0, bev.cols, bev.rows);
    if (bounds.width < 2 || bounds.height < 2) continue;
    const cv::Rect paint = cv::boundingRect(mask_r(bounds) > 127);
    if (paint.width < 2 || paint.height < 2) continue;
    const cv::Rect box(bounds.x + paint.x, bounds.y + paint.y, paint.width, paint.height);
    PatchBox patch{box.x,
                   box.y,
                   box.x + box.width - 1,
                   box.y + box.height - 1,
                   static_cast<float>(box.height) * region.x_step_m,
                   static_cast<float>(box.width) * region.y_step_m,
                   c.parts};
    Sample copy = s;
    copy.augmented = true;
    PatchScratch scratch;
    compute_features(bev_r, mask_r, patch, scratch, copy.features);
    keep_patch(scratch, copy);
    out.push_back(copy);
  }
}

int g_patch_mismatches = 0;  // candidates whose features the patch kept does not give

struct ImageSet {
  std::string dir;
  bool real = false;
  std::vector<train::AnnotatedImage> images;
  std::vector<Sample> samples;  // every candidate; label -2 = left out of training
};

bool inside(const std::array<std::array<float, 2>, 4>& quad, float x, float y) {
  std::vector<cv::Point2f> poly;
  for (const auto& p : quad) poly.emplace_back(p[0], p[1]);
  return cv::pointPolygonTest(poly, cv::Point2f(x, y), false) >= 0;
}

// The class of a marking seen in a mirror (left and right swapped), or -1
// when the mirror image is no marking (words, numbers, symbols).
int mirror_class(int label) {
  const auto name = [](std::string_view n) { return static_cast<int>(*marking_class_from_name(n)); };
  static const std::array<std::pair<int, int>, 8> kPairs = {{
      {name("leftturn"), name("rightturn")},
      {name("rightturn"), name("leftturn")},
      {name("forward&left"), name("forward&right")},
      {name("forward&right"), name("forward&left")},
      {name("forward"), name("forward")},
      {name("diamond"), name("diamond")},
      {name("stopline"), name("stopline")},
      {name("crosswalk"), name("crosswalk")},
  }};
  for (const auto& [from, to] : kPairs)
    if (from == label) return to;
  return -1;
}

constexpr int kDriveStep = 5;  // every 5th frame of a drive: 2 per second at 10 fps

// What a set is extracted for: training adds the augmented copies; a set
// only evaluated needs just the detector's own candidates.
enum class Use { kTrain, kEvaluate };

// The images of a set, in order: stills from DIR/images/, or a drive's
// frames read on from DIR/frames.y4m.
class ImageReader {
 public:
  ImageReader(const std::string& dir, const CameraModel& camera, bool drive)
      : dir_(dir), drive_(drive), size_(camera.width(), camera.height()), video_grey_(size_, CV_8UC1) {
    if (drive_ && !video_.open(dir_ + "/frames.y4m", size_.width, size_.height)) fail(video_.error());
  }

  // The image `name` (a drive: the frame of that number, at or after the last).
  cv::Mat grey(const std::string& name) {
    if (!drive_) {
      const std::string path = dir_ + "/images/" + name;
      markloop::Result<cv::Mat> still = markloop::io::read_grey_still(path, size_);
      if (!still) fail(path + ": " + still.message());
      return std::move(still).value();
    }
    const long wanted = std::stol(name);
    while (frame_ < wanted) {
      if (video_.read_frame({video_grey_.data, video_grey_.total()}) != markloop::io::Y4mRead::kFrame)
        fail(dir_ + "/frames.y4m#" + name + ": frame missing from the video (" + video_.error() + ")");
      ++frame_;
    }
    return video_grey_;
  }

 private:
  std::string dir_;
  bool drive_;
  cv::Size size_;
  markloop::io::Y4mReader video_;
  long frame_ = -1;
  cv::Mat video_grey_;
};

// Per annotation of `image`, whether it is in range: every corner on the
// road inside the detector's region (with the horizon `shift` rows where
// this image's lane lines put it).
void mark_in_range(const CameraModel& camera, const BirdsEyeRegion& region, float shift,
                   train::AnnotatedImage& image) {
  for (const auto& a : image.annotations) {
    bool in = true;
    for (const auto& p : a.quad) {
      Eigen::Vector2d g;
      in = in && camera.image_to_ground({p[0], p[1] - shift}, g) && g.x() >= region.x_near_m &&
           g.x() <= region.x_far_m && g.y() <= region.y_left_m && g.y() >= region.y_right_m;
    }
    image.in_range.push_back(in);
  }
}

// The label of a candidate centred at `centre`: the class of the annotation
// containing it, reject when none does, -2 (left out) for a class markloop
// does not know.
int label_at(const train::AnnotatedImage& image, const std::array<float, 2>& centre) {
  for (const auto& a : image.annotations) {
    if (!inside(a.quad, centre[0], centre[1])) continue;
    const auto label = marking_class_from_name(a.label);
    return label ? static_cast<int>(*label) : -2;
  }
  return kRejectClass;
}

// The sample of the detector's candidate `c` in image `index` of a set.
Sample sample_of(const MarkingDetector& detector, const Candidate& c, const train::AnnotatedImage& image,
                 int index, bool real, bool drive) {
  Detection where{};
  detector.locate(c, where);
  Sample s;
  s.features = c.features;
  s.image = index;
  s.clip = real ? train::clip_of(image.name) : -1;
  s.real = real;
  s.centre = {0.0f, 0.0f};
  for (const auto& p : where.quad) {
    s.centre[0] += 0.25f * p[0];
    s.centre[1] += 0.25f * p[1];
  }
  s.augmented = false;
  s.clipped = c.clipped;
  s.partial = c.clipped_near_only && detector.config().report_partial_in_stills;
  s.beyond_region = detector.beyond_region(c);
  s.box = {c.col0, c.row0, c.col1, c.row1};
  PatchScratch scratch;
  Features again;
  compute_features(detector.birdseye_image(), detector.paint_mask(),
                   PatchBox{c.col0, c.row0, c.col1, c.row1, c.length_m, c.width_m, c.parts}, scratch, again);
  keep_patch(scratch, s);
  if (again != c.features) ++g_patch_mismatches;
  s.label = label_at(image, s.centre);
  // A drive lists only markings wholly in the image: a candidate cut by
  // the edge of the view may be one of the others, so it teaches nothing.
  if (drive && s.label == kRejectClass && c.clipped) s.label = -2;
  return s;
}

// The training copies of a labelled candidate: rotated copies of markings;
// on the real images also shifted and scaled boxes, and mirrored ones. One
// random sequence per set, drawn in the order of its candidates.
class Augmenter {
 public:
  explicit Augmenter(const MarkingDetector& detector) : detector_(detector) {}

  void add(const Candidate& c, const Sample& s, bool real, int image, std::vector<Sample>& out) {
    if (s.label != kRejectClass) add_rotated(detector_, c, s, out, rng_);
    // The simulator varies its markings itself; the few real clips need more help.
    if (!real) return;
    add_jittered(detector_.birdseye_image(), detector_.paint_mask(), c, s, c.col0, c.col1, s.label, out);
    // An arrow seen in a mirror is its mirror class (a left turn becomes a
    // right turn): the rare right-hand arrows learn from the many left ones.
    const int mirrored = mirror_class(s.label);
    if (mirrored < 0) return;
    if (mirrored_for_ != image) {
      cv::flip(detector_.birdseye_image(), mirrored_bev_, 1);
      cv::flip(detector_.paint_mask(), mirrored_mask_, 1);
      mirrored_for_ = image;
    }
    const int last = mirrored_bev_.cols - 1;
    add_jittered(mirrored_bev_, mirrored_mask_, c, s, last - c.col1, last - c.col0, mirrored, out);
  }

 private:
  // Shifted and scaled boxes (columns col0..col1 of `bev`), as the detector
  // would cut them on another frame; markings get more copies than the
  // plentiful rejects.
  void add_jittered(const cv::Mat& bev, const cv::Mat& mask, const Candidate& c, const Sample& s, int col0,
                    int col1, int label, std::vector<Sample>& out) {
    const int copies = s.label == kRejectClass ? 1 : kJitters;
    const int w = c.col1 - c.col0 + 1, h = c.row1 - c.row0 + 1;
    for (int k = 0; k < copies; ++k) {
      PatchBox box{col0 + static_cast<int>(std::lround(jitter_(rng_) * static_cast<float>(w))),
                   c.row0 + static_cast<int>(std::lround(jitter_(rng_) * static_cast<float>(h))),
                   col1 + static_cast<int>(std::lround(jitter_(rng_) * static_cast<float>(w))),
                   c.row1 + static_cast<int>(std::lround(jitter_(rng_) * static_cast<float>(h))),
                   c.length_m,
                   c.width_m,
                   c.parts};
      box.col0 = std::clamp(box.col0, 0, bev.cols - 1);
      box.col1 = std::clamp(box.col1, box.col0, bev.cols - 1);
      box.row0 = std::clamp(box.row0, 0, bev.rows - 1);
      box.row1 = std::clamp(box.row1, box.row0, bev.rows - 1);
      Sample copy = s;
      copy.augmented = true;
      copy.label = label;
      PatchScratch scratch;
      compute_features(bev, mask, box, scratch, copy.features);
      keep_patch(scratch, copy);
      out.push_back(copy);
    }
  }

  const MarkingDetector& detector_;
  std::mt19937 rng_{12345};
  std::uniform_real_distribution<float> jitter_{-0.08f, 0.08f};
  cv::Mat mirrored_bev_, mirrored_mask_;  // the current image's bird's-eye view, left and right swapped
  int mirrored_for_ = -1;
};

void print_extracted(const ImageSet& set, const DetectorCounters& views) {
  std::printf("%s: %d images, %zu candidates", set.dir.c_str(), static_cast<int>(set.images.size()),
              set.samples.size());
  if (const std::uint64_t no_road = views.flat_frames + views.noisy_frames + views.cluttered_frames)
    std::printf(" (%llu images showing no road: %llu flat, %llu noisy, %llu cluttered)",
                static_cast<unsigned long long>(no_road), static_cast<unsigned long long>(views.flat_frames),
                static_cast<unsigned long long>(views.noisy_frames),
                static_cast<unsigned long long>(views.cluttered_frames));
  std::printf("\n");
}

// Every candidate the detector proposes in the set's images, labelled; for
// training, their augmented copies too.
ImageSet extract(const std::string& dir, const std::string& camera_path, bool real, Use use,
                 bool drive = false) {
  ImageSet set;
  set.dir = dir;
  set.real = real;
  auto images = drive ? train::load_drive_annotations(dir, kDriveStep) : train::load_annotations(dir);
  if (!images) fail(images.message());
  set.images = std::move(*images);
  const auto camera = load_camera_model(camera_path);
  if (!camera) fail(camera.message());
  const auto detector_config = load_detector_config(camera_path);
  if (!detector_config) fail(detector_config.message());
  const DetectorConfig& config = *detector_config;
  MarkingDetector detector(*camera, config);
  Augmenter augmenter(detector);
  ImageReader reader(dir, *camera, drive);
  for (std::size_t i = 0; i < set.images.size(); ++i) {
    auto& image = set.images[i];
    detector.detect_still(reader.grey(image.name));
    mark_in_range(*camera, config.region, static_cast<float>(detector.horizon_shift()), image);
    for (const Candidate& c : detector.candidates()) {
      const Sample s = sample_of(detector, c, image, static_cast<int>(i), real, drive);
      set.samples.push_back(s);
      if (s.label >= 0 && use == Use::kTrain) augmenter.add(c, s, real, static_cast<int>(i), set.samples);
    }
  }
  print_extracted(set, detector.counters());
  return set;
}

// A one-hidden-layer perceptron trained with Adam on class-weighted softmax
// cross-entropy; the weights written out are exactly these, or their running
// average (subnormal values, which slow float arithmetic down, are set to 0
// before they are used).
struct Mlp {
  int inputs = 0, hidden = 0, outputs = 0;
  Eigen::VectorXf mean, inv_std;
  Eigen::MatrixXf w1, w2;  // hidden x inputs, outputs x hidden
  Eigen::VectorXf b1, b2;

  MlpNet view() const {
    MlpNet m;
    m.inputs = inputs;
    m.hidden = hidden;
    m.outputs = outputs;
    m.feature_mean = mean.data();
    m.feature_inv_std = inv_std.data();
    m.w1 = w1_row_major.data();
    m.b1 = b1.data();
    m.w2 = w2_row_major.data();
    m.b2 = b2.data();
    return m;
  }
  void freeze() {
    const auto normal = [](float v) { return std::abs(v) < std::numeric_limits<float>::min() ? 0.0f : v; };
    w1_row_major.resize(w1.size());
    w2_row_major.resize(w2.size());
    for (int j = 0; j < hidden; ++j)
      for (int i = 0; i < inputs; ++i) w1_row_major[j * inputs + i] = normal(w1(j, i));
    for (int k = 0; k < outputs; ++k)
      for (int j = 0; j < hidden; ++j) w2_row_major[k * hidden + j] = normal(w2(k, j));
    for (auto* v : {&mean, &inv_std, &b1, &b2}) *v = v->unaryExpr(normal);
  }
  std::vector<float> w1_row_major, w2_row_major;
};

struct TrainOptions {
  int members = 3;
  int epochs = 60;
  int hidden = 64;
  unsigned seed = 1;
  float reject_weight = 1.0f;  // extra factor on the reject class's weight
  // Extra factor on the real images' samples: the simulator's outnumber them.
  float real_weight = 1.0f;
  float weight_decay = 1e-4f;
  // Decay of the running average of the weights (0: the last step's are
  // kept). The last step's weights land wherever the last batches pushed
  // them; their average over the last few epochs sits nearer the bottom of
  // the valley (docs/decisions.md: found more on every test set).
  float weight_average = 0.0f;
};

// Late in training many Adam moments and gradients decay into subnormal
// floats, which x86 cores handle in microcode, tens of times slower: the
// training thread flushes them to zero (below 1.2e-38, far smaller than any
// step Adam takes).
void flush_subnormals_to_zero() {
#if defined(__SSE__)
  _mm_setcsr(_mm_getcsr() | 0x8040);  // FTZ (bit 15) and DAZ (bit 6)
#endif
}

// Eigen splits a matrix product into blocks sized from the CPU's caches,
// which it asks the CPU for at run time, and the blocks set the order in
// which each sum is added up: the same command trained other weights on a
// machine whose caches Eigen reads otherwise (docs/decisions.md). Fixed
// sizes (a common x86-64 core's) make the arithmetic the build's alone.
void fix_matrix_product_blocking() {
  constexpr std::ptrdiff_t kL1 = 32 * 1024, kL2 = 1024 * 1024, kL3 = 32 * 1024 * 1024;
  Eigen::setCpuCacheSizes(kL1, kL2, kL3);
}

// The samples' features as columns, standardised; sets m's mean and
// inverse standard deviation from them.
Eigen::MatrixXf standardised_features(const std::vector<const Sample*>& data, Mlp& m) {
  const int n = static_cast<int>(data.size());
  const int d = kFeatureCount;
  Eigen::MatrixXf x(d, n);
  for (int s = 0; s < n; ++s)
    for (int i = 0; i < d; ++i) x(i, s) = data[s]->features[i];
  m.mean = x.rowwise().mean();
  m.inv_std.resize(d);
  for (int i = 0; i < d; ++i) {
    const float var = (x.row(i).array() - m.mean(i)).square().mean();
    m.inv_std(i) = 1.0f / std::sqrt(var + 1e-4f);
  }
  for (int s = 0; s < n; ++s) x.col(s) = (x.col(s) - m.mean).cwiseProduct(m.inv_std);
  return x;
}

// Rare classes weigh more (inverse square root of their frequency).
std::vector<float> class_weights(const std::vector<const Sample*>& data, float reject_weight) {
  const int n = static_cast<int>(data.size());
  const int k = kClassifierOutputs;
  std::vector<int> count(k, 0);
  for (const Sample* s : data) ++count[s->label];
  std::vector<float> class_weight(k, 0.0f);
  for (int c = 0; c < k; ++c)
    class_weight[c] =
        count[c] > 0 ? std::sqrt(static_cast<float>(n) / static_cast<float>(k * count[c])) : 0.0f;
  class_weight[kRejectClass] *= reject_weight;
  return class_weight;
}

// Random weights scaled to their layer's inputs (He), zero biases.
void initialise(Mlp& m, std::mt19937& rng) {
  std::normal_distribution<float> normal(0.0f, 1.0f);
  m.w1 = Eigen::MatrixXf::NullaryExpr(m.hidden, m.inputs, [&] { return normal(rng); }) *
         std::sqrt(2.0f / static_cast<float>(m.inputs));
  m.w2 = Eigen::MatrixXf::NullaryExpr(m.outputs, m.hidden, [&] { return normal(rng); }) *
         std::sqrt(2.0f / static_cast<float>(m.hidden));
  m.b1 = Eigen::VectorXf::Zero(m.hidden);
  m.b2 = Eigen::VectorXf::Zero(m.outputs);
}

constexpr float kRate = 1e-3f, kBeta1 = 0.9f, kBeta2 = 0.999f, kEps = 1e-8f;

// Adam's moments of every parameter, and the steps taken.
struct AdamState {
  explicit AdamState(const Mlp& m)
      : mw1(Eigen::MatrixXf::Zero(m.hidden, m.inputs)),
        vw1(mw1),
        mw2(Eigen::MatrixXf::Zero(m.outputs, m.hidden)),
        vw2(mw2),
        mb1(Eigen::VectorXf::Zero(m.hidden)),
        vb1(mb1),
        mb2(Eigen::VectorXf::Zero(m.outputs)),
        vb2(mb2) {}
  Eigen::MatrixXf mw1, vw1, mw2, vw2;
  Eigen::VectorXf mb1, vb1, mb2, vb2;
  int step = 0;
};

// One parameter's Adam update; c1 and c2 correct the moments' bias.
template <typename Parameter>
void adam_update(Parameter& param, Parameter& mom, Parameter& vel, const Parameter& grad, float c1,
                 float c2) {
  mom = kBeta1 * mom + (1.0f - kBeta1) * grad;
  vel = kBeta2 * vel + (1.0f - kBeta2) * grad.cwiseProduct(grad);
  param.array() -= kRate * (mom.array() / c1) / ((vel.array() / c2).sqrt() + kEps);
}

// One step of Adam on a batch: the samples xb (columns), their one-hot
// targets and loss weights.
void train_step(Mlp& m, const Eigen::MatrixXf& xb, const Eigen::MatrixXf& target,
                const Eigen::RowVectorXf& weight, float weight_decay, AdamState& adam) {
  const int b = static_cast<int>(xb.cols());
  const Eigen::MatrixXf pre = (m.w1 * xb).colwise() + m.b1;
  const Eigen::MatrixXf h = pre.cwiseMax(0.0f);
  Eigen::MatrixXf logits = (m.w2 * h).colwise() + m.b2;
  for (int j = 0; j < b; ++j) {
    logits.col(j).array() -= logits.col(j).maxCoeff();
    logits.col(j) = logits.col(j).array().exp();
    logits.col(j) /= logits.col(j).sum();
  }
  Eigen::MatrixXf dlogits = (logits - target).array().rowwise() * weight.array();
  dlogits /= static_cast<float>(b);
  const Eigen::MatrixXf gw2 = dlogits * h.transpose() + weight_decay * m.w2;
  const Eigen::VectorXf gb2 = dlogits.rowwise().sum();
  Eigen::MatrixXf dh = m.w2.transpose() * dlogits;
  dh = dh.cwiseProduct((pre.array() > 0.0f).cast<float>().matrix());
  const Eigen::MatrixXf gw1 = dh * xb.transpose() + weight_decay * m.w1;
  const Eigen::VectorXf gb1 = dh.rowwise().sum();
  ++adam.step;
  const float c1 = 1.0f - std::pow(kBeta1, static_cast<float>(adam.step));
  const float c2 = 1.0f - std::pow(kBeta2, static_cast<float>(adam.step));
  adam_update(m.w1, adam.mw1, adam.vw1, gw1, c1, c2);
  adam_update(m.b1, adam.mb1, adam.vb1, gb1, c1, c2);
  adam_update(m.w2, adam.mw2, adam.vw2, gw2, c1, c2);
  adam_update(m.b2, adam.mb2, adam.vb2, gb2, c1, c2);
}

// The weights' running average (--weight-average).
struct WeightAverage {
  explicit WeightAverage(const Mlp& m) : w1(m.w1), w2(m.w2), b1(m.b1), b2(m.b2) {}

  // After step `step`; early on the decay is lower, so the random start is
  // soon forgotten.
  void follow(const Mlp& m, float weight_average, int step) {
    const float decay =
        std::min(weight_average, (1.0f + static_cast<float>(step)) / (10.0f + static_cast<float>(step)));
    const auto follow_one = [decay](auto& average, const auto& param) {
      average = decay * average + (1.0f - decay) * param;
    };
    follow_one(w1, m.w1);
    follow_one(b1, m.b1);
    follow_one(w2, m.w2);
    follow_one(b2, m.b2);
  }
  void replace(Mlp& m) const {
    m.w1 = w1;
    m.b1 = b1;
    m.w2 = w2;
    m.b2 = b2;
  }

  Eigen::MatrixXf w1, w2;
  Eigen::VectorXf b1, b2;
};

Mlp train_mlp(const std::vector<const Sample*>& data, const TrainOptions& options) {
  flush_subnormals_to_zero();
  const int n = static_cast<int>(data.size());
  const int d = kFeatureCount, k = kClassifierOutputs;
  Mlp m;
  m.inputs = d;
  m.hidden = options.hidden;
  m.outputs = k;
  const Eigen::MatrixXf x = standardised_features(data, m);
  const std::vector<float> class_weight = class_weights(data, options.reject_weight);
  std::mt19937 rng(options.seed);
  initialise(m, rng);
  AdamState adam(m);
  WeightAverage average(m);
  constexpr int kBatch = 64;
  std::vector<int> order(n);
  std::iota(order.begin(), order.end(), 0);
  for (int epoch = 0; epoch < options.epochs; ++epoch) {
    std::shuffle(order.begin(), order.end(), rng);
    for (int start = 0; start < n; start += kBatch) {
      const int b = std::min(kBatch, n - start);
      Eigen::MatrixXf xb(d, b);
      Eigen::MatrixXf target = Eigen::MatrixXf::Zero(k, b);
      Eigen::RowVectorXf weight(b);
      for (int j = 0; j < b; ++j) {
        const int s = order[start + j];
        xb.col(j) = x.col(s);
        target(data[s]->label, j) = 1.0f;
        weight(j) = class_weight[data[s]->label] * (data[s]->real ? options.real_weight : 1.0f);
      }
      train_step(m, xb, target, weight, options.weight_decay, adam);
      if (options.weight_average > 0.0f) average.follow(m, options.weight_average, adam.step);
    }
  }
  if (options.weight_average > 0.0f) average.replace(m);
  m.freeze();
  return m;
}

// The ensemble: members trained alike from different random starts (member
// 0 from `seed` itself). Each member has its own seed and only reads the
// data, so they train in parallel threads: the same networks as one after
// another, in less time.
std::vector<Mlp> train_members(const std::vector<const Sample*>& data, const TrainOptions& options) {
  std::vector<Mlp> members(static_cast<std::size_t>(options.members));
  std::vector<std::thread> threads;
  for (int i = 0; i < options.members; ++i)
    threads.emplace_back([&, i] {
      TrainOptions member = options;
      member.seed = options.seed + 100 * static_cast<unsigned>(i);
      members[static_cast<std::size_t>(i)] = train_mlp(data, member);
    });
  for (std::thread& thread : threads) thread.join();
  return members;
}

MlpModel view(const std::vector<Mlp>& members) {
  MlpModel model;
  model.members = static_cast<int>(members.size());
  for (std::size_t i = 0; i < members.size(); ++i) model.nets[i] = members[i].view();
  return model;
}

// Detections vs annotations, per class. A detection is correct when its
// quad centre lies inside an annotated quad of the same label; a second
// correct detection of one marking is a duplicate (neither right nor wrong);
// detections on annotations of unknown classes are not judged.
struct Score {
  std::map<std::string, int> annotated, found, detected, correct;
  std::map<std::string, int> annotated_in_range, found_in_range;
  std::map<std::string, int> confusion;  // "annotated -> predicted" for missed markings
  int duplicates = 0;
  int unjudged = 0;
  int wrong_label = 0;
  int on_nothing = 0;
  int partial_right = 0, partial_wrong = 0;  // cut by the view's near edge, reported
};

// `list`: print what the diagnostics ask for (MARKLOOP_TRAIN_LIST_*); one
// judgement of the several thresholds does, so each line comes once.
void judge(const ImageSet& set, int image_index, const std::vector<const Sample*>& detections,
           const std::vector<int>& predicted, const std::vector<bool>& piece, float min_score,
           const std::vector<float>& scores, bool list, Score& score) {
  const auto& image = set.images[image_index];
  std::vector<bool> matched(image.annotations.size(), false);
  for (std::size_t a = 0; a < image.annotations.size(); ++a) {
    const std::string& label = image.annotations[a].label;
    if (!marking_class_from_name(label)) continue;
    ++score.annotated[label];
    if (image.in_range[a]) ++score.annotated_in_range[label];
  }
  for (std::size_t i = 0; i < detections.size(); ++i) {
    if (predicted[i] == kRejectClass || scores[i] < min_score ||
        (detections[i]->clipped && !detections[i]->partial) || detections[i]->beyond_region || piece[i])
      continue;
    const std::string label(marking_class_name(static_cast<markloop::Label>(predicted[i])));
    // The real dataset does not annotate stop lines and crosswalks: such
    // detections on its images can be judged neither right nor wrong.
    if (set.real && (label == "stopline" || label == "crosswalk")) {
      ++score.unjudged;
      continue;
    }
    const Sample& s = *detections[i];
    int hit = -1;
    for (std::size_t a = 0; a < image.annotations.size(); ++a)
      if (inside(image.annotations[a].quad, s.centre[0], s.centre[1])) {
        hit = static_cast<int>(a);
        break;
      }
    if (hit >= 0 && !marking_class_from_name(image.annotations[hit].label)) continue;
    if (hit >= 0 && image.annotations[hit].label == label) {
      if (matched[hit]) {
        ++score.duplicates;
        continue;
      }
      matched[hit] = true;
      ++score.detected[label];
      ++score.correct[label];
      ++score.found[label];
      if (image.in_range[hit]) ++score.found_in_range[label];
      if (s.partial) ++score.partial_right;
      continue;
    }
    ++score.detected[label];
    if (s.partial) ++score.partial_wrong;
    if (hit >= 0)
      ++score.wrong_label;
    else
      ++score.on_nothing;
    if (list && std::getenv("MARKLOOP_TRAIN_LIST_FALSE") != nullptr)
      std::printf("  false: %s %s %s at (%.0f, %.0f)%s\n", set.dir.c_str(), image.name.c_str(), label.c_str(),
                  static_cast<double>(s.centre[0]), static_cast<double>(s.centre[1]),
                  s.partial ? " (partial)" : "");
  }
  for (std::size_t a = 0; a < image.annotations.size(); ++a) {
    if (matched[a] || !marking_class_from_name(image.annotations[a].label)) continue;
    std::string seen = "no candidate";
    char detail[64] = "";  // the candidate's score, and whether the view's edge cut it
    for (std::size_t i = 0; i < detections.size(); ++i)
      if (inside(image.annotations[a].quad, detections[i]->centre[0], detections[i]->centre[1])) {
        seen = predicted[i] == kRejectClass
                   ? std::string("reject")
                   : std::string(marking_class_name(static_cast<markloop::Label>(predicted[i])));
        std::snprintf(detail, sizeof detail, " (score %.2f%s)", static_cast<double>(scores[i]),
                      detections[i]->clipped ? ", cut by the view's edge"
                      : piece[i]             ? ", a piece of a larger marking"
                                             : "");
        if (predicted[i] != kRejectClass) break;
      }
    ++score.confusion[image.annotations[a].label + " -> " + seen];
    if (list && std::getenv("MARKLOOP_TRAIN_LIST_MISSED") != nullptr)
      std::printf("  not found: %s %s -> %s%s%s\n", image.name.c_str(), image.annotations[a].label.c_str(),
                  seen.c_str(), detail, image.in_range[a] ? " (in range)" : "");
  }
}

bool is_main_class(std::string_view name) {
  return std::find(kMainClasses.begin(), kMainClasses.end(), name) != kMainClasses.end();
}

// Recall and precision on the main classes, one line per score threshold:
// the operating points a user of the detector can choose from.
void print_operating_points(std::span<const float> thresholds, std::span<const Score> scores) {
  std::printf("\nMain classes by score threshold (detections below it not reported):\n");
  std::printf("%9s %7s %8s %10s %9s\n", "min score", "found", "recall", "detected", "precision");
  const auto main_total = [](const std::map<std::string, int>& per_class) {
    int total = 0;
    for (const auto& [label, n] : per_class)
      if (is_main_class(label)) total += n;
    return total;
  };
  for (std::size_t t = 0; t < thresholds.size(); ++t) {
    const int annotated = main_total(scores[t].annotated), found = main_total(scores[t].found),
              detected = main_total(scores[t].detected);
    std::printf("%9.2f %7d %7.1f%% %10d %8.1f%%\n", static_cast<double>(thresholds[t]), found,
                annotated ? 100.0 * found / annotated : 0.0, detected,
                detected ? 100.0 * found / detected : 0.0);
  }
}

void print_score(const char* title, const Score& score, bool main_only_total) {
  std::printf("\n%s\n", title);
  std::printf("%-14s %10s %7s %8s %10s %7s %9s %9s %7s %8s\n", "class", "annotated", "found", "recall",
              "detected", "right", "precision", "in range", "found", "recall");
  int ta = 0, tf = 0, td = 0, tc = 0, tar = 0, tfr = 0;
  for (std::string_view name : kMarkingClassNames) {
    const std::string key(name);
    const auto get = [&](const std::map<std::string, int>& m) {
      const auto it = m.find(key);
      return it == m.end() ? 0 : it->second;
    };
    const int a = get(score.annotated), f = get(score.found), d = get(score.detected), c = get(score.correct),
              ar = get(score.annotated_in_range), fr = get(score.found_in_range);
    if (a == 0 && d == 0) continue;
    const bool main = is_main_class(name);
    std::printf("%-14s %10d %7d %7.1f%% %10d %7d %8.1f%% %9d %7d %7.1f%%%s\n", key.c_str(), a, f,
                a ? 100.0 * f / a : 0.0, d, c, d ? 100.0 * c / d : 0.0, ar, fr, ar ? 100.0 * fr / ar : 0.0,
                main_only_total && !main ? "  (not a main class)" : "");
    if (!main_only_total || main) {
      ta += a;
      tf += f;
      td += d;
      tc += c;
      tar += ar;
      tfr += fr;
    }
  }
  std::printf("%-14s %10d %7d %7.1f%% %10d %7d %8.1f%% %9d %7d %7.1f%%\n",
              main_only_total ? "main classes" : "all", ta, tf, ta ? 100.0 * tf / ta : 0.0, td, tc,
              td ? 100.0 * tc / td : 0.0, tar, tfr, tar ? 100.0 * tfr / tar : 0.0);
  std::printf("duplicates %d, wrong label %d, detections on no marking %d%s\n", score.duplicates,
              score.wrong_label, score.on_nothing,
              score.unjudged
                  ? (", stop line/crosswalk (not annotated) " + std::to_string(score.unjudged)).c_str()
                  : "");
  std::printf("reported cut by the view's near edge (partial): %d right, %d wrong\n", score.partial_right,
              score.partial_wrong);
  if (std::getenv("MARKLOOP_TRAIN_SHOW_MISSES") != nullptr)
    for (const auto& [what, n] : score.confusion) std::printf("  missed: %-30s %d\n", what.c_str(), n);
}

// Classifies the candidates of the images in use once, then judges them at
// each score threshold: scores[t] gets the judgement at min_scores[t].
using ClassifySample = std::function<int(const Sample&, std::array<float, kClassifierOutputs>&)>;

void evaluate(const ImageSet& set, const ClassifySample& classify_sample, const std::vector<bool>& use_image,
              std::span<const float> min_scores, std::span<Score> scores) {
  std::vector<std::vector<const Sample*>> per_image(set.images.size());
  for (const Sample& s : set.samples)
    if (!s.augmented) per_image[s.image].push_back(&s);
  std::vector<std::vector<int>> predicted(set.images.size());
  std::vector<std::vector<float>> confidence(set.images.size());
  std::vector<std::vector<bool>> piece(set.images.size());
  for (std::size_t i = 0; i < set.images.size(); ++i) {
    if (!use_image[i]) continue;
    for (const Sample* s : per_image[i]) {
      std::array<float, kClassifierOutputs> p;
      const int c = classify_sample(*s, p);
      predicted[i].push_back(c);
      confidence[i].push_back(p[c]);
    }
    // As the detector reports them: pieces of larger markings are not.
    std::vector<Candidate> boxes(per_image[i].size());
    for (std::size_t k = 0; k < boxes.size(); ++k) {
      const Sample& s = *per_image[i][k];
      boxes[k].col0 = s.box[0];
      boxes[k].row0 = s.box[1];
      boxes[k].col1 = s.box[2];
      boxes[k].row1 = s.box[3];
      boxes[k].clipped = s.clipped;
      boxes[k].predicted = predicted[i][k];
    }
    piece[i].resize(boxes.size());
    for (std::size_t k = 0; k < boxes.size(); ++k)
      piece[i][k] = predicted[i][k] != kRejectClass && is_piece_of_larger(boxes, k);
  }
  for (std::size_t t = 0; t < min_scores.size(); ++t)
    for (std::size_t i = 0; i < set.images.size(); ++i)
      if (use_image[i])
        judge(set, static_cast<int>(i), per_image[i], predicted[i], piece[i], min_scores[t], confidence[i],
              t == 0, scores[t]);
}

ClassifySample by_model(const MlpModel& model) {
  return [&model](const Sample& s, std::array<float, kClassifierOutputs>& p) {
    return classify(model, s.features, p);
  };
}

void evaluate(const ImageSet& set, const MlpModel& model, const std::vector<bool>& use_image,
              std::span<const float> min_scores, std::span<Score> scores) {
  evaluate(set, by_model(model), use_image, min_scores, scores);
}

void evaluate(const ImageSet& set, const ClassifySample& classify_sample, const std::vector<bool>& use_image,
              float min_score, Score& score) {
  evaluate(set, classify_sample, use_image, std::span(&min_score, 1), std::span(&score, 1));
}

// The dataset holds every other 60-frame block: number the clips present in
// order, and deal them out to the folds in turn.
std::vector<int> g_clips;
int fold_of(int clip, int folds) {
  const auto it = std::lower_bound(g_clips.begin(), g_clips.end(), clip);
  return static_cast<int>(it - g_clips.begin()) % folds;
}

// --dump: every sample of a set as raw arrays for train_cnn.py,
// PREFIX.meta.i32 (label, image, clip, fold, real, augmented,
// clipped | partial << 1 | beyond_region << 2, 0), PREFIX.features.f32,
// PREFIX.grey.f32 and PREFIX.paint.u8 (the patch); class probabilities come
// back as PREFIX.probs.f32 (kClassifierOutputs per sample) for --scores.
template <typename T>
void write_raw(const std::string& path, const std::vector<T>& values) {
  markloop::tools::OutputFile file;
  if (const markloop::Status opened = file.open(path); !opened) markloop::tools::fail_run(opened.message());
  std::fwrite(values.data(), sizeof(T), values.size(), file.get());
  if (const markloop::Status closed = file.close(); !closed) markloop::tools::fail_run(closed.message());
}

void dump_set(const ImageSet& set, const std::string& prefix, int folds) {
  std::vector<std::int32_t> meta;
  std::vector<float> features, grey;
  std::vector<std::uint8_t> paint;
  for (const Sample& s : set.samples) {
    meta.insert(meta.end(), {s.label, s.image, s.clip, s.real ? fold_of(s.clip, folds) : -1, s.real ? 1 : 0,
                             s.augmented ? 1 : 0,
                             (s.clipped ? 1 : 0) | (s.partial ? 2 : 0) | (s.beyond_region ? 4 : 0), 0});
    features.insert(features.end(), s.features.begin(), s.features.end());
    grey.insert(grey.end(), s.grey.begin(), s.grey.end());
    paint.insert(paint.end(), s.paint.begin(), s.paint.end());
  }
  write_raw(prefix + ".meta.i32", meta);
  write_raw(prefix + ".features.f32", features);
  write_raw(prefix + ".grey.f32", grey);
  write_raw(prefix + ".paint.u8", paint);
}

void read_probabilities(const ImageSet& set, const std::string& path, std::vector<float>& out) {
  const std::size_t expected = set.samples.size() * kClassifierOutputs * sizeof(float);
  const std::string whose = " (" + std::to_string(set.samples.size()) + " candidates of " + set.dir + ")";
  std::string bytes;
  if (const std::error_code ec = markloop::platform::read_file_bounded(path.c_str(), expected, bytes)) {
    if (ec == std::errc::file_too_large)
      fail(path + ": more than " + std::to_string(expected) + " bytes, expected " + std::to_string(expected) +
           whose);
    if (ec == std::errc::is_a_directory) fail(path + ": is a directory, not a probabilities file");
    fail(path + ": cannot open: " + ec.message());
  }
  if (bytes.size() != expected)
    fail(path + ": " + std::to_string(bytes.size()) + " bytes, expected " + std::to_string(expected) + whose);
  out.resize(expected / sizeof(float));
  std::memcpy(out.data(), bytes.data(), expected);
}

// Per sample of `set`, kClassifierOutputs probabilities in `values`.
ClassifySample by_probabilities(const ImageSet& set, const std::vector<float>& values) {
  return [&set, &values](const Sample& s, std::array<float, kClassifierOutputs>& p) {
    const auto index = static_cast<std::size_t>(&s - set.samples.data());
    std::copy_n(values.begin() + static_cast<std::ptrdiff_t>(index * kClassifierOutputs), kClassifierOutputs,
                p.begin());
    return static_cast<int>(std::max_element(p.begin(), p.end()) - p.begin());
  };
}

// The probabilities of every sample of `set` by `classify_sample` (zero
// where `wanted` is false), written for --scores.
void write_probabilities(const ImageSet& set, const ClassifySample& classify_sample,
                         const std::function<bool(const Sample&)>& wanted, std::vector<float>& out) {
  out.resize(set.samples.size() * kClassifierOutputs, 0.0f);
  for (std::size_t i = 0; i < set.samples.size(); ++i) {
    if (!wanted(set.samples[i])) continue;
    std::array<float, kClassifierOutputs> p;
    classify_sample(set.samples[i], p);
    std::copy(p.begin(), p.end(), out.begin() + static_cast<std::ptrdiff_t>(i * kClassifierOutputs));
  }
}

// How many annotated markings have at least one candidate on them: the
// recall the classifier could reach at best.
void print_coverage(const ImageSet& set) {
  std::map<std::string, std::pair<int, int>> per_class;
  std::vector<std::vector<const Sample*>> per_image(set.images.size());
  for (const Sample& s : set.samples)
    if (!s.augmented) per_image[s.image].push_back(&s);
  for (std::size_t i = 0; i < set.images.size(); ++i)
    for (const auto& a : set.images[i].annotations) {
      auto& [total, covered] = per_class[a.label];
      ++total;
      bool found = false;
      for (const Sample* s : per_image[i])
        if (inside(a.quad, s->centre[0], s->centre[1])) {
          found = true;
          break;
        }
      covered += found ? 1 : 0;
      if (!found && std::getenv("MARKLOOP_TRAIN_LIST_MISSED") != nullptr)
        std::printf("  missed %s %s\n", set.images[i].name.c_str(), a.label.c_str());
    }
  std::printf("\nCandidates on annotated markings (best reachable recall):\n");
  for (const auto& [label, tc] : per_class)
    std::printf("  %-14s %4d / %4d\n", label.c_str(), tc.second, tc.first);
}

// The build whose markloop-train gives this model bit for bit: the network's
// arithmetic follows the compiler's flags (CMakeLists.txt beside this file).
constexpr const char* kBuild = MARKLOOP_TRAIN_BUILD_DIR;

void write_bytes(const std::string& path, const std::string& bytes) {
  markloop::tools::OutputFile file;
  if (const markloop::Status opened = file.open(path); !opened) markloop::tools::fail_run(opened.message());
  std::fwrite(bytes.data(), 1, bytes.size(), file.get());
  if (const markloop::Status closed = file.close(); !closed) markloop::tools::fail_run(closed.message());
}

// --out: the model file (app/perception/model/README.md: every member's
// arrays in turn), and beside it FILE.txt saying how it was trained.
void write_model(const std::vector<Mlp>& members, const std::string& path, const std::string& command,
                 std::size_t samples) {
  namespace model_file = markloop::perception::model_file;
  const Mlp& first = members.front();
  std::vector<float> values;
  const auto add = [&values](const float* v, Eigen::Index n) { values.insert(values.end(), v, v + n); };
  for (const Mlp& m : members) {
    add(m.mean.data(), m.mean.size());
    add(m.inv_std.data(), m.inv_std.size());
    add(m.w1_row_major.data(), static_cast<Eigen::Index>(m.w1_row_major.size()));
    add(m.b1.data(), m.b1.size());
    add(m.w2_row_major.data(), static_cast<Eigen::Index>(m.w2_row_major.size()));
    add(m.b2.data(), m.b2.size());
  }
  const auto shape = [&first] {
    std::array<std::uint32_t, model_file::kShapeWords> s{};
    s[0] = static_cast<std::uint32_t>(first.inputs);
    s[1] = static_cast<std::uint32_t>(first.hidden);
    s[2] = static_cast<std::uint32_t>(first.outputs);
    return s;
  }();
  write_bytes(path, model_file::encode(model_file::Kind::kMlp, static_cast<std::uint32_t>(members.size()),
                                       shape, values));

  markloop::tools::OutputFile notes;
  if (const markloop::Status opened =
          notes.open(std::filesystem::path(path).replace_extension(".txt").string());
      !opened)
    markloop::tools::fail_run(opened.message());
  std::fprintf(notes.get(),
               "%s: the marking classifier's MLPs, written by markloop-train\n"
               "(format: app/perception/model/README.md). Regenerate with\n"
               "  app/tools/train/train-model.sh\n"
               "from the repository root (%s built by its preset; the real images are not part\n"
               "of the repository), which renders the simulator data and runs\n"
               "  %s\n"
               "%zu training candidates; %zu networks of %d inputs, %d hidden units (ReLU),\n"
               "%d outputs (the marking classes of marking_classes.hpp, then reject).\n"
               "Payload CRC-32 0x%08x.\n",
               std::filesystem::path(path).filename().c_str(), kBuild, command.c_str(), samples,
               members.size(), first.inputs, first.hidden, first.outputs,
               static_cast<unsigned>(model_file::payload_crc(values)));
  if (const markloop::Status closed = notes.close(); !closed) markloop::tools::fail_run(closed.message());
}

// The command line.
struct Options {
  std::string real_dir, real_camera, out, dump_dir;
  std::vector<std::string> scores_dirs;
  std::vector<std::string> sim_dirs, sim_test_dirs, sim_drive_dirs, sim_drive_train_dirs;
  int folds = 4;
  TrainOptions train;
  bool evaluate_builtin = false;
  bool help = false;
  std::string command;  // as the model's notes give it
};

// One option with a value; numbers fail when they are not.
void apply_option(Options& o, std::string_view name, const std::string& text) {
  using markloop::cli::parse_number;
  using markloop::cli::parse_whole;
  const char* value = text.c_str();
  if (name == "--real")
    o.real_dir = text;
  else if (name == "--real-camera")
    o.real_camera = text;
  else if (name == "--sim")
    o.sim_dirs.push_back(text);
  else if (name == "--sim-test")
    o.sim_test_dirs.push_back(text);
  else if (name == "--sim-drive")
    o.sim_drive_dirs.push_back(text);
  else if (name == "--sim-drive-train")
    o.sim_drive_train_dirs.push_back(text);
  else if (name == "--folds")
    o.folds = static_cast<int>(parse_whole(name, value));
  else if (name == "--seed")
    o.train.seed = parse_whole(name, value);
  else if (name == "--epochs")
    o.train.epochs = static_cast<int>(parse_whole(name, value));
  else if (name == "--members")
    o.train.members = static_cast<int>(parse_whole(name, value));
  else if (name == "--hidden")
    o.train.hidden = static_cast<int>(parse_whole(name, value));
  else if (name == "--real-weight")
    o.train.real_weight = static_cast<float>(parse_number(name, value));
  else if (name == "--reject-weight")
    o.train.reject_weight = static_cast<float>(parse_number(name, value));
  else if (name == "--weight-decay")
    o.train.weight_decay = static_cast<float>(parse_number(name, value));
  else if (name == "--weight-average")
    o.train.weight_average = static_cast<float>(parse_number(name, value));
  else if (name == "--out")
    o.out = text;
  else if (name == "--dump")
    o.dump_dir = text;
  else if (name == "--scores")
    o.scores_dirs.push_back(text);
}

// The options in the order given (the values before a --help are checked
// too, as they come).
Options parse_options(int argc, char** argv) {
  const markloop::cli::ParsedArgs args = markloop::cli::parse_args_or_fail(argc, argv, kOptions);
  Options o;
  o.command = std::string(kBuild) + "/bin/markloop-train";
  for (const auto& [name, value] : args.given()) {
    if (name == "--evaluate-builtin") {
      o.evaluate_builtin = true;
      continue;
    }
    o.command.append(" ").append(name).append(" ").append(value);
    apply_option(o, name, std::string(value));
  }
  o.help = args.help();
  return o;
}

// What the options ask for must make sense together.
void check_options(const Options& o) {
  if (!o.scores_dirs.empty() && (o.evaluate_builtin || !o.dump_dir.empty() || !o.out.empty()))
    fail("--scores judges given probabilities: not with --evaluate-builtin, --dump or --out");
  if (o.evaluate_builtin &&
      (!o.sim_dirs.empty() || !o.sim_drive_train_dirs.empty() || !o.out.empty() || !o.dump_dir.empty()))
    fail("--evaluate-builtin trains nothing: give only --real, --real-camera, --sim-test and --sim-drive");
  if (o.evaluate_builtin && o.real_dir.empty() && o.sim_test_dirs.empty() && o.sim_drive_dirs.empty())
    fail("--evaluate-builtin: nothing to judge: give --real, --sim-test or --sim-drive");
  if (!o.evaluate_builtin && o.real_dir.empty() && o.sim_dirs.empty() && o.sim_drive_train_dirs.empty())
    fail("no training data: give --real, --sim or --sim-drive-train");
  if (!o.real_dir.empty() && o.real_camera.empty()) fail("--real needs --real-camera");
  if (o.train.members < 1 || o.train.members > kMaxMembers)
    fail("--members must be 1.." + std::to_string(kMaxMembers));
  if (o.train.hidden < 1 || o.train.hidden > kMaxHidden)
    fail("--hidden must be 1.." + std::to_string(kMaxHidden));
  if (!(o.train.weight_average >= 0.0f && o.train.weight_average < 1.0f))
    fail("--weight-average must be at least 0 and below 1");
}

// The sets trained on (the real images first, when given) and those only judged.
struct Sets {
  std::vector<ImageSet> train, tests;
};

Sets load_sets(const Options& o) {
  Sets sets;
  if (!o.real_dir.empty()) {
    sets.train.push_back(
        extract(o.real_dir, o.real_camera, true, o.evaluate_builtin ? Use::kEvaluate : Use::kTrain));
    for (const auto& image : sets.train.front().images) g_clips.push_back(train::clip_of(image.name));
    std::sort(g_clips.begin(), g_clips.end());
    g_clips.erase(std::unique(g_clips.begin(), g_clips.end()), g_clips.end());
  }
  for (const auto& dir : o.sim_dirs)
    sets.train.push_back(extract(dir, dir + "/camera.yaml", false, Use::kTrain));
  for (const auto& dir : o.sim_drive_train_dirs)
    sets.train.push_back(extract(dir, dir + "/camera.yaml", false, Use::kTrain, true));
  for (const auto& dir : o.sim_test_dirs)
    sets.tests.push_back(extract(dir, dir + "/camera.yaml", false, Use::kEvaluate));
  for (const auto& dir : o.sim_drive_dirs)
    sets.tests.push_back(extract(dir, dir + "/camera.yaml", false, Use::kEvaluate, true));
  return sets;
}

float default_min_score() {
  return DetectorConfig{}.min_score;
}

// The real images judged by a model trained on them: a fit, not a validation.
void judge_real_fit(const ImageSet& real, const ClassifySample& model, const char* title) {
  Score fit;
  evaluate(real, model, std::vector<bool>(real.images.size(), true), default_min_score(), fit);
  print_score(title, fit, true);
}

void judge_tests(const std::vector<ImageSet>& tests, const ClassifySample& model) {
  for (const auto& test : tests) {
    print_coverage(test);
    Score score;
    evaluate(test, model, std::vector<bool>(test.images.size(), true), default_min_score(), score);
    print_score(("Simulator test set " + test.dir + " (never trained on):").c_str(), score, false);
  }
}

// --dump DIR: the candidates for train_cnn.py, and the MLPs' probabilities
// (DIR/mlp/) for the blend judged with --scores.
void dump_candidates(const Options& o, const Sets& sets) {
  std::error_code made;
  std::filesystem::create_directories(o.dump_dir + "/mlp", made);
  if (made) markloop::tools::fail_run(o.dump_dir + "/mlp: cannot create the directory: " + made.message());
  markloop::tools::OutputFile index;
  if (const markloop::Status opened = index.open(o.dump_dir + "/sets.txt"); !opened)
    markloop::tools::fail_run(opened.message());
  for (std::size_t k = 0; k < sets.train.size(); ++k) {
    dump_set(sets.train[k], o.dump_dir + "/train" + std::to_string(k), o.folds);
    std::fprintf(index.get(), "train%zu %s %zu\n", k, sets.train[k].dir.c_str(),
                 sets.train[k].samples.size());
  }
  for (std::size_t k = 0; k < sets.tests.size(); ++k) {
    dump_set(sets.tests[k], o.dump_dir + "/test" + std::to_string(k), o.folds);
    std::fprintf(index.get(), "test%zu %s %zu\n", k, sets.tests[k].dir.c_str(), sets.tests[k].samples.size());
  }
  if (const markloop::Status closed = index.close(); !closed) markloop::tools::fail_run(closed.message());
  // The patches written must be those the detector classified.
  if (g_patch_mismatches > 0)
    fail(std::to_string(g_patch_mismatches) + " candidates' patches do not give their features");
}

// The probabilities written by --dump (MLPs, the first DIR) and
// train_cnn.py (a network per further DIR) for `set` (file NAME.probs.f32
// in each), blended as the detector blends them (blend_with_networks, where
// networks_needed). One DIR alone is taken as it is.
std::vector<float> blended_probabilities(const ImageSet& set, const std::string& name,
                                         const std::vector<std::string>& scores_dirs) {
  std::vector<std::vector<float>> by_dir(scores_dirs.size());
  for (std::size_t d = 0; d < scores_dirs.size(); ++d)
    read_probabilities(set, scores_dirs[d] + "/" + name + ".probs.f32", by_dir[d]);
  const DetectorConfig defaults;
  std::vector<float> blended = by_dir.front();
  std::vector<std::array<float, kClassifierOutputs>> networks(by_dir.size() - 1);
  for (std::size_t at = 0; at < blended.size(); at += kClassifierOutputs) {
    std::array<float, kClassifierOutputs> sample;
    std::copy_n(blended.begin() + static_cast<std::ptrdiff_t>(at), kClassifierOutputs, sample.begin());
    if (networks.empty() || !networks_needed(sample, defaults.cnn_share, defaults.skip_networks_at)) continue;
    for (std::size_t m = 0; m < networks.size(); ++m)
      std::copy_n(by_dir[m + 1].begin() + static_cast<std::ptrdiff_t>(at), kClassifierOutputs,
                  networks[m].begin());
    blend_with_networks(sample, networks, defaults.cnn_share);
    std::copy(sample.begin(), sample.end(), blended.begin() + static_cast<std::ptrdiff_t>(at));
  }
  return blended;
}

// --scores: the probabilities given, blended, judged on the real images
// (their cross-validation) and the test sets.
void judge_scores(const Options& o, const Sets& sets) {
  const float min_score = default_min_score();
  if (!o.real_dir.empty()) {
    const ImageSet& real = sets.train.front();
    const std::vector<float> thresholds = {min_score, 0.5f, 0.6f, 0.7f, 0.8f, 0.9f};
    std::vector<Score> by_threshold(thresholds.size());
    print_coverage(real);
    const std::vector<float> blended = blended_probabilities(real, "train0", o.scores_dirs);
    evaluate(real, by_probabilities(real, blended), std::vector<bool>(real.images.size(), true), thresholds,
             by_threshold);
    print_score("Real images, cross-validation by clip, the probabilities given blended:",
                by_threshold.front(), true);
    print_operating_points(std::span(thresholds).subspan(1), std::span(by_threshold).subspan(1));
  }
  for (std::size_t k = 0; k < sets.tests.size(); ++k) {
    const ImageSet& test = sets.tests[k];
    Score score;
    print_coverage(test);
    const std::vector<float> blended = blended_probabilities(test, "test" + std::to_string(k), o.scores_dirs);
    evaluate(test, by_probabilities(test, blended), std::vector<bool>(test.images.size(), true), min_score,
             score);
    print_score(("Simulator test set " + test.dir + ", the probabilities given blended:").c_str(), score,
                false);
  }
}

// --evaluate-builtin: the compiled-in model as the detector classifies (the
// MLPs blended with the networks, read turned too where not sure). The real
// images annotate only markings seen from ahead: those read turned and
// reported are counted apart, most of them the oncoming lanes' arrows.
void judge_builtin(const Options& o, const Sets& sets) {
  int turned = 0, turned_unannotated = 0;
  CandidateClassifier classifier{DetectorConfig{}};
  const ClassifySample model = [&](const Sample& s, std::array<float, kClassifierOutputs>& p) {
    PatchScratch patch;
    patch.grey = s.grey;
    for (std::size_t i = 0; i < patch.paint.size(); ++i) patch.paint[i] = s.paint[i] * (1.0f / 255.0f);
    const CandidateClassifier::Reading reading = classifier.read(s.features, patch, p);
    if (reading.turned && reading.score >= default_min_score() && !s.clipped && !s.beyond_region) {
      ++turned;
      if (s.label == kRejectClass) ++turned_unannotated;
    }
    return reading.label;
  };
  if (!o.real_dir.empty()) {
    print_coverage(sets.train.front());
    judge_real_fit(sets.train.front(), model,
                   "Real images, the built-in model (trained on them: a fit, not a validation):");
    std::printf("read turned half way round (seen from behind): %d, %d of them on no annotated marking\n",
                turned, turned_unannotated);
  }
  judge_tests(sets.tests, model);
}

// The training samples: every labelled one, less the real images of the
// fold held out (-1: none).
std::vector<const Sample*> training_data(const std::vector<ImageSet>& sets, int held_out_fold, int folds) {
  std::vector<const Sample*> data;
  for (const auto& set : sets)
    for (const Sample& s : set.samples) {
      if (s.label < 0) continue;
      if (held_out_fold >= 0 && s.real && fold_of(s.clip, folds) == held_out_fold) continue;
      data.push_back(&s);
    }
  return data;
}

// Cross-validation by clip on the real images: each fold judged by a model
// trained without it; with --dump, the probabilities so found.
void cross_validate(const Options& o, const Sets& sets) {
  const ImageSet& real = sets.train.front();
  print_coverage(real);
  // The default threshold first (the full table), then the operating points.
  const std::vector<float> thresholds = {default_min_score(), 0.5f, 0.6f, 0.7f, 0.8f, 0.9f};
  std::vector<Score> by_threshold(thresholds.size());
  std::vector<float> cv_probabilities;  // each real candidate's, by the model that held it out
  for (int fold = 0; fold < o.folds; ++fold) {
    const auto data = training_data(sets.train, fold, o.folds);
    const std::vector<Mlp> members = train_members(data, o.train);
    std::vector<bool> use(real.images.size(), false);
    for (std::size_t i = 0; i < real.images.size(); ++i)
      use[i] = fold_of(train::clip_of(real.images[i].name), o.folds) == fold;
    evaluate(real, view(members), use, thresholds, by_threshold);
    if (!o.dump_dir.empty()) {
      std::vector<float> fold_probabilities;
      write_probabilities(
          real, by_model(view(members)),
          [&](const Sample& s) { return !s.augmented && fold_of(s.clip, o.folds) == fold; },
          fold_probabilities);
      if (cv_probabilities.empty()) cv_probabilities.assign(fold_probabilities.size(), 0.0f);
      for (std::size_t i = 0; i < fold_probabilities.size(); ++i)
        cv_probabilities[i] += fold_probabilities[i];
    }
    std::printf("fold %d: trained on %zu candidates\n", fold, data.size());
  }
  char title[160];
  std::snprintf(title, sizeof title,
                "Real images, %d-fold cross-validation by clip (each clip judged by a model "
                "trained without it):",
                o.folds);
  print_score(title, by_threshold.front(), true);
  print_operating_points(std::span(thresholds).subspan(1), std::span(by_threshold).subspan(1));
  if (!o.dump_dir.empty()) write_raw(o.dump_dir + "/mlp/train0.probs.f32", cv_probabilities);
}

// The model trained on all training data: judged on the test sets, its
// probabilities dumped, written with --out.
void train_final(const Options& o, const Sets& sets) {
  const auto data = training_data(sets.train, -1, o.folds);
  const std::vector<Mlp> members = train_members(data, o.train);
  if (std::getenv("MARKLOOP_TRAIN_SHOW_FIT") != nullptr && !o.real_dir.empty())
    judge_real_fit(sets.train.front(), by_model(view(members)),
                   "Real images, training fit (not a validation):");
  judge_tests(sets.tests, by_model(view(members)));
  for (std::size_t k = 0; k < sets.tests.size() && !o.dump_dir.empty(); ++k) {
    std::vector<float> test_probabilities;
    write_probabilities(
        sets.tests[k], by_model(view(members)), [](const Sample&) { return true; }, test_probabilities);
    write_raw(o.dump_dir + "/mlp/test" + std::to_string(k) + ".probs.f32", test_probabilities);
  }
  if (!o.out.empty()) {
    write_model(members, o.out, o.command, data.size());
    std::printf("\nwrote %s (%zu training candidates)\n", o.out.c_str(), data.size());
  }
}

int train_main(int argc, char** argv) {
  fix_matrix_product_blocking();  // before any training thread starts
  const Options options = parse_options(argc, argv);
  if (options.help) {
    std::fputs(usage().c_str(), stdout);
    return 0;
  }
  check_options(options);
  const Sets sets = load_sets(options);
  if (!options.dump_dir.empty()) dump_candidates(options, sets);
  if (!options.scores_dirs.empty()) {
    judge_scores(options, sets);
    return 0;
  }
  if (options.evaluate_builtin) {
    judge_builtin(options, sets);
    return 0;
  }
  if (!options.real_dir.empty() && options.folds > 1) cross_validate(options, sets);
  train_final(options, sets);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  markloop::cli::program_name() = "markloop-train";
  const int status = train_main(argc, argv);
  if (const markloop::Status flushed = markloop::tools::flush_stdout(); !flushed)
    markloop::tools::fail_run(flushed.message());
  return status;
}
