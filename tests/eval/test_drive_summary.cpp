// markloop-eval --summary: two drives' eval.json files summed into the
// table's numbers, and files that are not an eval.json refused by name.
#include <catch2/catch_approx.hpp>
#include <catch2/catch_test_macros.hpp>
#include <catch2/matchers/catch_matchers_string.hpp>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "app/tools/eval/drive_summary.hpp"
#include "app/tools/eval/json_reader.hpp"

namespace fs = std::filesystem;
using namespace markloop;
using namespace markloop::eval;
using Catch::Approx;
using Catch::Matchers::ContainsSubstring;

namespace {

std::string write_json(const std::string& name, const std::string& text) {
  const fs::path dir = fs::temp_directory_path() / "markloop-drive-summary-test";
  fs::create_directories(dir);
  std::ofstream(dir / name) << text;
  return (dir / name).string();
}

// An eval.json cut down to what the summary reads.
std::string eval_json(double route_m, int wrong, int pose_errors, double rpe_m, const std::string& events) {
  return "{\"frames\":10,\"route_length_m\":" + std::to_string(route_m) +
         ",\"loops\":{\"wrong\":" + std::to_string(wrong) +
         ",\"pose_errors\":" + std::to_string(pose_errors) +
         ",\"translation_error_mean_m\":" + std::to_string(rpe_m) +
         ",\"events\":[]},\"revisits\":{\"radius_m\":6,\"events\":[" + events + "]}}\n";
}

std::string event(int first, double length_m, const char* kind, const char* closed_at) {
  return "{\"first_frame\":" + std::to_string(first) + ",\"last_frame\":" + std::to_string(first + 10) +
         ",\"start_m\":0,\"length_m\":" + std::to_string(length_m) + ",\"kind\":\"" + kind +
         "\",\"closed_at_m\":" + closed_at + ",\"closing_query_frame\":null}";
}

DriveFigures load(const std::string& path) {
  Result<DriveFigures> d = load_drive_figures(path);
  INFO((d ? std::string() : d.message()));
  REQUIRE(d);
  return *d;
}

// An event with the markings it shares with the older visit (markloop-eval
// with the markings in view).
std::string event_sharing(int first, const char* shared, const char* second, const char* third,
                          const std::string& name = "shared") {
  std::string e = event(first, 100.0, "same", "null");
  e.pop_back();
  return e + ",\"" + name + "_markings\":" + shared + ",\"second_" + name + "_m\":" + second + ",\"third_" +
         name + "_m\":" + third + "}";
}

}  // namespace

TEST_CASE("two drives' eval.json files sum into the table's numbers") {
  const std::string a = write_json(
      "a.json", eval_json(1200.0, 0, 10, 0.02,
                          event(100, 300.0, "same", "20.0") + "," + event(500, 12.0, "crossing", "null") +
                              "," + event(700, 80.0, "opposite", "60.0")));
  const std::string b = write_json(
      "b.json", eval_json(800.0, 2, 30, 0.06,
                          event(50, 150.0, "same", "null") + "," + event(400, 55.0, "crossing", "40.0")));
  const DrivesSummary s = summarise_drives({load(a), load(b)});
  CHECK(s.drives == 2);
  CHECK(s.route_length_m == Approx(2000.0));
  CHECK(s.wrong == 2);
  REQUIRE(s.with_wrong_loops.size() == 1);
  CHECK(s.with_wrong_loops[0].name == b);
  // Mean over all 40 detections with a pose: (10 * 0.02 + 30 * 0.06) / 40.
  CHECK(s.pose_errors == 40);
  CHECK(s.translation_error_mean_m == Approx(0.05));
  // Long: same 1 of 2, opposite 1 of 1, crossing (turn-in) 1 of 1; short: crossing 0 of 1.
  const auto& same = s.tally.by_kind[static_cast<std::size_t>(replay::RevisitKind::SameDirection)];
  const auto& crossing = s.tally.by_kind[static_cast<std::size_t>(replay::RevisitKind::Crossing)];
  CHECK(same[1].closed == 1);
  CHECK(same[1].total == 2);
  CHECK(crossing[0].total == 1);
  CHECK(crossing[0].closed == 0);
  CHECK(crossing[1].closed == 1);
  CHECK(s.tally.longer.closed == 3);
  CHECK(s.tally.longer.total == 4);
  CHECK(s.tally.all.total == 5);
  // Closed at 20, 40, 60 m.
  CHECK(s.tally.closure_long.median_m == Approx(40.0));
  CHECK(s.tally.closure_long.p90_m == Approx(60.0));
}

TEST_CASE("the markings events share with the older visit are summed over drives") {
  const std::string a = write_json("shared-a.json", eval_json(1000.0, 0, 0, 0.0,
                                                              event_sharing(1, "4", "10.0", "30.0") + "," +
                                                                  event_sharing(200, "2", "5.0", "null")));
  const std::string b = write_json("shared-b.json", eval_json(1000.0, 0, 0, 0.0,
                                                              event_sharing(1, "5", "20.0", "50.0") + "," +
                                                                  event(300, 100.0, "same", "null")));
  const DrivesSummary s = summarise_drives({load(a), load(b)});
  // The event without them (an older eval.json's) is not counted.
  CHECK(s.tally.seen_long.known == 3);
  CHECK(s.tally.seen_long.second.count == 3);
  CHECK(s.tally.seen_long.second.median_m == Approx(10.0));
  CHECK(s.tally.seen_long.third.count == 2);
  CHECK(s.tally.seen_long.third.median_m == Approx(40.0));
  CHECK(s.tally.landmarked_long.known == 0);
  const std::string c = write_json(
      "landmarked.json", eval_json(1000.0, 0, 0, 0.0, event_sharing(1, "3", "12.0", "33.0", "landmarked")));
  const DrivesSummary l = summarise_drives({load(c)});
  CHECK(l.tally.seen_long.known == 0);
  CHECK(l.tally.landmarked_long.known == 1);
  CHECK(l.tally.landmarked_long.third.median_m == Approx(33.0));
  const std::string bad =
      write_json("shared-bad.json", eval_json(1.0, 0, 0, 0.0, event_sharing(1, "2.5", "1.0", "null")));
  const Result<DriveFigures> refused = load_drive_figures(bad);
  REQUIRE_FALSE(refused);
  CHECK_THAT(refused.message(), ContainsSubstring("\"shared_markings\" is not a whole number"));
}

TEST_CASE("a file that is not an eval.json of this markloop-eval is refused by name") {
  const std::string truncated = write_json("cut.json", "{\"loops\":{\"wrong\":1");
  const Result<DriveFigures> cut = load_drive_figures(truncated);
  REQUIRE_FALSE(cut);
  CHECK_THAT(cut.message(), ContainsSubstring(truncated + ": byte"));
  const std::string old = write_json("old.json", "{\"route_length_m\":1,\"loops\":{\"wrong\":0}}");
  const Result<DriveFigures> without = load_drive_figures(old);
  REQUIRE_FALSE(without);
  CHECK_THAT(without.message(), ContainsSubstring("\"revisits\""));
  const std::string bad_kind =
      write_json("kind.json", eval_json(1.0, 0, 0, 0.0, event(1, 10.0, "sideways", "null")));
  const Result<DriveFigures> kind = load_drive_figures(bad_kind);
  REQUIRE_FALSE(kind);
  CHECK_THAT(kind.message(), ContainsSubstring("revisit event 1: \"kind\""));
}

TEST_CASE("the JSON reader reads nesting, escapes and numbers, and refuses junk after the value") {
  const Result<JsonValue> v = parse_json(R"( {"a":[1,-2.5e1,true,null],"b":{"c":"x\"y\u0041"}} )");
  REQUIRE(v);
  const JsonValue* a = v->find("a");
  REQUIRE(a);
  REQUIRE(a->items.size() == 4);
  CHECK(a->items[1].number == Approx(-25.0));
  CHECK(a->items[2].boolean);
  CHECK(a->items[3].is(JsonValue::Type::Null));
  CHECK(v->find("b")->find("c")->string == "x\"yA");
  CHECK_FALSE(parse_json("{} x"));
  CHECK_FALSE(parse_json("[1,]"));
  CHECK_FALSE(parse_json(std::string(100, '[')));
}
