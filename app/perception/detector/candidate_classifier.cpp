#include "app/perception/detector/candidate_classifier.hpp"

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
  const Reading reading = read(candidate.features, scratch_, probabilities);
  candidate.predicted = reading.label;
  candidate.score = reading.score;
  candidate.turned = reading.turned;
}

CandidateClassifier::Reading CandidateClassifier::read(const Features& upright_features, PatchScratch& patch,
                                                       std::array<float, kClassifierOutputs>& probabilities) {
  const auto classify_patch = [&](const Features& features, std::array<float, kClassifierOutputs>& p) {
    return perception::classify(*model_, cnn_, config_.cnn_share, config_.skip_networks_at, features, patch,
                                cnn_scratch_, p);
  };
  Reading upright;
  upright.label = classify_patch(upright_features, probabilities);
  upright.score = probabilities[upright.label];
  const bool sure = upright.label != kRejectClass && upright.score >= config_.turned_min_score;
  if (sure || config_.turned_min_score > 1.0f) return upright;
  turn_features(patch, upright_features, turned_features_);
  const int turned = classify_patch(turned_features_, turned_probabilities_);
  const float turned_score = turned_probabilities_[turned];
  if (turned == kRejectClass || same_when_turned(static_cast<Label>(turned)) ||
      turned_score < config_.turned_min_score)
    return upright;
  probabilities = turned_probabilities_;
  return {turned, turned_score, true};
}

}  // namespace markloop::perception
