#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iterator>
#include <utility>

#include "app/common/result.hpp"
#include "app/ecu/runner.hpp"
#include "platform/files.hpp"
#include "platform/os.hpp"

namespace markloop::ecu::detail {

platform::UniqueFd open_stop_signals() {
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGTERM);
  sigaddset(&signals, SIGINT);
  platform::UniqueFd fd;
  if (auto ec = platform::open_signalfd(signals, fd)) {
    std::fprintf(stderr, "markloop: cannot open signalfd: %s\n", ec.message().c_str());
    std::exit(2);
  }
  return fd;
}

int pending_stop_signal(int signal_fd) {
  int number = 0;
  (void)platform::read_signal(signal_fd, number);
  return number;
}

platform::SystemdNotifier open_systemd_notifier() {
  platform::SystemdNotifier systemd;
  if (auto ec = systemd.open())
    std::fprintf(stderr, "markloop: NOTIFY_SOCKET unusable (%s): no systemd notifications\n",
                 ec.message().c_str());
  return systemd;
}

bool start_up(Ecu& ecu, const EcuConfig& config, bool quiet) {
  const MapLoadResult map = ecu.load_map();
  if (map.outcome == MapLoadOutcome::kUnusable) {
    std::fprintf(stderr, "markloop: map refused: %s; not starting\n", map.message.c_str());
    return false;
  }
  if (map.outcome == MapLoadOutcome::kRejected)
    std::fprintf(stderr, "markloop: map rejected: %s; starting with an empty map\n", map.message.c_str());
  else if (!quiet && !config.map_file.empty())
    std::fprintf(stderr, "markloop: %s\n", map.message.c_str());

  // Everything is allocated now: keep it in RAM, then take the CPU.
  if (config.realtime.lock_memory) {
    if (auto ec = platform::lock_all_memory())
      std::fprintf(stderr, "markloop: mlockall not permitted (%s): running unlocked\n", ec.message().c_str());
  }
  if (config.realtime.cpu >= 0) {
    if (auto ec = platform::pin_to_cpu(config.realtime.cpu))
      std::fprintf(stderr, "markloop: cannot pin to CPU %d (%s)\n", config.realtime.cpu,
                   ec.message().c_str());
  }
  if (config.realtime.priority > 0) {
    if (auto ec = platform::set_fifo_priority(config.realtime.priority))
      std::fprintf(stderr, "markloop: SCHED_FIFO %d not permitted (%s): normal scheduling\n",
                   config.realtime.priority, ec.message().c_str());
  }
  return true;
}

bool shut_down(Ecu& ecu, const EcuConfig& config, bool quiet) {
  if (config.map_file.empty() || !config.save_map_on_exit) return true;
  if (auto ec = ecu.save_map()) {
    std::fprintf(stderr, "markloop: saving the map to %s failed: %s\n", config.map_file.c_str(),
                 ec.message().c_str());
    return false;
  }
  if (!quiet)
    std::fprintf(stderr, "markloop: map saved to %s (%zu landmarks, %zu sequences)\n",
                 config.map_file.c_str(), ecu.engine().database().stats().landmarks,
                 ecu.engine().database().stats().sequences);
  return true;
}

namespace {
double ms(std::int64_t ns) {
  return double(ns) / 1e6;
}

void print_scale_line(const OdometryScaleEstimator& estimator) {
  const ScaleCounters& c = estimator.counters();
  char value[64] = "none yet";
  if (const std::optional<ScaleEstimate> e = estimator.estimate())
    std::snprintf(value, sizeof value, "%.5f +- %.5f", e->scale, e->standard_error);
  std::fprintf(stderr,
               "markloop: odometry scale by the camera %s (%llu markings; %llu seen too briefly, %llu "
               "outliers)\n",
               value, (unsigned long long)c.markings_used, (unsigned long long)c.markings_short,
               (unsigned long long)c.markings_outlier);
}
}  // namespace

namespace {
Status write_summary(const Ecu& ecu, const RunOptions& options, double wall_seconds, const char* mode,
                     std::size_t rss);
}  // namespace

bool report(const Ecu& ecu, const RunOptions& options, double wall_seconds, const char* mode) {
  const EcuCounters& c = ecu.counters();
  const auto& detect = ecu.detect_time();
  const auto& engine = ecu.engine_time();
  const auto& frame = ecu.frame_time();
  const DatabaseStats db = ecu.engine().database().stats();
  const OdometryCounters& odo = ecu.odometry().counters();
  std::size_t rss = 0;
  (void)platform::resident_bytes(rss);
  if (!options.quiet) {
    std::fprintf(stderr,
                 "markloop: %s mode, %.1f s: %llu frames processed (%llu showing no road), %llu "
                 "dropped, %llu above the rate, %llu overruns, %llu detections, %llu loop detections "
                 "sent\n",
                 mode, wall_seconds, (unsigned long long)c.frames_processed,
                 (unsigned long long)c.frames_blind, (unsigned long long)c.frames_dropped,
                 (unsigned long long)c.frames_over_rate, (unsigned long long)c.overruns,
                 (unsigned long long)c.detections, (unsigned long long)c.loop_detections);
    std::fprintf(stderr,
                 "markloop: per frame (ms, 10 us bins) detect median %.2f p99 %.2f | engine median "
                 "%.3f p99 %.3f | total median %.2f p99 %.2f max %.2f\n",
                 ms(detect.quantile_ns(0.5)), ms(detect.quantile_ns(0.99)), ms(engine.quantile_ns(0.5)),
                 ms(engine.quantile_ns(0.99)), ms(frame.quantile_ns(0.5)), ms(frame.quantile_ns(0.99)),
                 ms(frame.max_ns()));
    std::fprintf(stderr,
                 "markloop: odometry %llu accepted, %llu bad CRC, %llu bad counter, %llu wrong length, "
                 "%llu out of range, %llu invalid signals, %llu out of order, %llu timeouts; "
                 "%llu malformed frames on our ids, %llu commands rejected, %llu foreign frames, "
                 "%llu log frames after the last camera frame; "
                 "database %zu landmarks, %zu sequences; RSS %.1f MiB\n",
                 (unsigned long long)odo.accepted, (unsigned long long)odo.bad_crc,
                 (unsigned long long)odo.bad_counter, (unsigned long long)odo.wrong_length,
                 (unsigned long long)odo.out_of_range, (unsigned long long)odo.invalid_signals,
                 (unsigned long long)odo.out_of_order, (unsigned long long)odo.timeouts,
                 (unsigned long long)c.bad_frames, (unsigned long long)c.commands_rejected,
                 (unsigned long long)c.foreign_frames, (unsigned long long)c.can_frames_unused, db.landmarks,
                 db.sequences, double(rss) / (1024.0 * 1024.0));
    const perception::DetectorCounters& d = ecu.detector().counters();
    std::fprintf(stderr,
                 "markloop: detector %llu parts, %llu lane lines, %llu candidates, %llu rejected, "
                 "%llu below score, %llu pieces of larger ones, %llu joined to another's detection (a "
                 "word, a side crosswalk), %llu cut by the view's edge, "
                 "%llu beyond the region, %llu bad frames, %llu flat, %llu noisy and %llu "
                 "cluttered views (%llu detections withheld), %llu parts, %llu candidates and "
                 "%llu letter strokes over the caps; horizon measured in %llu frames (not in "
                 "%llu), moved %llu times, now %d rows\n",
                 (unsigned long long)d.parts, (unsigned long long)d.lane_lines,
                 (unsigned long long)d.candidates, (unsigned long long)d.rejected,
                 (unsigned long long)d.low_score, (unsigned long long)d.pieces, (unsigned long long)d.joined,
                 (unsigned long long)d.clipped, (unsigned long long)d.beyond_region,
                 (unsigned long long)d.bad_frames, (unsigned long long)d.flat_frames,
                 (unsigned long long)d.noisy_frames, (unsigned long long)d.cluttered_frames,
                 (unsigned long long)d.detections_withheld, (unsigned long long)d.parts_dropped,
                 (unsigned long long)d.candidates_dropped, (unsigned long long)d.strokes_dropped,
                 (unsigned long long)d.horizon_measured, (unsigned long long)d.horizon_unmeasured,
                 (unsigned long long)d.horizon_moves, ecu.detector().horizon_shift());
    const EngineCounters& e = ecu.engine().counters();
    const PlaceCounters& p = ecu.engine().place_counters();
    std::fprintf(
        stderr,
        "markloop: engine %llu sequences, %llu candidates, %llu too recent, %llu residual, "
        "%llu drift, %llu frames apart, %llu loaded-map single sequences, "
        "%llu loaded-map hypotheses, %llu loaded-map disagreeing, "
        "%llu matches (%llu with the pose refined over a run, %llu by place); places: %llu queries, "
        "%llu hypotheses, %llu ambiguous, %llu beyond the drift limits, %llu of two across roads, "
        "%llu of two with a marking unseen\n",
        (unsigned long long)e.sequences_created, (unsigned long long)e.candidates,
        (unsigned long long)e.candidates_too_recent, (unsigned long long)e.candidates_rejected_residual,
        (unsigned long long)e.candidates_rejected_drift,
        (unsigned long long)e.candidates_rejected_frames_apart, (unsigned long long)e.loaded_single_sequences,
        (unsigned long long)e.loaded_hypotheses, (unsigned long long)e.loaded_rejected,
        (unsigned long long)e.matches, (unsigned long long)e.closures_extended,
        (unsigned long long)e.place_matches, (unsigned long long)p.queries, (unsigned long long)p.hypotheses,
        (unsigned long long)p.ambiguous, (unsigned long long)p.rejected_drift, (unsigned long long)p.across,
        (unsigned long long)p.unseen);
    print_scale_line(ecu.engine().odometry_scale());
  }
  if (const Status written = write_summary(ecu, options, wall_seconds, mode, rss); !written) {
    std::fprintf(stderr, "markloop: %s\n", written.message().c_str());
    return false;
  }
  return true;
}

namespace {

// The run's figures: every field of the summary but the engine's.
void print_run_figures(std::FILE* out, const Ecu& ecu, double wall_seconds, const char* mode,
                       std::size_t rss) {
  const EcuCounters& c = ecu.counters();
  const auto& detect = ecu.detect_time();
  const auto& engine = ecu.engine_time();
  const auto& frame = ecu.frame_time();
  const auto& latency = ecu.detection_latency();
  const DatabaseStats db = ecu.engine().database().stats();
  const OdometryCounters& odo = ecu.odometry().counters();
  std::fprintf(
      out,
      "{\"mode\": \"%s\", \"wall_s\": %.3f, \"frames_processed\": %llu, \"frames_dropped\": %llu,"
      " \"overruns\": %llu, \"detections\": %llu, \"loop_detections\": %llu,"
      " \"frames_without_pose\": %llu, \"frames_blind\": %llu, \"pose_losses\": %llu,"
      " \"foreign_frames\": %llu, \"bad_frames\": %llu, \"commands_rejected\": %llu,"
      " \"can_frames_unused\": %llu, \"odometry_wrong_length\": %llu,"
      " \"odometry_out_of_range\": %llu, \"odometry_invalid_signals\": %llu,"
      " \"odometry_out_of_order\": %llu,"
      " \"send_errors\": %llu, \"odometry_accepted\": %llu, \"odometry_bad_crc\": %llu,"
      " \"odometry_bad_counter\": %llu, \"odometry_timeouts\": %llu,"
      " \"detect_ms\": {\"median\": %.3f, \"p99\": %.3f, \"max\": %.3f},"
      " \"engine_ms\": {\"median\": %.4f, \"p99\": %.4f, \"max\": %.4f},"
      " \"frame_ms\": {\"median\": %.3f, \"p99\": %.3f, \"max\": %.3f},"
      " \"latency_ms\": {\"count\": %llu, \"median\": %.3f, \"p99\": %.3f, \"max\": %.3f},"
      " \"landmarks\": %zu, \"sequences\": %zu, \"rss_bytes\": %zu,",
      mode, wall_seconds, (unsigned long long)c.frames_processed, (unsigned long long)c.frames_dropped,
      (unsigned long long)c.overruns, (unsigned long long)c.detections, (unsigned long long)c.loop_detections,
      (unsigned long long)c.frames_without_pose, (unsigned long long)c.frames_blind,
      (unsigned long long)c.pose_losses, (unsigned long long)c.foreign_frames,
      (unsigned long long)c.bad_frames, (unsigned long long)c.commands_rejected,
      (unsigned long long)c.can_frames_unused, (unsigned long long)odo.wrong_length,
      (unsigned long long)odo.out_of_range, (unsigned long long)odo.invalid_signals,
      (unsigned long long)odo.out_of_order, (unsigned long long)c.send_errors,
      (unsigned long long)odo.accepted, (unsigned long long)odo.bad_crc, (unsigned long long)odo.bad_counter,
      (unsigned long long)odo.timeouts, ms(detect.quantile_ns(0.5)), ms(detect.quantile_ns(0.99)),
      ms(detect.max_ns()), ms(engine.quantile_ns(0.5)), ms(engine.quantile_ns(0.99)), ms(engine.max_ns()),
      ms(frame.quantile_ns(0.5)), ms(frame.quantile_ns(0.99)), ms(frame.max_ns()),
      (unsigned long long)latency.count(), ms(latency.quantile_ns(0.5)), ms(latency.quantile_ns(0.99)),
      ms(latency.max_ns()), db.landmarks, db.sequences, rss);
}

// The camera's measure of the odometry's scale, and the markings it rests on.
void print_odometry_scale(std::FILE* out, const OdometryScaleEstimator& estimator) {
  const ScaleCounters& c = estimator.counters();
  std::fprintf(out, " \"odometry_scale\": {");
  if (const std::optional<ScaleEstimate> e = estimator.estimate())
    std::fprintf(out, "\"scale\": %.5f, \"standard_error\": %.5f, ", e->scale, e->standard_error);
  std::fprintf(out, "\"markings_used\": %llu, \"markings_short\": %llu, \"markings_outlier\": %llu},",
               (unsigned long long)c.markings_used, (unsigned long long)c.markings_short,
               (unsigned long long)c.markings_outlier);
}

// Where the engine's candidates went, and its rarer events; closes the summary.
void print_engine_counters(std::FILE* out, const EngineCounters& e, const PlaceCounters& p) {
  const std::pair<const char*, std::uint64_t> engine_counters[] = {
      {"landmarks_released", e.landmarks_released},
      {"passing_frames_forgotten", e.passing_frames_forgotten},
      {"landmarks_flushed_ahead", e.landmarks_flushed_ahead},
      {"chain_breaks", e.chain_breaks},
      {"sequences_created", e.sequences_created},
      {"sequences_over_skipped_row", e.sequences_over_skipped_row},
      {"queries", e.queries},
      {"candidates", e.candidates},
      {"candidates_too_recent", e.candidates_too_recent},
      {"candidates_rejected_residual", e.candidates_rejected_residual},
      {"candidates_rejected_drift", e.candidates_rejected_drift},
      {"candidates_rejected_frames_apart", e.candidates_rejected_frames_apart},
      {"loaded_single_sequences", e.loaded_single_sequences},
      {"loaded_hypotheses", e.loaded_hypotheses},
      {"loaded_hypotheses_sent", e.loaded_hypotheses_sent},
      {"loaded_rivalled", e.loaded_rivalled},
      {"loaded_rejected", e.loaded_rejected},
      {"candidate_limit_hits", e.candidate_limit_hits},
      {"matches", e.matches},
      {"closures_extended", e.closures_extended},
      {"matches_over_skipped_row", e.matches_over_skipped_row},
      {"matches_held_far", e.matches_held_far},
      {"place_matches", e.place_matches},
      {"place_queries", p.queries},
      {"place_hypotheses", p.hypotheses},
      {"place_ambiguous", p.ambiguous},
      {"place_rejected_drift", p.rejected_drift},
      {"place_across", p.across},
      {"place_unseen", p.unseen},
  };
  std::fprintf(out, " \"engine\": {");
  for (std::size_t i = 0; i < std::size(engine_counters); ++i)
    std::fprintf(out, "%s\"%s\": %llu", i > 0 ? ", " : "", engine_counters[i].first,
                 (unsigned long long)engine_counters[i].second);
  std::fprintf(out, "}}\n");
}

// The --summary-json file, when asked for; else "PATH: why".
Status write_summary(const Ecu& ecu, const RunOptions& options, double wall_seconds, const char* mode,
                     std::size_t rss) {
  if (options.summary_json.empty()) return {};
  char* text = nullptr;
  std::size_t length = 0;
  std::FILE* out = ::open_memstream(&text, &length);
  if (out == nullptr) return error(options.summary_json + ": out of memory");
  print_run_figures(out, ecu, wall_seconds, mode, rss);
  print_odometry_scale(out, ecu.engine().odometry_scale());
  print_engine_counters(out, ecu.engine().counters(), ecu.engine().place_counters());
  const bool formatted = std::fclose(out) == 0;
  const std::error_code ec =
      formatted ? platform::write_file_replacing(options.summary_json.c_str(), std::string_view(text, length))
                : std::make_error_code(std::errc::not_enough_memory);
  std::free(text);
  if (ec) return error(options.summary_json + ": cannot write the summary: " + ec.message());
  return {};
}

}  // namespace

}  // namespace markloop::ecu::detail
