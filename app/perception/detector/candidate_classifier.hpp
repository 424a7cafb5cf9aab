// Classification, the detector's fourth stage: a candidate's features (HOG
// of the normalised patch, occupancy, size) go to the small MLPs and the
// convolutional networks blended with them (marking_classifier.hpp), with
// an explicit reject class.
#pragma once

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
  // bird's-eye image `bev` and its paint `mask`.
  void classify(const cv::Mat& bev, const cv::Mat& mask, Candidate& candidate);

 private:
  ClassifierConfig config_;
  const MlpModel* model_;
  const CnnModel* cnn_;
  PatchScratch scratch_;
  CnnScratch cnn_scratch_;
};

}  // namespace markloop::perception
