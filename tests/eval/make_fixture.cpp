// Writes the synthetic run of eval_fixture.hpp into DIR, for the CLI test.
#include <cstdio>

#include "tests/eval/eval_fixture.hpp"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: markloop-eval-fixture DIR\n");
    return 2;
  }
  markloop::eval::fixture::write_run(argv[1]);
  return 0;
}
