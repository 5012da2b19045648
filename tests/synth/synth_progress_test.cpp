// GenerateDrive's progress callback: when it runs, and that a callback that
// throws stops the render (how a server cancels the drive of a stopped
// session).
#include "synth/synth.hpp"
#include "synth/texture.hpp"
#include "temp_dir.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <stdexcept>
#include <vector>

namespace fs = std::filesystem;
namespace synth = locaid::synth;
using locaid::test_support::ScopedTempDir;

namespace {

synth::SynthConfig SmallDrive() {
  synth::SynthConfig cfg;
  cfg.seed = 4;
  cfg.frames = 5;
  cfg.width = 160;
  cfg.height = 64;
  return cfg;
}

size_t PngCount(const fs::path& root) {
  size_t n = 0;
  if (!fs::exists(root)) return 0;
  for (const auto& e : fs::recursive_directory_iterator(root)) n += e.path().extension() == ".png";
  return n;
}

}  // namespace

TEST(SynthProgress, SetUpStepsReportFrameZeroThenEveryFrameOnce) {
  const ScopedTempDir dir("synth_progress");
  std::vector<int> frames;
  synth::GenerateDrive(SmallDrive(), dir.path(), [&](int frame, int total) {
    EXPECT_EQ(total, 5);
    frames.push_back(frame);
  });
  // The route, each texture and the world: one frame-0 report each.
  std::vector<int> expected(1 + synth::kNumTextures + 1, 0);
  for (int k = 1; k <= 5; ++k) expected.push_back(k);
  EXPECT_EQ(frames, expected);
}

// Making the textures is the longest set-up step (seconds under a sanitizer):
// a cancel lands between two textures, not after all of them.
TEST(SynthProgress, ACallbackThatThrowsWhileTexturesAreMadeStopsThere) {
  struct Cancelled : std::runtime_error {
    Cancelled() : std::runtime_error("cancelled") {}
  };
  int calls = 0;
  EXPECT_THROW(synth::MakeTextures(4,
                                   [&] {
                                     if (++calls == 3) throw Cancelled();
                                   }),
               Cancelled);
  EXPECT_EQ(calls, 3);
  calls = 0;
  const std::vector<synth::MipTexture> all = synth::MakeTextures(4, [&] { ++calls; });
  EXPECT_EQ(calls, synth::kNumTextures);
  ASSERT_EQ(all.size(), static_cast<size_t>(synth::kNumTextures));
  for (const auto& t : all) EXPECT_FALSE(t.levels.empty());
}

TEST(SynthProgress, ACallbackThatThrowsDuringSetUpStopsBeforeAnyImage) {
  const ScopedTempDir dir("synth_progress_cancel");
  struct Cancelled : std::runtime_error {
    Cancelled() : std::runtime_error("cancelled") {}
  };
  int calls = 0;
  EXPECT_THROW(synth::GenerateDrive(SmallDrive(), dir.path(),
                                    [&](int, int) {
                                      ++calls;
                                      throw Cancelled();
                                    }),
               Cancelled);
  EXPECT_EQ(calls, 1);
  EXPECT_EQ(PngCount(dir.path()), 0u) << "the render went on to draw frames after it was cancelled";
}
