// Checks on a markloop::Result shared by the test binaries: the value of a
// call that must succeed, the message of one that must fail.
#pragma once

#include <catch2/catch_test_macros.hpp>

#include <string>
#include <utility>

#include "app/common/result.hpp"

namespace markloop::test {

// The value of a load that must succeed.
template <class T>
T loaded(markloop::Result<T> result) {
  INFO((result ? std::string() : result.message()));
  REQUIRE(result);
  return std::move(result).value();
}

// The message of a load that must fail.
template <class T>
std::string error_of(const markloop::Result<T>& result) {
  REQUIRE_FALSE(result);
  return result.message();
}

}  // namespace markloop::test
