#include "app/perception/detector/view_edges.hpp"

#include <algorithm>

namespace markloop::perception {

ViewEdges::ViewEdges(const BirdsEyeView& view) {
  const int rows = view.rows(), cols = view.cols();
  valid_integral_.create(rows + 1, cols + 1, CV_32SC1);
  valid_integral_.setTo(0);
  at_edge_.create(rows, cols, CV_8UC1);
  unseen_kind_row_.assign(static_cast<std::size_t>(cols), 0);
  unseen_kind_across_.create(rows, cols, CV_8UC1);
  update(view);
}

void ViewEdges::update(const BirdsEyeView& view) {
  integrate_valid(view.valid());
  // Pixels on the view's border or next to (or on) one the camera does not
  // see: paint there may go on beyond what is seen. Near only where every
  // unseen neighbour is level or below and unseen_below(). Run on every
  // move of the view (the horizon measured), so in passes over rows: each
  // pixel's kind of unseen, ORed across with its neighbours', then down.
  mark_unseen_across(view);
  mark_edges();
}

void ViewEdges::integrate_valid(const cv::Mat& valid) {
  const int rows = valid.rows, cols = valid.cols;
  for (int r = 0; r < rows; ++r) {
    const std::uint8_t* v = valid.ptr<std::uint8_t>(r);
    const std::int32_t* above = valid_integral_.ptr<std::int32_t>(r);
    std::int32_t* out = valid_integral_.ptr<std::int32_t>(r + 1);
    std::int32_t line = 0;
    for (int c = 0; c < cols; ++c) {
      line += v[c] != 0 ? 1 : 0;
      out[c + 1] = above[c + 1] + line;
    }
  }
}

void ViewEdges::mark_unseen_across(const BirdsEyeView& view) {
  const int rows = view.rows(), cols = view.cols();
  const cv::Mat& valid = view.valid();
  for (int r = 0; r < rows; ++r) {
    const std::uint8_t* v = valid.ptr<std::uint8_t>(r);
    std::uint8_t* kind = unseen_kind_row_.data();
    for (int c = 0; c < cols; ++c) kind[c] = v[c] != 0 ? 0 : view.unseen_below(r, c) ? kNearEdge : kOtherEdge;
    std::uint8_t* across = unseen_kind_across_.ptr<std::uint8_t>(r);
    across[0] = static_cast<std::uint8_t>(kind[0] | kind[std::min(cols - 1, 1)]);
    for (int c = 1; c < cols - 1; ++c)
      across[c] = static_cast<std::uint8_t>(kind[c - 1] | kind[c] | kind[c + 1]);
    across[cols - 1] = static_cast<std::uint8_t>(kind[std::max(0, cols - 2)] | kind[cols - 1]);
  }
}

void ViewEdges::mark_edges() {
  const int rows = at_edge_.rows, cols = at_edge_.cols;
  for (int r = 0; r < rows; ++r) {
    // The first and last rows stand in for the missing neighbour row: the
    // first is all border anyway, and ORing the last with itself adds nothing.
    const std::uint8_t* level = unseen_kind_across_.ptr<std::uint8_t>(r);
    const std::uint8_t* above = unseen_kind_across_.ptr<std::uint8_t>(std::max(0, r - 1));
    const std::uint8_t* below = unseen_kind_across_.ptr<std::uint8_t>(std::min(rows - 1, r + 1));
    const bool border_row = r == 0;
    const std::uint8_t near_row = r == rows - 1 ? kNearEdge : 0;
    std::uint8_t* out = at_edge_.ptr<std::uint8_t>(r);
    for (int c = 0; c < cols; ++c) {
      // An unseen pixel in the row above is never below this one.
      const std::uint8_t level_or_below = level[c] | below[c];
      const bool other = border_row || above[c] != 0 || (level_or_below & kOtherEdge) != 0;
      const bool near = ((level_or_below | near_row) & kNearEdge) != 0;
      out[c] = other ? kOtherEdge : near ? kNearEdge : 0;
    }
    out[0] = kOtherEdge;
    out[cols - 1] = kOtherEdge;
  }
}

std::uint8_t ViewEdges::touched(const cv::Mat& mask, int col0, int row0, int col1, int row1) const {
  // Paint of the box next to the edge of the view: the marking may go on
  // beyond it. The box alone would say so for every marking whose box
  // corner reaches into the unseen corners of the view.
  std::uint8_t edges = 0;
  for (int row = row0; row <= row1; ++row) {
    const std::uint8_t* paint = mask.ptr<std::uint8_t>(row);
    const std::uint8_t* edge = at_edge_.ptr<std::uint8_t>(row);
    for (int col = col0; col <= col1; ++col) edges |= paint[col] & edge[col];
    if (edges == (kNearEdge | kOtherEdge)) break;
  }
  return edges;
}

}  // namespace markloop::perception
