// Reassembles one LoopDetection from its pages (receive side: SLAM backend,
// HIL tests). markloop sends pages kPages[0..5] back to back with the same
// MatchId; decode() with E2E state already rejects lost or repeated frames,
// so a detection is complete when every page arrived in order with one id.
#pragma once

#include <cstddef>

#include "dbc/markloop_messages.hpp"

namespace markloop::dbc {

class LoopDetectionAssembler {
 public:
  // Feed every LoopDetection frame that decoded without error, and report
  // every rejected one with drop(). Returns true when `frame` completed a
  // detection, which detection() then holds until the next add().
  bool add(const LoopDetection& frame) noexcept {
    const bool starts = frame.loop_page == LoopDetection::kPages[0];
    if (starts) {
      collecting_ = frame;
      next_page_ = 1;
      return false;
    }
    const bool continues = next_page_ > 0 && next_page_ < LoopDetection::kPages.size() &&
                           frame.loop_page == LoopDetection::kPages[next_page_] &&
                           frame.match_id == collecting_.match_id;
    if (!continues) {
      next_page_ = 0;  // out of order or mixed detections: wait for a new start
      return false;
    }
    collecting_ = merged(collecting_, frame);
    if (++next_page_ < LoopDetection::kPages.size()) return false;
    next_page_ = 0;
    complete_ = collecting_;
    return true;
  }

  // A frame of this id was rejected (CRC, counter, ...): the detection being
  // collected cannot be trusted any more.
  void drop() noexcept { next_page_ = 0; }

  const LoopDetection& detection() const noexcept { return complete_; }

 private:
  // Takes the fields of `page` that its page carries.
  static LoopDetection merged(LoopDetection into, const LoopDetection& page) noexcept {
    into.loop_page = page.loop_page;
    switch (page.loop_page) {
      case LoopPage::Query:
        into.query_frame = page.query_frame;
        into.sequence_length = page.sequence_length;
        break;
      case LoopPage::Match:
        into.match_frame = page.match_frame;
        into.match_score = page.match_score;
        break;
      case LoopPage::QueryTime:
        into.query_time_s = page.query_time_s;
        break;
      case LoopPage::MatchTime:
        into.match_time_s = page.match_time_s;
        break;
      case LoopPage::Translation:
        into.pose_dx_m = page.pose_dx_m;
        into.pose_dy_m = page.pose_dy_m;
        into.pose_valid = page.pose_valid;
        break;
      case LoopPage::RotationResidual:
        into.pose_dyaw_deg = page.pose_dyaw_deg;
        into.pose_residual_m = page.pose_residual_m;
        break;
    }
    return into;
  }

  LoopDetection collecting_{};
  LoopDetection complete_{};
  std::size_t next_page_ = 0;  // index into kPages of the page expected next; 0: idle
};

}  // namespace markloop::dbc
