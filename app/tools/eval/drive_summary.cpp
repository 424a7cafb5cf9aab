#include "app/tools/eval/drive_summary.hpp"

#include <cmath>
#include <optional>

#include "app/tools/common/tool_files.hpp"
#include "app/tools/eval/inputs.hpp"
#include "app/tools/eval/json_reader.hpp"
#include "app/tools/replay/revisit_report.hpp"

namespace markloop::eval {

namespace {

using Type = JsonValue::Type;

// The number at `key` of `object`, a whole one when `whole`; else why not.
Result<double> number_at(const JsonValue& object, const char* key, bool whole = false) {
  const JsonValue* v = object.find(key);
  if (v == nullptr || !v->is(Type::Number)) return error(std::string("\"") + key + "\" is not a number");
  if (whole && (v->number < 0 || v->number != std::floor(v->number)))
    return error(std::string("\"") + key + "\" is not a whole number");
  return v->number;
}

// The number at `key` of `object`; none when absent or null (or not a number).
std::optional<double> optional_number_at(const JsonValue& object, const char* key) {
  const JsonValue* v = object.find(key);
  return v != nullptr && v->is(Type::Number) ? std::optional<double>(v->number) : std::nullopt;
}

// An event's "<name>_markings", "second_<name>_m" and "third_<name>_m".
Result<std::optional<replay::SharedMarkings>> shared_of(const JsonValue& e, const std::string& name) {
  if (e.find(name + "_markings") == nullptr) return std::optional<replay::SharedMarkings>();
  const Result<double> count = number_at(e, (name + "_markings").c_str(), true);
  if (!count) return count.error();
  replay::SharedMarkings shared;
  shared.count = static_cast<std::size_t>(*count);
  shared.second_m = optional_number_at(e, ("second_" + name + "_m").c_str());
  shared.third_m = optional_number_at(e, ("third_" + name + "_m").c_str());
  return std::optional(shared);
}

Result<replay::RevisitEvent> event_of(const JsonValue& e) {
  replay::RevisitEvent event;
  const Result<double> first = number_at(e, "first_frame", true), last = number_at(e, "last_frame", true),
                       length = number_at(e, "length_m");
  for (const Result<double>* r : {&first, &last, &length})
    if (!*r) return r->error();
  event.first_frame = static_cast<std::size_t>(*first);
  event.last_frame = static_cast<std::size_t>(*last);
  event.length_m = *length;
  const JsonValue* kind = e.find("kind");
  const auto k = kind && kind->is(Type::String) ? replay::revisit_kind_from_name(kind->string) : std::nullopt;
  if (!k) return error("\"kind\" is not same, opposite or crossing");
  event.kind = *k;
  event.closed_at_m = optional_number_at(e, "closed_at_m");
  // Shared markings: absent from runs without the markings in view (or the
  // landmarks).
  for (const auto& [name, shared] :
       {std::pair{"shared", &event.seen}, std::pair{"landmarked", &event.landmarked}}) {
    Result<std::optional<replay::SharedMarkings>> read = shared_of(e, name);
    if (!read) return read.error();
    *shared = *read;
  }
  return event;
}

// The drive's figures from the parsed file; else what is missing.
Result<DriveFigures> figures_of(const JsonValue& root) {
  DriveFigures d;
  const JsonValue* loops = root.find("loops");
  const JsonValue* revisits = root.find("revisits");
  const JsonValue* events = revisits ? revisits->find("events") : nullptr;
  if (!loops || !events || !events->is(Type::Array))
    return error("no \"loops\" or \"revisits\".\"events\" (not an eval.json of this markloop-eval)");
  const Result<double> length = number_at(root, "route_length_m"), wrong = number_at(*loops, "wrong", true),
                       poses = number_at(*loops, "pose_errors", true),
                       rpe = number_at(*loops, "translation_error_mean_m");
  for (const Result<double>* r : {&length, &wrong, &poses, &rpe})
    if (!*r) return r->error();
  d.route_length_m = *length;
  d.wrong = static_cast<std::size_t>(*wrong);
  d.pose_errors = static_cast<std::size_t>(*poses);
  d.translation_error_mean_m = *rpe;
  for (std::size_t i = 0; i < events->items.size(); ++i) {
    Result<replay::RevisitEvent> e = event_of(events->items[i]);
    if (!e) return error("revisit event " + std::to_string(i + 1) + ": " + e.message());
    d.events.push_back(*e);
  }
  return d;
}

}  // namespace

Result<DriveFigures> load_drive_figures(const std::string& path) {
  const Result<std::string> text = tools::read_input(path, kMaxInputBytes, "an eval.json");
  if (!text) return text.error();
  const Result<JsonValue> root = parse_json(*text);
  if (!root) return error(path + ": " + root.message());
  Result<DriveFigures> figures = figures_of(*root);
  if (!figures) return error(path + ": " + figures.message());
  figures->name = path;
  return figures;
}

DrivesSummary summarise_drives(const std::vector<DriveFigures>& drives) {
  DrivesSummary s;
  std::vector<replay::RevisitEvent> events;
  double error_sum = 0.0;
  for (const DriveFigures& d : drives) {
    ++s.drives;
    s.route_length_m += d.route_length_m;
    events.insert(events.end(), d.events.begin(), d.events.end());
    s.wrong += d.wrong;
    s.pose_errors += d.pose_errors;
    error_sum += d.translation_error_mean_m * static_cast<double>(d.pose_errors);
    if (d.wrong > 0) s.with_wrong_loops.push_back({d.name, d.wrong});
  }
  s.tally = replay::tally_revisit_events(events);
  if (s.pose_errors > 0) s.translation_error_mean_m = error_sum / static_cast<double>(s.pose_errors);
  return s;
}

void print_drives_summary(std::FILE* out, const DrivesSummary& s) {
  std::fprintf(out, "markloop-eval --summary: %zu drives, %.2f km driven\n", s.drives,
               s.route_length_m / 1000.0);
  replay::print_revisit_tally(out, s.tally);
  std::fprintf(out, "\nLoop detections\n");
  std::fprintf(out, "  %-40s %zu\n", "wrong LoopDetections", s.wrong);
  if (s.pose_errors > 0)
    std::fprintf(out, "  %-40s %.3f m (%zu correct detections with a pose)\n", "relative pose error, mean",
                 s.translation_error_mean_m, s.pose_errors);
  else
    std::fprintf(out, "  %-40s - (no correct detection with a pose)\n", "relative pose error, mean");
  for (const DriveWithWrongLoops& d : s.with_wrong_loops)
    std::fprintf(out, "    wrong loops: %s (%zu)\n", d.name.c_str(), d.wrong);
}

Status write_drives_summary_json(const std::string& path, const DrivesSummary& s) {
  tools::OutputFile file;
  if (Status opened = file.open(path); !opened) return opened;
  std::FILE* f = file.get();
  std::fprintf(f, "{\"drives\":%zu,\"route_length_m\":%.1f,\"revisits\":", s.drives, s.route_length_m);
  replay::json_revisit_tally(f, s.tally);
  std::fprintf(f,
               ",\"wrong\":%zu,\"pose_errors\":%zu,\"translation_error_mean_m\":%.4f,\"with_wrong_loops\":[",
               s.wrong, s.pose_errors, s.translation_error_mean_m);
  for (std::size_t i = 0; i < s.with_wrong_loops.size(); ++i) {
    // Names are paths: quotes and backslashes escaped.
    std::string name;
    for (const char c : s.with_wrong_loops[i].name)
      name += (c == '"' || c == '\\') ? std::string{'\\', c} : std::string{c};
    std::fprintf(f, "%s{\"drive\":\"%s\",\"wrong\":%zu}", i ? "," : "", name.c_str(),
                 s.with_wrong_loops[i].wrong);
  }
  std::fprintf(f, "]}\n");
  return file.close();
}

}  // namespace markloop::eval
