#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <random>
#include <span>
#include <string>
#include <vector>

#include <catch2/catch_approx.hpp>
#include <catch2/catch_test_macros.hpp>

#include "app/perception/marking_classifier.hpp"
#include "app/perception/model/model_file.hpp"

using namespace markloop::perception;

namespace {

// The network of marking_classifier.hpp written the plain way: a tensor per
// layer, bounds checked instead of padded, as PyTorch defines the layers.
struct Tensor {
  int channels, rows, cols;
  std::vector<float> v;
  Tensor(int ch, int r, int c)
      : channels(ch), rows(r), cols(c), v(static_cast<std::size_t>(ch * r * c), 0.0f) {}
  float& at(int ch, int r, int c) { return v[static_cast<std::size_t>((ch * rows + r) * cols + c)]; }
  float get(int ch, int r, int c) const {
    if (r < 0 || r >= rows || c < 0 || c >= cols) return 0.0f;
    return v[static_cast<std::size_t>((ch * rows + r) * cols + c)];
  }
};

Tensor conv_relu(const Tensor& in, const std::vector<float>& w, const std::vector<float>& b,
                 int out_channels) {
  Tensor out(out_channels, in.rows, in.cols);
  for (int o = 0; o < out_channels; ++o)
    for (int r = 0; r < in.rows; ++r)
      for (int c = 0; c < in.cols; ++c) {
        double s = b[static_cast<std::size_t>(o)];
        for (int i = 0; i < in.channels; ++i)
          for (int ky = -1; ky <= 1; ++ky)
            for (int kx = -1; kx <= 1; ++kx)
              s += w[static_cast<std::size_t>(((o * in.channels + i) * 3 + ky + 1) * 3 + kx + 1)] *
                   in.get(i, r + ky, c + kx);
        out.at(o, r, c) = static_cast<float>(std::max(s, 0.0));
      }
  return out;
}

Tensor max_pool(const Tensor& in) {
  Tensor out(in.channels, in.rows / 2, in.cols / 2);
  for (int ch = 0; ch < in.channels; ++ch)
    for (int r = 0; r < out.rows; ++r)
      for (int c = 0; c < out.cols; ++c)
        out.at(ch, r, c) = std::max({in.get(ch, 2 * r, 2 * c), in.get(ch, 2 * r, 2 * c + 1),
                                     in.get(ch, 2 * r + 1, 2 * c), in.get(ch, 2 * r + 1, 2 * c + 1)});
  return out;
}

std::vector<float> random_values(std::mt19937& rng, int n, float scale) {
  std::uniform_real_distribution<float> u(-scale, scale);
  std::vector<float> v(static_cast<std::size_t>(n));
  for (float& x : v) x = u(rng);
  return v;
}

constexpr float kAlwaysRun = 2.0f;  // no MLP reject probability reaches it: the networks always run

using Probabilities = std::array<float, kClassifierOutputs>;

// Random weights for each layer of one network, drawn in the layers' order.
struct RandomWeights {
  std::vector<float> conv1_w, conv1_b, conv2_w, conv2_b, conv3_w, conv3_b, shape_mean, shape_inv_std, fc1_w,
      fc1_b, fc2_w, fc2_b;

  explicit RandomWeights(std::mt19937& rng)
      : conv1_w(random_values(rng, kCnnChannels1 * kCnnInputChannels * 9, 0.5f)),
        conv1_b(random_values(rng, kCnnChannels1, 0.1f)),
        conv2_w(random_values(rng, kCnnChannels2 * kCnnChannels1 * 9, 0.3f)),
        conv2_b(random_values(rng, kCnnChannels2, 0.1f)),
        conv3_w(random_values(rng, kCnnChannels3 * kCnnChannels2 * 9, 0.2f)),
        conv3_b(random_values(rng, kCnnChannels3, 0.1f)),
        shape_mean(random_values(rng, kShapeFeatures, 1.0f)),
        shape_inv_std(kShapeFeatures, 0.7f),
        fc1_w(random_values(rng, kCnnHidden * kCnnHeadInputs, 0.05f)),
        fc1_b(random_values(rng, kCnnHidden, 0.1f)),
        fc2_w(random_values(rng, kClassifierOutputs * kCnnHidden, 0.3f)),
        fc2_b(random_values(rng, kClassifierOutputs, 0.1f)) {}

  // The network on these weights; valid while they live.
  CnnNet net() const {
    return CnnNet{conv1_w.data(), conv1_b.data(), conv2_w.data(),    conv2_b.data(),
                  conv3_w.data(), conv3_b.data(), shape_mean.data(), shape_inv_std.data(),
                  fc1_w.data(),   fc1_b.data(),   fc2_w.data(),      fc2_b.data()};
  }
};

// What the classifier is given: a patch and features at random, and its scratch.
struct ClassifierInputs {
  PatchScratch patch;
  Features features{};
  CnnScratch scratch;

  explicit ClassifierInputs(std::mt19937& rng) {
    std::normal_distribution<float> grey(0.0f, 1.0f);
    std::uniform_int_distribution<int> paint(0, 255);
    for (float& g : patch.grey) g = grey(rng);
    for (float& p : patch.paint) p = static_cast<float>(paint(rng)) / 255.0f;
    for (float& f : features) f = grey(rng);
  }
};

// The head's inputs: the third convolution's output, then the normalised
// shape features.
std::vector<double> reference_head(const RandomWeights& w, const ClassifierInputs& in) {
  Tensor input(kCnnInputChannels, kPatchRows, kPatchCols);
  for (int r = 0; r < kPatchRows; ++r)
    for (int c = 0; c < kPatchCols; ++c) {
      input.at(0, r, c) = in.patch.grey[static_cast<std::size_t>(r * kPatchCols + c)];
      input.at(1, r, c) = in.patch.paint[static_cast<std::size_t>(r * kPatchCols + c)];
    }
  const Tensor layer3 =
      conv_relu(max_pool(conv_relu(max_pool(conv_relu(input, w.conv1_w, w.conv1_b, kCnnChannels1)), w.conv2_w,
                                   w.conv2_b, kCnnChannels2)),
                w.conv3_w, w.conv3_b, kCnnChannels3);
  std::vector<double> head(layer3.v.begin(), layer3.v.end());
  for (int i = 0; i < kShapeFeatures; ++i)
    head.push_back((in.features[static_cast<std::size_t>(kFeatureCount - kShapeFeatures + i)] -
                    w.shape_mean[static_cast<std::size_t>(i)]) *
                   w.shape_inv_std[static_cast<std::size_t>(i)]);
  return head;
}

// The reference network's exponentiated logits and their sum.
struct ReferenceOutputs {
  std::vector<double> logits;
  double total = 0.0;
};

ReferenceOutputs reference_outputs(const RandomWeights& w, const ClassifierInputs& in) {
  const std::vector<double> head = reference_head(w, in);
  REQUIRE(head.size() == static_cast<std::size_t>(kCnnHeadInputs));
  std::vector<double> hidden(kCnnHidden);
  ReferenceOutputs out{std::vector<double>(kClassifierOutputs), 0.0};
  for (int j = 0; j < kCnnHidden; ++j) {
    double s = w.fc1_b[static_cast<std::size_t>(j)];
    for (int i = 0; i < kCnnHeadInputs; ++i)
      s += w.fc1_w[static_cast<std::size_t>(j * kCnnHeadInputs + i)] * head[static_cast<std::size_t>(i)];
    hidden[static_cast<std::size_t>(j)] = std::max(s, 0.0);
  }
  for (int k = 0; k < kClassifierOutputs; ++k) {
    double s = w.fc2_b[static_cast<std::size_t>(k)];
    for (int j = 0; j < kCnnHidden; ++j)
      s += w.fc2_w[static_cast<std::size_t>(k * kCnnHidden + j)] * hidden[static_cast<std::size_t>(j)];
    out.logits[static_cast<std::size_t>(k)] = std::exp(s);
    out.total += out.logits[static_cast<std::size_t>(k)];
  }
  return out;
}

// The network alone (share 1): the reference's softmax and its best class.
void check_network_alone(const CnnModel& one, ClassifierInputs& in, const ReferenceOutputs& reference,
                         Probabilities& from_net) {
  const std::vector<double>& logits = reference.logits;
  const int best =
      classify(builtin_marking_model(), &one, 1.0f, kAlwaysRun, in.features, in.patch, in.scratch, from_net);
  int expected_best = 0;
  for (int k = 0; k < kClassifierOutputs; ++k) {
    CHECK(from_net[static_cast<std::size_t>(k)] ==
          Catch::Approx(logits[static_cast<std::size_t>(k)] / reference.total).margin(1e-5));
    if (logits[static_cast<std::size_t>(k)] > logits[static_cast<std::size_t>(expected_best)])
      expected_best = k;
  }
  CHECK(best == expected_best);
}

// Blended half and half with the MLPs: their geometric mean, normalised.
void check_blend_with_mlps(const CnnModel& one, ClassifierInputs& in, const Probabilities& from_net,
                           const Probabilities& from_mlps, Probabilities& blended) {
  const int blended_best =
      classify(builtin_marking_model(), &one, 0.5f, kAlwaysRun, in.features, in.patch, in.scratch, blended);
  std::array<double, kClassifierOutputs> product;
  double product_total = 0.0;
  for (std::size_t k = 0; k < product.size(); ++k) {
    product[k] = std::sqrt(std::max(double{from_net[k]}, 1e-12) * std::max(double{from_mlps[k]}, 1e-12));
    product_total += product[k];
  }
  for (std::size_t k = 0; k < product.size(); ++k)
    CHECK(blended[k] == Catch::Approx(product[k] / product_total).margin(1e-6));
  CHECK(blended_best == static_cast<int>(std::max_element(product.begin(), product.end()) - product.begin()));
}

// Two networks share the network's half alike: mlp^(1/2) net^(1/4) other^(1/4).
void check_two_networks(const CnnModel& two, const CnnNet& other, ClassifierInputs& in,
                        const Probabilities& from_net, const Probabilities& from_mlps,
                        Probabilities& blended) {
  std::array<float, kClassifierOutputs> from_other;
  classify(builtin_marking_model(), &two, 0.0f, kAlwaysRun, in.features, in.patch, in.scratch, blended);
  CHECK(blended == from_mlps);
  const CnnModel other_alone{1, {other}};
  classify(builtin_marking_model(), &other_alone, 1.0f, kAlwaysRun, in.features, in.patch, in.scratch,
           from_other);
  const int ensemble_best =
      classify(builtin_marking_model(), &two, 0.5f, kAlwaysRun, in.features, in.patch, in.scratch, blended);
  std::array<double, kClassifierOutputs> product;
  double product_total = 0.0;
  for (std::size_t k = 0; k < product.size(); ++k) {
    product[k] =
        std::sqrt(std::max(double{from_mlps[k]}, 1e-12)) *
        std::pow(std::max(double{from_net[k]}, 1e-12) * std::max(double{from_other[k]}, 1e-12), 0.25);
    product_total += product[k];
  }
  for (std::size_t k = 0; k < product.size(); ++k)
    CHECK(blended[k] == Catch::Approx(product[k] / product_total).margin(1e-6));
  CHECK(ensemble_best ==
        static_cast<int>(std::max_element(product.begin(), product.end()) - product.begin()));
}

// The networks skipped where the MLPs' reject reaches the bound: the MLPs' own.
void check_networks_skipped_at_reject_bound(const CnnModel& two, ClassifierInputs& in,
                                            const Probabilities& from_mlps, Probabilities& blended) {
  const float mlp_reject = from_mlps[static_cast<std::size_t>(kRejectClass)];
  classify(builtin_marking_model(), &two, 0.5f, mlp_reject, in.features, in.patch, in.scratch, blended);
  CHECK(blended == from_mlps);
  classify(builtin_marking_model(), &two, 0.5f, std::nextafter(mlp_reject, 2.0f), in.features, in.patch,
           in.scratch, blended);
  CHECK(blended != from_mlps);
}

}  // namespace

TEST_CASE("the network's probabilities are those of its layers written out plainly") {
  std::mt19937 rng(7);
  const RandomWeights weights(rng);
  const CnnNet net = weights.net();
  const CnnModel one{1, {net}};
  // A second member: the same layers, other output weights.
  const auto fc2_w_other = random_values(rng, kClassifierOutputs * kCnnHidden, 0.3f);
  CnnNet other = net;
  other.fc2_w = fc2_w_other.data();
  const CnnModel two{2, {net, other}};
  REQUIRE(cnn_is_usable(net));
  REQUIRE(cnn_is_usable(one));
  REQUIRE(cnn_is_usable(two));
  REQUIRE_FALSE(cnn_is_usable(CnnNet{}));
  REQUIRE_FALSE(cnn_is_usable(CnnModel{}));
  REQUIRE_FALSE(cnn_is_usable(CnnModel{2, {net, CnnNet{}}}));

  ClassifierInputs in(rng);
  const ReferenceOutputs reference = reference_outputs(weights, in);

  Probabilities from_net, from_mlps, blended;
  check_network_alone(one, in, reference, from_net);
  classify(builtin_marking_model(), in.features, from_mlps);
  check_blend_with_mlps(one, in, from_net, from_mlps, blended);
  check_two_networks(two, other, in, from_net, from_mlps, blended);
  check_networks_skipped_at_reject_bound(two, in, from_mlps, blended);
  // No network, or share 0: the MLPs alone.
  classify(builtin_marking_model(), nullptr, 0.5f, kAlwaysRun, in.features, in.patch, in.scratch, blended);
  CHECK(blended == from_mlps);
}

namespace {

namespace model_file = markloop::perception::model_file;

void append(std::vector<float>& to, const float* from, int count) {
  for (const float v : std::span(from, static_cast<std::size_t>(count))) to.push_back(v);
}

// The compiled-in weights in the model files' order (README.md in
// app/perception/model).
std::vector<float> compiled_in_mlp() {
  const MlpModel& model = builtin_marking_model();
  std::vector<float> values;
  for (int m = 0; m < model.members; ++m) {
    const MlpNet& n = model.nets[static_cast<std::size_t>(m)];
    append(values, n.feature_mean, n.inputs);
    append(values, n.feature_inv_std, n.inputs);
    append(values, n.w1, n.hidden * n.inputs);
    append(values, n.b1, n.hidden);
    append(values, n.w2, n.outputs * n.hidden);
    append(values, n.b2, n.outputs);
  }
  return values;
}

std::vector<float> compiled_in_cnn() {
  const CnnModel& model = builtin_marking_cnn();
  std::vector<float> values;
  append(values, model.nets[0].shape_mean, kShapeFeatures);
  append(values, model.nets[0].shape_inv_std, kShapeFeatures);
  for (int m = 0; m < model.members; ++m) {
    const CnnNet& n = model.nets[static_cast<std::size_t>(m)];
    append(values, n.conv1_w, kCnnChannels1 * kCnnInputChannels * 9);
    append(values, n.conv1_b, kCnnChannels1);
    append(values, n.conv2_w, kCnnChannels2 * kCnnChannels1 * 9);
    append(values, n.conv2_b, kCnnChannels2);
    append(values, n.conv3_w, kCnnChannels3 * kCnnChannels2 * 9);
    append(values, n.conv3_b, kCnnChannels3);
    append(values, n.fc1_w, kCnnHidden * kCnnHeadInputs);
    append(values, n.fc1_b, kCnnHidden);
    append(values, n.fc2_w, kClassifierOutputs * kCnnHidden);
    append(values, n.fc2_b, kClassifierOutputs);
  }
  return values;
}

std::string read_model_file(const std::string& name) {
  std::ifstream in(std::string(MARKLOOP_SOURCE_DIR) + "/app/perception/model/" + name, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

bool same_bits(std::span<const std::byte> payload, const std::vector<float>& values) {
  return payload.size() == values.size() * sizeof(float) &&
         std::memcmp(payload.data(), values.data(), payload.size()) == 0;
}

}  // namespace

TEST_CASE("the compiled-in weights are the model files' payload") {
  const std::string mlp_bytes = read_model_file("marking_mlp.bin");
  const auto mlp = model_file::decode(mlp_bytes, "marking_mlp.bin");
  REQUIRE(mlp.ok());
  CHECK(mlp->header.kind == model_file::Kind::kMlp);
  CHECK(static_cast<int>(mlp->header.members) == builtin_marking_model().members);
  CHECK(static_cast<int>(mlp->header.shape[0]) == kFeatureCount);
  CHECK(static_cast<int>(mlp->header.shape[2]) == kClassifierOutputs);
  CHECK(same_bits(mlp->payload, compiled_in_mlp()));

  const std::string cnn_bytes = read_model_file("marking_cnn.bin");
  const auto cnn = model_file::decode(cnn_bytes, "marking_cnn.bin");
  REQUIRE(cnn.ok());
  CHECK(cnn->header.kind == model_file::Kind::kCnn);
  CHECK(static_cast<int>(cnn->header.members) == builtin_marking_cnn().members);
  CHECK(same_bits(cnn->payload, compiled_in_cnn()));
}

TEST_CASE("a model file is refused when damaged, saying why") {
  const std::vector<float> values = {1.0f, -0.0f, 0x1.fffffep127f, 1e-40f};
  const std::string good = model_file::encode(model_file::Kind::kMlp, 1, {1, 1, 1}, values);
  REQUIRE(good.size() == 64 + 4 * values.size());
  const auto decoded = model_file::decode(good, "m.bin");
  REQUIRE(decoded.ok());
  CHECK(same_bits(decoded->payload, values));
  CHECK(decoded->header.crc32 == model_file::payload_crc(values));

  std::string flipped = good;
  flipped[70] = static_cast<char>(flipped[70] ^ 1);
  const auto damaged = model_file::decode(flipped, "m.bin");
  REQUIRE_FALSE(damaged.ok());
  CHECK(damaged.message() == "m.bin: the payload's CRC-32 does not match the header's: the file is damaged");
  const auto short_file = model_file::decode(std::string_view(good).substr(0, good.size() - 1), "m.bin");
  REQUIRE_FALSE(short_file.ok());
  CHECK(short_file.message() == "m.bin: 79 bytes, the header gives 80");
  std::string other = good;
  other[0] = 'X';
  CHECK(model_file::decode(other, "m.bin").message() == "m.bin: not a markloop model file");
  other = good;
  other[4] = 2;
  CHECK(model_file::decode(other, "m.bin").message() == "m.bin: format version 2, expected 1");
  CHECK(model_file::decode(good.substr(0, 10), "m.bin").message() ==
        "m.bin: 10 bytes, shorter than the 64-byte header");
}
