// Where the bird's-eye view borders what the camera does not see, so that
// a marking touching it is known to be seen only in part, and the count of
// seen pixels the paint mask's windows average over. Both change only when
// the view moves (the horizon measured): update() then.
#pragma once

#include <cstdint>
#include <vector>

#include <opencv2/core/mat.hpp>

#include "app/perception/birdseye.hpp"

namespace markloop::perception {

// Edges of the view (at_edge() bits). Near: the unseen lies below, on the
// bonnet or under the image (or the region's near end): markings leave the
// view there as the car drives on, seen whole before. Other: the far end,
// the region's sides and the image's sides.
inline constexpr std::uint8_t kNearEdge = 1;
inline constexpr std::uint8_t kOtherEdge = 2;

class ViewEdges {
 public:
  // Sized for `view` (its rows and columns stay as they are).
  explicit ViewEdges(const BirdsEyeView& view);

  void update(const BirdsEyeView& view);

  // CV_32SC1 (rows+1) x (cols+1): integral of the view's valid pixels.
  const cv::Mat& valid_integral() const { return valid_integral_; }
  // CV_8UC1: kNearEdge / kOtherEdge where a pixel borders what is not seen.
  const cv::Mat& at_edge() const { return at_edge_; }

  // kNearEdge | kOtherEdge bits of the edge pixels the paint of `mask` in a
  // box (a Candidate's or a Part's) touches.
  template <typename Box>
  std::uint8_t touched(const cv::Mat& mask, const Box& box) const {
    return touched(mask, box.col0, box.row0, box.col1, box.row1);
  }

 private:
  std::uint8_t touched(const cv::Mat& mask, int col0, int row0, int col1, int row1) const;
  void integrate_valid(const cv::Mat& valid);
  void mark_unseen_across(const BirdsEyeView& view);
  void mark_edges();

  cv::Mat valid_integral_;
  cv::Mat at_edge_;
  // One row's kind of unseen per pixel (kNearEdge: below, kOtherEdge:
  // elsewhere, 0: seen), and per pixel (CV_8UC1) those of it and its left
  // and right neighbours ORed.
  std::vector<std::uint8_t> unseen_kind_row_;
  cv::Mat unseen_kind_across_;
};

}  // namespace markloop::perception
