#include "pipeline/frame_source.hpp"

#include "kitti/oxts.hpp"
#include "pipeline/oxts_adapter.hpp"

#include <algorithm>
#include <cstdint>
#include <stdexcept>
#include <utility>

namespace locaid::pipeline {

DatasetFrameSource::DatasetFrameSource(std::unique_ptr<kitti::StereoDataset> dataset, int64_t first,
                                       int64_t last, bool load_images)
    : dataset_(std::move(dataset)), load_images_(load_images) {
  const auto n = static_cast<int64_t>(dataset_->size());
  first_ = std::clamp<int64_t>(first, 0, n);
  end_ = last < 0 ? n : std::clamp<int64_t>(last + 1, first_, n);
  next_ = first_;
  // OXTS samples before the first frame are not fed.
  if (first_ < n) {
    const int64_t t0 = dataset_->time_ns(static_cast<size_t>(first_));
    const auto& oxts = dataset_->oxts();
    while (next_oxts_ < oxts.size() && oxts[next_oxts_].t_ns < t0) ++next_oxts_;
  }
  // Unreadable OXTS files (NaN, wrong field count, ...) that a reader opened
  // with skip_bad_oxts left out: counted as bad OXTS lines of the session.
  const auto& skipped = dataset_->report().oxts_skipped;
  skipped_oxts_ = static_cast<int>(skipped.size());
  if (!skipped.empty()) skipped_oxts_error_ = skipped.back();
}

double DatasetFrameSource::duration_s() const {
  if (end_ - first_ < 2) return 0;
  return static_cast<double>(dataset_->time_ns(static_cast<size_t>(end_ - 1)) -
                             dataset_->time_ns(static_cast<size_t>(first_))) * 1e-9;
}

SourceItem DatasetFrameSource::Next() {
  SourceItem item;
  if (next_ >= end_) {
    item.kind = SourceItem::Kind::kEnd;
    return item;
  }
  const auto i = static_cast<size_t>(next_++);
  item.index = static_cast<int64_t>(i);
  if (skipped_oxts_ > 0) {  // once, with the first item
    item.oxts_bad_lines = std::exchange(skipped_oxts_, 0);
    item.error = std::move(skipped_oxts_error_);
  }
  item.t_ns = dataset_->time_ns(i);
  const auto& oxts = dataset_->oxts();
  while (next_oxts_ < oxts.size() && oxts[next_oxts_].t_ns <= item.t_ns) AppendOxts(oxts[next_oxts_++], item.samples);
  // The truth at the frame time: OXTS is the reference unit (docs/architecture.md,
// "Data flow": the filter sees only a degraded copy of it).
  if (next_oxts_ > 0) item.truth = OxtsTruthAt(item.t_ns, oxts[next_oxts_ - 1], oxts[std::min(next_oxts_, oxts.size() - 1)]);
  if (!dataset_->has_stereo(i)) {
    item.kind = SourceItem::Kind::kSkipped;
    item.error = "frame " + std::to_string(i) + ": left or right image missing";
    return item;
  }
  if (item.t_ns <= last_frame_ns_) {
    item.kind = SourceItem::Kind::kCorrupt;
    item.error = "frame " + std::to_string(i) + ": time " + std::to_string(item.t_ns) +
                 " ns not after the previous frame (" + std::to_string(last_frame_ns_) + " ns)";
    return item;
  }
  if (!load_images_) {
    item.kind = SourceItem::Kind::kFrame;
    last_frame_ns_ = item.t_ns;
    return item;
  }
  try {
    kitti::StereoImages images = dataset_->Load(i, pair_runner());
    item.left = std::move(images.left);
    item.right = std::move(images.right);
    item.kind = SourceItem::Kind::kFrame;
    last_frame_ns_ = item.t_ns;
  } catch (const std::exception& e) {
    item.kind = SourceItem::Kind::kCorrupt;
    item.error = e.what();
  }
  return item;
}

}  // namespace locaid::pipeline
