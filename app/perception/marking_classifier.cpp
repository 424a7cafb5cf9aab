#include "app/perception/marking_classifier.hpp"

#include <algorithm>
#include <cmath>

namespace markloop::perception {

namespace {

bool net_is_usable(const MlpNet& m) {
  return m.inputs == kFeatureCount && m.outputs == kClassifierOutputs && m.hidden > 0 &&
         m.hidden <= kMaxHidden && m.feature_mean != nullptr && m.feature_inv_std != nullptr &&
         m.w1 != nullptr && m.b1 != nullptr && m.w2 != nullptr && m.b2 != nullptr;
}

// ReLU(W x + b) for `outputs` rows of `inputs` weights each.
void dense_relu(const float* weights, const float* bias, const float* x, int inputs, int outputs,
                float* out) {
  for (int j = 0; j < outputs; ++j) {
    const float* w = weights + static_cast<std::size_t>(j) * inputs;
    // Eight independent partial sums: the compiler can keep them in one
    // vector register (a single running sum would serialise every add).
    std::array<float, 8> partial{};
    int i = 0;
    for (; i + 8 <= inputs; i += 8)
      for (int k = 0; k < 8; ++k) partial[k] += w[i + k] * x[i + k];
    float s = bias[j];
    for (; i < inputs; ++i) s += w[i] * x[i];
    for (float p : partial) s += p;
    out[j] = std::max(s, 0.0f);
  }
}

// The class probabilities: softmax of W x + b, `inputs` weights per class.
void dense_softmax(const float* weights, const float* bias, const float* x, int inputs,
                   std::array<float, kClassifierOutputs>& out) {
  for (int k = 0; k < kClassifierOutputs; ++k) {
    const float* w = weights + static_cast<std::size_t>(k) * inputs;
    float s = bias[k];
    for (int j = 0; j < inputs; ++j) s += w[j] * x[j];
    out[k] = s;
  }
  softmax_in_place(out);
}

// Adds one network's class probabilities to `sum`.
void add_probabilities(const MlpNet& m, const Features& features,
                       std::array<float, kClassifierOutputs>& sum) {
  std::array<float, kFeatureCount> x;
  for (int i = 0; i < kFeatureCount; ++i) x[i] = (features[i] - m.feature_mean[i]) * m.feature_inv_std[i];
  std::array<float, kMaxHidden> h;
  dense_relu(m.w1, m.b1, x.data(), kFeatureCount, m.hidden, h.data());
  std::array<float, kClassifierOutputs> probabilities;
  dense_softmax(m.w2, m.b2, h.data(), m.hidden, probabilities);
  for (int k = 0; k < kClassifierOutputs; ++k) sum[k] += probabilities[k];
}

// One 3x3 convolution with padding 1 and ReLU: `in` holds `in_channels`
// planes of (rows + 2) x (cols + 2) with a zero border, `out` gets
// `out_channels` planes of rows x cols. Innermost along a row: the compiler
// vectorises it.
template <int rows, int cols>
void convolve(const float* in, int in_channels, const float* weights, const float* bias, int out_channels,
              float* out) {
  constexpr int padded_cols = cols + 2, padded_plane = (rows + 2) * padded_cols;
  for (int o = 0; o < out_channels; ++o) {
    float* plane = out + o * rows * cols;
    std::fill(plane, plane + rows * cols, bias[o]);
    for (int i = 0; i < in_channels; ++i) {
      const float* w = weights + (o * in_channels + i) * 9;
      const float* source = in + i * padded_plane;
      for (int ky = 0; ky < 3; ++ky)
        for (int kx = 0; kx < 3; ++kx) {
          const float weight = w[ky * 3 + kx];
          for (int r = 0; r < rows; ++r) {
            const float* from = source + (r + ky) * padded_cols + kx;
            float* to = plane + r * cols;
            for (int c = 0; c < cols; ++c) to[c] += weight * from[c];
          }
        }
    }
    for (int k = 0; k < rows * cols; ++k) plane[k] = std::max(plane[k], 0.0f);
  }
}

// 2x2 max pooling of `channels` planes of rows x cols into planes of
// (rows / 2 + 2) x (cols / 2 + 2) with a zero border (the next convolution's
// padding).
template <int rows, int cols>
void pool(const float* in, int channels, float* out) {
  constexpr int out_rows = rows / 2 + 2, out_cols = cols / 2 + 2;
  std::fill(out, out + channels * out_rows * out_cols, 0.0f);
  for (int ch = 0; ch < channels; ++ch)
    for (int r = 0; r < rows / 2; ++r)
      for (int c = 0; c < cols / 2; ++c) {
        const float* p = in + ch * rows * cols + 2 * r * cols + 2 * c;
        out[ch * out_rows * out_cols + (r + 1) * out_cols + c + 1] =
            std::max(std::max(p[0], p[1]), std::max(p[cols], p[cols + 1]));
      }
}

void cnn_probabilities(const CnnNet& n, const Features& features, const PatchScratch& patch,
                       CnnScratch& scratch, std::array<float, kClassifierOutputs>& out) {
  constexpr int rows = kPatchRows, cols = kPatchCols;
  auto& input = scratch.input;  // zero border: the first convolution's padding
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) {
      const int at = (r + 1) * (cols + 2) + c + 1;
      input[at] = patch.grey[r * cols + c];
      input[(rows + 2) * (cols + 2) + at] =
          static_cast<float>(paint_level(patch.paint[r * cols + c])) * (1.0f / 255.0f);
    }
  convolve<rows, cols>(input.data(), kCnnInputChannels, n.conv1_w, n.conv1_b, kCnnChannels1,
                       scratch.conv1.data());
  pool<rows, cols>(scratch.conv1.data(), kCnnChannels1, scratch.pooled1.data());
  convolve<rows / 2, cols / 2>(scratch.pooled1.data(), kCnnChannels1, n.conv2_w, n.conv2_b, kCnnChannels2,
                               scratch.conv2.data());
  pool<rows / 2, cols / 2>(scratch.conv2.data(), kCnnChannels2, scratch.pooled2.data());
  auto& head = scratch.head;
  convolve<rows / 4, cols / 4>(scratch.pooled2.data(), kCnnChannels2, n.conv3_w, n.conv3_b, kCnnChannels3,
                               head.data());
  for (int i = 0; i < kShapeFeatures; ++i)
    head[kCnnFlat + i] =
        (features[kFeatureCount - kShapeFeatures + i] - n.shape_mean[i]) * n.shape_inv_std[i];
  dense_relu(n.fc1_w, n.fc1_b, head.data(), kCnnHeadInputs, kCnnHidden, scratch.hidden.data());
  dense_softmax(n.fc2_w, n.fc2_b, scratch.hidden.data(), kCnnHidden, out);
}

}  // namespace

bool cnn_is_usable(const CnnNet& n) {
  for (const float* p : {n.conv1_w, n.conv1_b, n.conv2_w, n.conv2_b, n.conv3_w, n.conv3_b, n.shape_mean,
                         n.shape_inv_std, n.fc1_w, n.fc1_b, n.fc2_w, n.fc2_b})
    if (p == nullptr) return false;
  return true;
}

bool cnn_is_usable(const CnnModel& cnn) {
  if (cnn.members < 1 || cnn.members > kMaxCnnMembers) return false;
  for (int i = 0; i < cnn.members; ++i)
    if (!cnn_is_usable(cnn.nets[i])) return false;
  return true;
}

bool networks_needed(const std::array<float, kClassifierOutputs>& mlp, float cnn_share,
                     float skip_networks_at) {
  return cnn_share > 0.0f && mlp[kRejectClass] < skip_networks_at;
}

int blend_with_networks(std::array<float, kClassifierOutputs>& probabilities,
                        std::span<const std::array<float, kClassifierOutputs>> networks, float cnn_share) {
  const float member_share = cnn_share / static_cast<float>(networks.size());
  for (int k = 0; k < kClassifierOutputs; ++k) {
    float log_probability = (1.0f - cnn_share) * blend_log(probabilities[k]);
    for (const auto& from_network : networks) log_probability += member_share * blend_log(from_network[k]);
    probabilities[k] = log_probability;
  }
  return softmax_in_place(probabilities);
}

int classify(const MlpModel& model, const CnnModel* cnn, float cnn_share, float skip_networks_at,
             const Features& features, const PatchScratch& patch, CnnScratch& scratch,
             std::array<float, kClassifierOutputs>& probabilities) {
  const int mlp_class = classify(model, features, probabilities);
  if (cnn == nullptr || !networks_needed(probabilities, cnn_share, skip_networks_at)) return mlp_class;
  std::array<std::array<float, kClassifierOutputs>, kMaxCnnMembers> from_networks;
  for (int m = 0; m < cnn->members; ++m)
    cnn_probabilities(cnn->nets[m], features, patch, scratch, from_networks[static_cast<std::size_t>(m)]);
  return blend_with_networks(
      probabilities, std::span(from_networks).first(static_cast<std::size_t>(cnn->members)), cnn_share);
}

float blend_log(float probability) {
  return std::log(std::max(probability, kBlendProbabilityFloor));
}

int softmax_in_place(std::array<float, kClassifierOutputs>& logs) {
  int best_class = 0;
  for (int k = 1; k < kClassifierOutputs; ++k)
    if (logs[k] > logs[best_class]) best_class = k;
  const float best = logs[best_class];
  float total = 0.0f;
  for (float& l : logs) {
    l = std::exp(l - best);
    total += l;
  }
  for (float& l : logs) l /= total;
  return best_class;
}

bool model_is_usable(const MlpModel& m) {
  if (m.members < 1 || m.members > kMaxMembers) return false;
  for (int i = 0; i < m.members; ++i)
    if (!net_is_usable(m.nets[i])) return false;
  return true;
}

int classify(const MlpModel& m, const Features& features,
             std::array<float, kClassifierOutputs>& probabilities) {
  probabilities.fill(0.0f);
  for (int i = 0; i < m.members; ++i) add_probabilities(m.nets[i], features, probabilities);
  const float scale = 1.0f / static_cast<float>(m.members);
  int best_class = 0;
  for (int k = 0; k < kClassifierOutputs; ++k) {
    probabilities[k] *= scale;
    if (probabilities[k] > probabilities[best_class]) best_class = k;
  }
  return best_class;
}

}  // namespace markloop::perception
