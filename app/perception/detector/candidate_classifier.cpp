#include "app/perception/detector/candidate_classifier.hpp"

#include <array>

namespace markloop::perception {

CandidateClassifier::CandidateClassifier(const ClassifierConfig& config)
    : config_(config),
      model_(config.model != nullptr ? config.model : &builtin_marking_model()),
      cnn_(config.cnn != nullptr ? config.cnn : &builtin_marking_cnn()) {}

bool CandidateClassifier::usable() const {
  return model_is_usable(*model_) && cnn_is_usable(*cnn_);
}

void CandidateClassifier::classify(const cv::Mat& bev, const cv::Mat& mask, Candidate& candidate) {
  const PatchBox box{candidate.col0,     candidate.row0,    candidate.col1, candidate.row1,
                     candidate.length_m, candidate.width_m, candidate.parts};
  compute_features(bev, mask, box, scratch_, candidate.features);
  std::array<float, kClassifierOutputs> probabilities;
  candidate.predicted = perception::classify(*model_, cnn_, config_.cnn_share, config_.skip_networks_at,
                                             candidate.features, scratch_, cnn_scratch_, probabilities);
  candidate.score = probabilities[candidate.predicted];
}

}  // namespace markloop::perception
