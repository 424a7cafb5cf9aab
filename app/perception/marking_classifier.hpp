// The marking classifier: a few one-hidden-layer perceptrons (ReLU,
// softmax) on standardised candidate features, with one output per marking
// class plus an explicit reject class ("not a marking": lane-line pieces,
// cracks, shadows, vehicles, glare). The members are trained alike from
// different random starts and their probabilities averaged: on a clip unlike
// any trained on, they err in different places. Weights live in a generated
// source file (model/marking_model.cpp, written by markloop-train).
#pragma once

#include <array>
#include <cstddef>

#include "perception/marking_classes.hpp"
#include "perception/marking_features.hpp"

namespace markloop::perception {

inline constexpr int kRejectClass = static_cast<int>(kMarkingClassCount);
inline constexpr int kClassifierOutputs = kRejectClass + 1;
inline constexpr int kMaxHidden = 256;

inline constexpr int kMaxMembers = 4;

// One network.
struct MlpNet {
  int inputs = 0;   // == kFeatureCount
  int hidden = 0;   // <= kMaxHidden
  int outputs = 0;  // == kClassifierOutputs
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

}  // namespace markloop::perception
