#include "perception/marking_classifier.hpp"

#include <algorithm>
#include <cmath>

namespace markloop::perception {

namespace {

bool net_is_usable(const MlpNet& m) {
  return m.inputs == kFeatureCount && m.outputs == kClassifierOutputs && m.hidden > 0 &&
         m.hidden <= kMaxHidden && m.feature_mean != nullptr && m.feature_inv_std != nullptr &&
         m.w1 != nullptr && m.b1 != nullptr && m.w2 != nullptr && m.b2 != nullptr;
}

// Adds one network's class probabilities to `sum`.
void add_probabilities(const MlpNet& m, const Features& features,
                       std::array<float, kClassifierOutputs>& sum) {
  std::array<float, kFeatureCount> x;
  for (int i = 0; i < kFeatureCount; ++i)
    x[i] = (features[i] - m.feature_mean[i]) * m.feature_inv_std[i];
  std::array<float, kMaxHidden> h;
  for (int j = 0; j < m.hidden; ++j) {
    const float* w = m.w1 + static_cast<std::size_t>(j) * kFeatureCount;
    // Eight independent partial sums: the compiler can keep them in one
    // vector register (a single running sum would serialise every add).
    std::array<float, 8> partial{};
    int i = 0;
    for (; i + 8 <= kFeatureCount; i += 8)
      for (int k = 0; k < 8; ++k) partial[k] += w[i + k] * x[i + k];
    float s = m.b1[j];
    for (; i < kFeatureCount; ++i) s += w[i] * x[i];
    for (float p : partial) s += p;
    h[j] = std::max(s, 0.0f);
  }
  std::array<float, kClassifierOutputs> logits;
  float best = -1e30f;
  for (int k = 0; k < kClassifierOutputs; ++k) {
    const float* w = m.w2 + static_cast<std::size_t>(k) * m.hidden;
    float s = m.b2[k];
    for (int j = 0; j < m.hidden; ++j) s += w[j] * h[j];
    logits[k] = s;
    best = std::max(best, s);
  }
  float total = 0.0f;
  for (float& l : logits) {
    l = std::exp(l - best);
    total += l;
  }
  for (int k = 0; k < kClassifierOutputs; ++k) sum[k] += logits[k] / total;
}

}  // namespace

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
