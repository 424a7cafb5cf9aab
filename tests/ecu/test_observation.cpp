// How a detection becomes an observation: the gate, the placement by the
// car's pose and the weight (shared by the ECU and markloop-replay).
#include <catch2/catch_approx.hpp>
#include <catch2/catch_test_macros.hpp>

#include <cmath>
#include <limits>
#include <numbers>
#include <string_view>

#include "app/ecu/observation.hpp"

using namespace markloop;
using Catch::Approx;

TEST_CASE("a detection is placed on the ground by the car's pose", "[ecu][observation]") {
  // Facing north from (10, 20): 8 m ahead and 1 m to the left is (9, 28).
  const Pose2 pose{10.0, 20.0, std::numbers::pi / 2};
  Observation o;
  REQUIRE(ecu::observe(3, 0.9f, false, 8.0, 1.0, pose, ecu::ObservationGate{}, o) == ecu::Observed::kYes);
  CHECK(o.label == 3);
  CHECK(o.x == Approx(9.0).margin(1e-5));
  CHECK(o.y == Approx(28.0).margin(1e-5));
  // Further ahead, placed less precisely: weighed less.
  Observation far;
  REQUIRE(ecu::observe(3, 0.9f, false, 14.0, 1.0, pose, ecu::ObservationGate{}, far) == ecu::Observed::kYes);
  CHECK(far.weight < o.weight);
  CHECK(o.weight < 1.0f);
}

TEST_CASE("the gate refuses low scores, markings cut by the view and positions that are no numbers",
          "[ecu][observation]") {
  const ecu::ObservationGate gate;  // 0.6, 5.5 to 16 m
  const Pose2 pose{};
  Observation o;
  CHECK(ecu::observe(0, 0.59f, false, 8.0, 0.0, pose, gate, o) == ecu::Observed::kGated);
  CHECK(ecu::observe(0, 0.9f, false, 5.4, 0.0, pose, gate, o) == ecu::Observed::kGated);
  CHECK(ecu::observe(0, 0.9f, false, 16.1, 0.0, pose, gate, o) == ecu::Observed::kGated);
  CHECK(ecu::observe(0, 0.6f, false, 5.5, 0.0, pose, gate, o) == ecu::Observed::kYes);
  CHECK(ecu::observe(0, 0.9f, false, std::numeric_limits<double>::quiet_NaN(), 0.0, pose, gate, o) ==
        ecu::Observed::kRejected);
  CHECK(ecu::observe(0, 0.9f, false, 8.0, std::numeric_limits<double>::infinity(), pose, gate, o) ==
        ecu::Observed::kRejected);
}

TEST_CASE("a detection read turned faces against the car, unless a half turn leaves its class alike",
          "[ecu][observation]") {
  const auto facing = [](std::string_view name, bool turned) {
    Observation o;
    REQUIRE(ecu::observe(*perception::marking_class_from_name(name), 0.9f, turned, 8.0, 0.0, Pose2{},
                         ecu::ObservationGate{}, o) == ecu::Observed::kYes);
    return o.facing;
  };
  CHECK(facing("bike", false) == Facing::kAlong);
  CHECK(facing("bike", true) == Facing::kAgainst);
  CHECK(facing("forward", true) == Facing::kAgainst);
  CHECK(facing("crosswalk", false) == Facing::kAny);
  CHECK(facing("stopline", true) == Facing::kAny);
}
