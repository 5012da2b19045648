// Left and right images paired by their stamps, for every stereo input whose
// two cameras arrive apart: a bag's two image topics (BagFrameSource), the
// cameras the server reads itself (server/camera_feeder) and a car's image
// topics over DDS (ros2/input_assembler). Images of each
// side come in stamp order; the oldest image of each side is compared with
// the other side's oldest: within the tolerance they are a pair, otherwise
// the older one has no partner (the other side has already moved past it).
// A side keeps at most `max_waiting` images while the other side has none;
// one more pushes its oldest out, unpaired.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <deque>
#include <optional>
#include <utility>

namespace locaid::pipeline {

enum class StereoSide { kLeft, kRight };

template <typename Image>
class StereoPairer {
 public:
  StereoPairer(int64_t tolerance_ns, size_t max_waiting) : tolerance_ns_(tolerance_ns), max_waiting_(max_waiting) {}

  // Queues an image of one side. Returns the oldest image of that side when
  // more than max_waiting wait: it has no partner (a newer image of its own
  // side came first).
  std::optional<Image> Add(StereoSide side, int64_t stamp_ns, Image image) {
    std::deque<Waiting>& q = Queue(side);
    q.push_back({stamp_ns, std::move(image)});
    if (q.size() <= max_waiting_) return std::nullopt;
    Image oldest = std::move(q.front().image);
    q.pop_front();
    return oldest;
  }

  // Pairs while both sides have an image: on_pair(left, right) for a pair,
  // on_unpaired(side, image) for an older image without a partner, in
  // stamp order.
  template <typename OnPair, typename OnUnpaired>
  void Pair(OnPair&& on_pair, OnUnpaired&& on_unpaired) {
    while (!left_.empty() && !right_.empty()) {
      const int64_t d = left_.front().stamp_ns - right_.front().stamp_ns;
      if (std::llabs(d) <= tolerance_ns_) {
        Waiting l = std::move(left_.front()), r = std::move(right_.front());
        left_.pop_front();
        right_.pop_front();
        on_pair(std::move(l.image), std::move(r.image));
        continue;
      }
      const StereoSide older = d < 0 ? StereoSide::kLeft : StereoSide::kRight;
      Waiting w = std::move(Queue(older).front());
      Queue(older).pop_front();
      on_unpaired(older, std::move(w.image));
    }
  }

  // The images still waiting, left side first, each side oldest first (the
  // end of the input: none of them will be paired); the pairer is empty after.
  template <typename OnUnpaired>
  void Drain(OnUnpaired&& on_unpaired) {
    for (const StereoSide side : {StereoSide::kLeft, StereoSide::kRight}) {
      for (Waiting& w : Queue(side)) on_unpaired(side, std::move(w.image));
      Queue(side).clear();
    }
  }

  void Clear() {
    left_.clear();
    right_.clear();
  }

  // The stamp of the oldest image of `side` still waiting for a partner.
  std::optional<int64_t> OldestWaiting(StereoSide side) const {
    const std::deque<Waiting>& q = side == StereoSide::kLeft ? left_ : right_;
    return q.empty() ? std::nullopt : std::optional<int64_t>(q.front().stamp_ns);
  }

 private:
  struct Waiting {
    int64_t stamp_ns = 0;
    Image image;
  };
  std::deque<Waiting>& Queue(StereoSide side) { return side == StereoSide::kLeft ? left_ : right_; }

  int64_t tolerance_ns_;
  size_t max_waiting_;
  std::deque<Waiting> left_, right_;
};

}  // namespace locaid::pipeline
