#include "perception/marking_classifier.hpp"

#include <algorithm>
#include <cmath>

namespace markloop::perception {

bool model_is_usable(const MlpModel& m) {
  return m.inputs == kFeatureCount && m.outputs == kClassifierOutputs && m.hidden > 0 &&
         m.hidden <= kMaxHidden && m.feature_mean != nullptr && m.feature_inv_std != nullptr &&
         m.w1 != nullptr && m.b1 != nullptr && m.w2 != nullptr && m.b2 != nullptr;
}

int classify(const MlpModel& m, const Features& features,
             std::array<float, kClassifierOutputs>& probabilities) {
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
  float best = -1e30f;
  int best_class = 0;
  for (int k = 0; k < kClassifierOutputs; ++k) {
    const float* w = m.w2 + static_cast<std::size_t>(k) * m.hidden;
    float s = m.b2[k];
    for (int j = 0; j < m.hidden; ++j) s += w[j] * h[j];
    probabilities[k] = s;
    if (s > best) {
      best = s;
      best_class = k;
    }
  }
  float total = 0.0f;
  for (float& p : probabilities) {
    p = std::exp(p - best);
    total += p;
  }
  for (float& p : probabilities) p /= total;
  return best_class;
}

}  // namespace markloop::perception
