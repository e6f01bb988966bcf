// main() of the MPI test executables: gtest under one MPI session. Every rank runs every test
// and checks every assertion; only rank 0 prints gtest's report; a failure on any rank fails
// the run.
#include "parallel/comm.h"

#include <gtest/gtest.h>

namespace hs {
namespace {
const par::Comm* g_comm = nullptr;
}  // namespace
const par::Comm& test_world() { return *g_comm; }
}  // namespace hs

int main(int argc, char** argv) {
  hs::par::Session session(&argc, &argv);
  hs::g_comm = &session.world();
  ::testing::InitGoogleTest(&argc, argv);
  if (session.world().rank() != 0) {
    auto& listeners = ::testing::UnitTest::GetInstance()->listeners();
    delete listeners.Release(listeners.default_result_printer());
  }
  const int rc = RUN_ALL_TESTS();
  const std::int64_t bad = session.world().sum(static_cast<std::int64_t>(rc != 0));
  return bad ? 1 : 0;
}
