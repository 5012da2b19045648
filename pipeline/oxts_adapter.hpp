// The one place a recorded drive's OXTS becomes samples. OXTS (the RT3003's
// GPS/IMU solution) is the drive's truth, so its samples go into
// SampleBatch's truth lists, from which the scenario stage makes what the
// filter sees; the frame's truth is the truth sample at its time.
#pragma once

#include "fusion/types.hpp"
#include "kitti/types.hpp"
#include "pipeline/samples.hpp"

#include <cstdint>

namespace locaid::pipeline {

// The IMU part of an OXTS record (body axes: accelerations and angular rates).
fusion::ImuSample OxtsImu(int64_t t_ns, const kitti::OxtsRecord& record);
// The position and attitude of an OXTS record.
fusion::TruthSample OxtsTruthSample(int64_t t_ns, const kitti::OxtsRecord& record);
// Both, appended to the batch's truth lists.
void AppendOxts(const kitti::OxtsSample& sample, SampleBatch& batch);
// Ground truth at t_ns between two records: position interpolated, attitude
// of the nearer record (a before b; a alone when they are the same record).
fusion::TruthSample OxtsTruthAt(int64_t t_ns, const kitti::OxtsSample& a, const kitti::OxtsSample& b);

}  // namespace locaid::pipeline
