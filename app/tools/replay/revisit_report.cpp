#include "app/tools/replay/revisit_report.hpp"

#include <optional>
#include <string>

namespace markloop::replay {

namespace {

constexpr RevisitKind kKinds[] = {RevisitKind::SameDirection, RevisitKind::OppositeDirection,
                                  RevisitKind::Crossing};

const char* kind_label(RevisitKind kind) {
  switch (kind) {
    case RevisitKind::SameDirection:
      return "same direction";
    case RevisitKind::OppositeDirection:
      return "opposite direction";
    case RevisitKind::Crossing:
      return "crossing/turn-in";
  }
  return "?";
}

// "3 / 4 (75.0 %)"
std::string count_text(const RevisitCount& c) {
  return std::to_string(c.closed) + " / " + std::to_string(c.total) + " (" + percent_of(c.closed, c.total) +
         ")";
}

void print_row(std::FILE* out, const char* name, const RevisitCount& shorter, const RevisitCount& longer) {
  std::fprintf(out, "  %-22s %-22s %s\n", name, count_text(shorter).c_str(), count_text(longer).c_str());
}

void print_closure(std::FILE* out, const char* name, const ClosureDistances& d) {
  if (d.count == 0) {
    std::fprintf(out, "  %-40s - (none closed)\n", name);
    return;
  }
  std::fprintf(out, "  %-40s %.1f / %.1f m (%zu closed)\n", name, d.median_m, d.p90_m, d.count);
}

void print_shared(std::FILE* out, const char* name, const ClosureDistances& d, std::size_t events) {
  if (d.count == 0) {
    std::fprintf(out, "    %-38s - (no event has one)\n", name);
    return;
  }
  std::fprintf(out, "    %-38s %.1f / %.1f m (%zu of %zu events)\n", name, d.median_m, d.p90_m, d.count,
               events);
}

void print_shared_tally(std::FILE* out, const char* heading, const SharedTally& t) {
  if (t.known == 0) return;
  std::fprintf(out, "  %s (events of 50 m or more: %zu):\n", heading, t.known);
  print_shared(out, "second, median / p90", t.second, t.known);
  print_shared(out, "third, median / p90", t.third, t.known);
}

// "; third marking in view on both visits passed at 24.0 m"
void print_event_shared(std::FILE* out, const char* what, const std::optional<SharedMarkings>& shared) {
  if (!shared) return;
  if (shared->third_m)
    std::fprintf(out, "; third marking %s passed at %.1f m", what, *shared->third_m);
  else
    std::fprintf(out, "; %zu marking%s %s", shared->count, shared->count == 1 ? "" : "s", what);
}

void json_optional(std::FILE* out, const char* name, const std::optional<double>& v) {
  if (v)
    std::fprintf(out, ",\"%s\":%.3f", name, *v);
  else
    std::fprintf(out, ",\"%s\":null", name);
}

// ,"shared_markings":3,"second_shared_m":13.000,"third_shared_m":24.000
void json_event_shared(std::FILE* out, const std::string& name, const std::optional<SharedMarkings>& shared) {
  if (!shared) return;
  std::fprintf(out, ",\"%s_markings\":%zu", name.c_str(), shared->count);
  json_optional(out, ("second_" + name + "_m").c_str(), shared->second_m);
  json_optional(out, ("third_" + name + "_m").c_str(), shared->third_m);
}

void json_count(std::FILE* out, const char* name, const RevisitCount& c) {
  std::fprintf(out, "\"%s\":{\"closed\":%zu,\"total\":%zu}", name, c.closed, c.total);
}

void json_closure(std::FILE* out, const char* name, const ClosureDistances& d) {
  std::fprintf(out, "\"%s\":{\"count\":%zu,\"median_m\":%.3f,\"p90_m\":%.3f}", name, d.count, d.median_m,
               d.p90_m);
}

// ,"shared_known_longer":52,"second_shared_longer":{...},"third_shared_longer":{...}
void json_shared_tally(std::FILE* out, const std::string& name, const SharedTally& t) {
  std::fprintf(out, ",\"%s_known_longer\":%zu,", name.c_str(), t.known);
  json_closure(out, ("second_" + name + "_longer").c_str(), t.second);
  std::fputc(',', out);
  json_closure(out, ("third_" + name + "_longer").c_str(), t.third);
}

}  // namespace

std::string percent_of(std::size_t part, std::size_t whole) {
  if (whole == 0) return "-";
  char text[32];
  std::snprintf(text, sizeof text, "%.1f %%", 100.0 * static_cast<double>(part) / static_cast<double>(whole));
  return text;
}

void print_revisit_tally(std::FILE* out, const RevisitTally& t) {
  std::fprintf(
      out,
      "\nRevisit events (frames within %.0f m of a frame at least %.0f s older, joined while the\n"
      "gaps are under %.0f s; closed by the first correct detection whose query frame is in the event)\n",
      kRevisitRadius_m, kRevisitMinAge_s, kRevisitMaxGap_s);
  std::fprintf(out, "  %-22s %-22s %s\n", "closed / events", "shorter than 50 m", "50 m or more");
  for (const RevisitKind k : kKinds) {
    const auto& row = t.by_kind[static_cast<std::size_t>(k)];
    print_row(out, kind_label(k), row[0], row[1]);
  }
  print_row(out, "all", t.shorter, t.longer);
  print_closure(out, "closed at, median / p90 (50 m or more)", t.closure_long);
  print_closure(out, "closed at, median / p90 (all)", t.closure_all);
  // Where a place of two or three markings could have closed them at the earliest.
  print_shared_tally(out, "markings in view on both visits, passed", t.seen_long);
  print_shared_tally(out, "... landmarks of one label on both visits", t.landmarked_long);
  if (t.landmarked_long.known > 0)
    print_shared(out, "closed past the third, median / p90", t.beyond_third_landmarked_long,
                 t.landmarked_long.third.count);
}

void print_revisit_events(std::FILE* out, std::span<const RevisitEvent> events, std::size_t limit) {
  for (std::size_t i = 0; i < events.size() && i < limit; ++i) {
    const RevisitEvent& e = events[i];
    std::fprintf(out, "    event at frame %zu (to %zu): %.1f m, %s, ", e.first_frame, e.last_frame,
                 e.length_m, kind_label(e.kind));
    if (e.closed_at_m)
      std::fprintf(out, "closed at %.1f m (query frame %zu)", *e.closed_at_m, *e.closing_query_frame);
    else
      std::fprintf(out, "never closed");
    print_event_shared(out, "in view on both visits", e.seen);
    print_event_shared(out, "landmarked on both", e.landmarked);
    std::fputc('\n', out);
  }
  if (events.size() > limit) std::fprintf(out, "    ... %zu more (all in --json)\n", events.size() - limit);
}

void json_revisit_tally(std::FILE* out, const RevisitTally& t) {
  std::fputc('{', out);
  for (const RevisitKind k : kKinds) {
    const auto& row = t.by_kind[static_cast<std::size_t>(k)];
    std::fprintf(out, "\"%s\":{", std::string(revisit_kind_name(k)).c_str());
    json_count(out, "shorter", row[0]);
    std::fputc(',', out);
    json_count(out, "longer", row[1]);
    std::fprintf(out, "},");
  }
  json_count(out, "shorter", t.shorter);
  std::fputc(',', out);
  json_count(out, "longer", t.longer);
  std::fputc(',', out);
  json_count(out, "all", t.all);
  std::fputc(',', out);
  json_closure(out, "closure_longer", t.closure_long);
  std::fputc(',', out);
  json_closure(out, "closure_all", t.closure_all);
  json_shared_tally(out, "shared", t.seen_long);
  json_shared_tally(out, "landmarked", t.landmarked_long);
  std::fputc(',', out);
  json_closure(out, "closure_beyond_third_landmarked_longer", t.beyond_third_landmarked_long);
  std::fputc('}', out);
}

void json_revisits(std::FILE* out, std::span<const RevisitEvent> events, const RevisitTally& tally) {
  std::fprintf(out,
               "\"revisits\":{\"radius_m\":%g,\"min_age_s\":%g,\"max_gap_s\":%g,\"longer_m\":%g,\"events\":[",
               kRevisitRadius_m, kRevisitMinAge_s, kRevisitMaxGap_s, kLongRevisit_m);
  for (std::size_t i = 0; i < events.size(); ++i) {
    const RevisitEvent& e = events[i];
    std::fprintf(
        out,
        "%s{\"first_frame\":%zu,\"last_frame\":%zu,\"start_m\":%.3f,\"length_m\":%.3f,\"kind\":\"%s\","
        "\"closed_at_m\":",
        i ? "," : "", e.first_frame, e.last_frame, e.start_m, e.length_m,
        std::string(revisit_kind_name(e.kind)).c_str());
    if (e.closed_at_m)
      std::fprintf(out, "%.3f,\"closing_query_frame\":%zu", *e.closed_at_m, *e.closing_query_frame);
    else
      std::fprintf(out, "null,\"closing_query_frame\":null");
    json_event_shared(out, "shared", e.seen);
    json_event_shared(out, "landmarked", e.landmarked);
    std::fputc('}', out);
  }
  std::fprintf(out, "],\"tally\":");
  json_revisit_tally(out, tally);
  std::fputc('}', out);
}

}  // namespace markloop::replay
