// The one place a recorded drive's OXTS becomes typed sensor data. OXTS (the
// RT3003's GPS/IMU solution) is the drive's ground truth, so its samples go
// into SampleBatch's reference lists, from which the scenario stage makes what
// the filter sees; the frame's truth is the reference pose at its time.
#pragma once

#include "fusion/types.hpp"
#include "kitti/types.hpp"
#include "pipeline/samples.hpp"

#include <cstdint>

namespace locaid::pipeline {

// The IMU part of an OXTS record (body axes: accelerations and angular rates).
fusion::ImuSample OxtsImu(int64_t t_ns, const kitti::OxtsRecord& record);
// The position and attitude of an OXTS record.
fusion::ReferencePose OxtsReferencePose(int64_t t_ns, const kitti::OxtsRecord& record);
// Both, appended to the batch's reference lists.
void AppendOxts(const kitti::OxtsSample& sample, SampleBatch& batch);
// Ground truth at t_ns between two records: position interpolated, attitude
// of the nearer record (a before b; a alone when they are the same record).
fusion::ReferencePose OxtsTruthAt(int64_t t_ns, const kitti::OxtsSample& a, const kitti::OxtsSample& b);

}  // namespace locaid::pipeline
