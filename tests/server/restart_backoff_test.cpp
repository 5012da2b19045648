// The one restart backoff of a live session's readers (gpsd, the cameras):
// 0.5 s, doubling with each failure in a row up to 5 s, 0.5 s again once the
// device delivered.
#include "server/restart_backoff.hpp"

#include <gtest/gtest.h>

#include <vector>

namespace locaid::server {
namespace {

TEST(RestartBackoff, DoublesFromHalfASecondToFiveAndStartsOverOnceTheDeviceDelivered) {
  RestartBackoff backoff;
  std::vector<double> waits;
  for (int i = 0; i < 7; ++i) {
    waits.push_back(backoff.wait_s());
    backoff.Failed();
  }
  EXPECT_EQ(waits, (std::vector<double>{0.5, 1, 2, 4, 5, 5, 5}));
  backoff.Delivered();
  EXPECT_EQ(backoff.wait_s(), 0.5);
}

}  // namespace
}  // namespace locaid::server
