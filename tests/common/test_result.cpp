#include "app/common/result.hpp"

#include <catch2/catch_test_macros.hpp>
#include <string>

namespace {

markloop::Result<int> half(int n) {
  if (n % 2 != 0) return markloop::error(std::to_string(n) + " is odd");
  return n / 2;
}

}  // namespace

TEST_CASE("a result holds either its value or the error's message") {
  const markloop::Result<int> good = half(8);
  REQUIRE(good.ok());
  CHECK(*good == 4);
  const markloop::Result<int> bad = half(7);
  REQUIRE_FALSE(bad.ok());
  CHECK(bad.message() == "7 is odd");
  CHECK(markloop::with_context("input.txt:3", bad.error()).message == "input.txt:3: 7 is odd");
}

TEST_CASE("a status is success or an error") {
  const markloop::Status fine;
  CHECK(fine.ok());
  const markloop::Status failed = markloop::error("disk full");
  CHECK_FALSE(failed.ok());
  CHECK(failed.message() == "disk full");
}
