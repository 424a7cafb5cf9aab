// The marking classifier: a few one-hidden-layer perceptrons (ReLU,
// softmax) on standardised candidate features, with one output per marking
// class plus an explicit reject class ("not a marking": lane-line pieces,
// cracks, shadows, vehicles, glare). The members are trained alike from
// different random starts and their probabilities averaged: on a clip unlike
// any trained on, they err in different places. The weights are in
// model/marking_mlp.bin (written by markloop-train), compiled in at build
// time (model/README.md).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>

#include "app/perception/marking_classes.hpp"
#include "app/perception/marking_features.hpp"

namespace markloop::perception {

inline constexpr int kRejectClass = static_cast<int>(kMarkingClassCount);
inline constexpr int kClassifierOutputs = kRejectClass + 1;
inline constexpr int kMaxHidden = 256;

inline constexpr int kMaxMembers = 4;

// One network.
struct MlpNet {
  int inputs = 0;                          // == kFeatureCount
  int hidden = 0;                          // <= kMaxHidden
  int outputs = 0;                         // == kClassifierOutputs
  const float* feature_mean = nullptr;     // [inputs]
  const float* feature_inv_std = nullptr;  // [inputs]
  const float* w1 = nullptr;               // [hidden][inputs]
  const float* b1 = nullptr;               // [hidden]
  const float* w2 = nullptr;               // [outputs][hidden]
  const float* b2 = nullptr;               // [outputs]
};

struct MlpModel {
  int members = 0;  // 1..kMaxMembers
  std::array<MlpNet, kMaxMembers> nets{};
};

// The model compiled into the program.
const MlpModel& builtin_marking_model();

// True when every member fits the feature layout and the fixed buffers.
bool model_is_usable(const MlpModel& model);

// Class probabilities (the members' mean); returns the most probable class.
int classify(const MlpModel& model, const Features& features,
             std::array<float, kClassifierOutputs>& probabilities);

// A small convolutional network on the candidate's patch itself (the grey
// levels and paint of PatchScratch, two channels of kPatchRows x kPatchCols)
// and its size and shape (the last kShapeFeatures features). It learns its
// own filters where the MLPs see fixed HOG cells: on a clip held out it finds
// markings the MLPs miss (docs/decisions.md). Layout as PyTorch
// stores it: three 3x3 convolutions (padding 1, ReLU; 2x2 max pooling after
// the first two), flattened channel by row by column, the standardised
// shape features appended, then a hidden layer (ReLU) and the outputs.
inline constexpr int kCnnInputChannels = 2;
inline constexpr int kCnnChannels1 = 8;
inline constexpr int kCnnChannels2 = 16;
inline constexpr int kCnnChannels3 = 32;
inline constexpr int kCnnFlat = kCnnChannels3 * (kPatchRows / 4) * (kPatchCols / 4);
inline constexpr int kCnnHeadInputs = kCnnFlat + kShapeFeatures;
inline constexpr int kCnnHidden = 64;

// The paint fraction as the network sees it, in steps of 1/255: the level
// markloop-train --dump writes as a byte for train_cnn.py and the detector
// feeds the network alike.
inline std::uint8_t paint_level(float paint) {
  return static_cast<std::uint8_t>(std::lround(std::clamp(paint, 0.0f, 1.0f) * 255.0f));
}

struct CnnNet {
  const float* conv1_w = nullptr;  // [kCnnChannels1][kCnnInputChannels][3][3]
  const float* conv1_b = nullptr;
  const float* conv2_w = nullptr;  // [kCnnChannels2][kCnnChannels1][3][3]
  const float* conv2_b = nullptr;
  const float* conv3_w = nullptr;  // [kCnnChannels3][kCnnChannels2][3][3]
  const float* conv3_b = nullptr;
  const float* shape_mean = nullptr;     // [kShapeFeatures]
  const float* shape_inv_std = nullptr;  // [kShapeFeatures]
  const float* fc1_w = nullptr;          // [kCnnHidden][kCnnHeadInputs]
  const float* fc1_b = nullptr;
  const float* fc2_w = nullptr;  // [kClassifierOutputs][kCnnHidden]
  const float* fc2_b = nullptr;
};

// The network's layers, held by the caller (sized at init, not on the stack
// of the real-time loop: about 44 KB).
struct CnnScratch {
  std::array<float, kCnnInputChannels*(kPatchRows + 2) * (kPatchCols + 2)> input{};
  std::array<float, kCnnChannels1 * kPatchRows * kPatchCols> conv1{};
  std::array<float, kCnnChannels1*(kPatchRows / 2 + 2) * (kPatchCols / 2 + 2)> pooled1{};
  std::array<float, kCnnChannels2*(kPatchRows / 2) * (kPatchCols / 2)> conv2{};
  std::array<float, kCnnChannels2*(kPatchRows / 4 + 2) * (kPatchCols / 4 + 2)> pooled2{};
  std::array<float, kCnnHeadInputs> head{};
  std::array<float, kCnnHidden> hidden{};
};

// Networks of one layout trained from different random starts: one seed
// moves a network's recall on a clip held out by about 2 points, and
// together they are steadier than either (docs/decisions.md).
inline constexpr int kMaxCnnMembers = 2;

struct CnnModel {
  int members = 0;  // 1..kMaxCnnMembers
  std::array<CnnNet, kMaxCnnMembers> nets{};
};

// The networks compiled into the program (model/marking_cnn.bin).
const CnnModel& builtin_marking_cnn();

bool cnn_is_usable(const CnnNet& cnn);
bool cnn_is_usable(const CnnModel& cnn);

// The MLPs' probabilities blended with the networks' by their weighted
// geometric mean, normalised: mlp^(1 - cnn_share) * (cnn_1 ... cnn_M)^(cnn_share / M)
// (cnn == nullptr or cnn_share 0: the MLPs alone). A class either model finds
// unlikely stays unlikely, where an average would keep half of the other's
// confidence (cross-validation: docs/decisions.md). Where the
// MLPs call the candidate a reject at `skip_networks_at` or more, their
// probabilities are returned as they are and the networks do not run: most
// candidates are such rejects, and against that a marking class would need
// the networks' near-certainty (on the simulator's test sets none of those
// candidates changed class at 0.8). Returns the most probable class. No
// allocation.
int classify(const MlpModel& model, const CnnModel* cnn, float cnn_share, float skip_networks_at,
             const Features& features, const PatchScratch& patch, CnnScratch& scratch,
             std::array<float, kClassifierOutputs>& probabilities);

// The two steps of the blend above, for callers that hold the
// probabilities already (markloop-train --scores): whether the networks
// are to run on a candidate the MLPs gave `mlp`, and the blend itself,
// in place, of the MLPs' probabilities with one set per network (at least
// one). blend_with_networks returns the most probable class.
bool networks_needed(const std::array<float, kClassifierOutputs>& mlp, float cnn_share,
                     float skip_networks_at);
int blend_with_networks(std::array<float, kClassifierOutputs>& probabilities,
                        std::span<const std::array<float, kClassifierOutputs>> networks, float cnn_share);

// The log of a probability as the blend takes it: floored at
// kBlendProbabilityFloor, so that one model's zero (a softmax underflowing)
// is a strong vote against, not a veto.
inline constexpr float kBlendProbabilityFloor = 1e-12f;
float blend_log(float probability);

// Softmax in place: log-probabilities (or logits) in, probabilities out.
// Returns the most probable class.
int softmax_in_place(std::array<float, kClassifierOutputs>& logs);

}  // namespace markloop::perception
