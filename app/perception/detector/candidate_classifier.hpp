// Classification, the detector's fourth stage: a candidate's features (HOG
// of the normalised patch, occupancy, size) go to the small MLPs and the
// convolutional networks blended with them (marking_classifier.hpp), with
// an explicit reject class.
#pragma once

#include <array>

#include "app/perception/detector/candidate.hpp"
#include "app/perception/detector/detector_config.hpp"
#include "app/perception/marking_classifier.hpp"
#include "app/perception/marking_features.hpp"

namespace markloop::perception {

class CandidateClassifier {
 public:
  // The models `config` names, or those compiled in.
  explicit CandidateClassifier(const ClassifierConfig& config);

  // False when a model's weights are unusable: nothing can be classified.
  bool usable() const;
  // Sets the candidate's features, predicted class and score from the
  // bird's-eye image `bev` and its paint `mask` (read()).
  void classify(const cv::Mat& bev, const cv::Mat& mask, Candidate& candidate);

  struct Reading {
    int label = kRejectClass;
    float score = 0.0f;
    bool turned = false;  // read turned half way round: seen from behind
  };
  // The class of a candidate whose features are `upright_features` and
  // whose patch `patch` holds (as compute_features left them): read as it
  // lies and, unless that is surely a marking, turned half way round
  // (turn_features; `patch` is left turned). The turned reading wins when it
  // names a marking that turning changes with at least
  // ClassifierConfig::turned_min_score. `probabilities` are the winner's.
  Reading read(const Features& upright_features, PatchScratch& patch,
               std::array<float, kClassifierOutputs>& probabilities);

 private:
  ClassifierConfig config_;
  const MlpModel* model_;
  const CnnModel* cnn_;
  PatchScratch scratch_;
  CnnScratch cnn_scratch_;
  Features turned_features_{};
  std::array<float, kClassifierOutputs> turned_probabilities_{};
};

}  // namespace markloop::perception
