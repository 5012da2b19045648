#!/usr/bin/env node
// CTest RosbagJs.ConverterWritesEveryVariantTheOfficialReaderReads: writes
// each variant of kitti_to_bag.mjs from the shared KITTI raw drive (20
// frames) into a temporary folder (removed on exit), reads each back with
// inspect_bag.mjs --check and checks what it reports; then checks that
// --check rejects a bag with a bad covariance and a stamp going backwards.
//
//   node self_test.mjs KITTI_DIR     (KITTI_DIR: .../shared/data/kitti)
//
// Without the data: exits 77 (skip), CI or not: the shared KITTI excerpts are
// optional, and every other test skips without them (tests/needs_tool.hpp).
import fs from "node:fs";
import os from "node:os";
import path from "node:path";
import { spawnSync } from "node:child_process";
import { fileURLToPath } from "node:url";
import { parse as parseMsg } from "@foxglove/rosmsg";
import { MessageWriter } from "@foxglove/rosmsg2-serialization";
import { BagWriter } from "./bag_writer.mjs";
import { schemaText } from "./ros2_schemas.mjs";

const here = path.dirname(fileURLToPath(import.meta.url));
const kitti = process.argv[2] ?? "";
const drive = path.join(kitti, "raw", "2011_09_26", "2011_09_26_drive_unknown_extract");
if (!fs.existsSync(path.join(drive, "image_00"))) {
  console.log(`self_test: no KITTI raw drive at ${drive}`);
  process.exit(77);
}

const tmp = fs.mkdtempSync(path.join(os.tmpdir(), "locaid_rosbag_"));
process.on("exit", () => fs.rmSync(tmp, { recursive: true, force: true }));
let failures = 0;
const check = (ok, what) => {
  console.log(`${ok ? "ok  " : "FAIL"} ${what}`);
  if (!ok) failures += 1;
};

function node(args) {
  const r = spawnSync(process.execPath, args, { cwd: here, encoding: "utf8", maxBuffer: 256 << 20 });
  return { status: r.status, stdout: r.stdout, stderr: r.stderr };
}

// Converts with `args`, inspects with --check; returns [converter JSON, inspector JSON].
function variant(name, args, samples = 1) {
  const out = path.join(tmp, name.endsWith("split") ? name : `${name}.mcap`);
  const conv = node(["kitti_to_bag.mjs", "--drive", drive, "--out", out, "--max-frames", "20", ...args]);
  if (conv.status !== 0) {
    check(false, `${name}: kitti_to_bag ${args.join(" ")} exited ${conv.status}: ${conv.stderr}`);
    return [null, null];
  }
  const written = JSON.parse(conv.stdout);
  const ins = node(["inspect_bag.mjs", "--check", "--samples", String(samples), out]);
  check(ins.status === 0, `${name}: inspect_bag --check (${(written.total_bytes / 1e6).toFixed(2)} MB)` +
                          (ins.status === 0 ? "" : `: ${ins.stderr}`));
  return [written, ins.status === 0 || ins.stdout ? JSON.parse(ins.stdout) : null];
}

const sameCounts = (w, r) => Object.entries(w.messages).every(([t, n]) => (r.topics[t]?.count ?? 0) === n) &&
  Object.values(r.topics).every((t) => t.decoded === t.count);

// Raw images, zstd chunks, summary.
const [w0, r0] = variant("raw_zstd", []);
if (r0) {
  check(sameCounts(w0, r0), "raw_zstd: every message written is read and decoded");
  check(r0.files[0].chunk_compression.join() === "zstd" && r0.files[0].summary && r0.files[0].indexed,
        "raw_zstd: zstd chunks, summary read by McapIndexedReader");
  check(r0.topics["/camera/left/image_raw"]?.type === "sensor_msgs/msg/Image" &&
        r0.topics["/camera/left/image_raw"].count === 20, "raw_zstd: 20 left Images");
  check(r0.topics["/camera/left/image_raw"].first_stamp_ns === "1317045935500923136",
        "raw_zstd: first left stamp = image_00 line 1 (2011-09-26 14:05:35.500923136 UTC) to the ns");
  const img = r0.samples["/camera/left/image_raw"][0];
  check(img.encoding === "mono8" && img.width === 1392 && img.height === 512 && img.step === 1392,
        "raw_zstd: mono8 1392x512");
  const tf = r0.samples["/tf_static"][0].transforms.map((t) => `${t.header.frame_id}>${t.child_frame_id}`);
  check(tf.join() === "imu_link>camera_left,camera_left>camera_right,imu_link>gps_link", "raw_zstd: /tf_static frames");
  const log = Object.values(r0.topics).map((t) => t.first_log_time_ns);
  check(new Set(log).size === log.length, "raw_zstd: log times differ from stamps (receive delays)");
}
// Compressed images, lz4 / none chunks.
const [w1, r1] = variant("png_lz4", ["--images", "png", "--compression", "lz4"]);
if (r1) {
  check(sameCounts(w1, r1) && r1.files[0].chunk_compression.join() === "lz4", "png_lz4: lz4 chunks read and decoded");
  check(r1.topics["/camera/left/image_raw/compressed"]?.type === "sensor_msgs/msg/CompressedImage" &&
        r1.samples["/camera/left/image_raw/compressed"][0].format.includes("png"), "png_lz4: CompressedImage png");
}
const [w2, r2] = variant("jpeg_none", ["--images", "jpeg", "--compression", "none"]);
if (r2) {
  check(sameCounts(w2, r2) && r2.files[0].chunk_compression.join() === "", "jpeg_none: uncompressed chunks");
  check(r2.samples["/camera/right/image_raw/compressed"][0].format.includes("jpeg"), "jpeg_none: CompressedImage jpeg");
}
// Layouts.
const [w3, r3] = variant("no_chunks", ["--no-chunks"]);
if (r3) check(sameCounts(w3, r3) && r3.files[0].chunks === 0 && r3.files[0].summary, "no_chunks: messages outside chunks");
const [w4, r4] = variant("no_summary", ["--no-summary"]);
if (r4) check(sameCounts(w4, r4) && !r4.files[0].summary && r4.files[0].complete, "no_summary: complete file without summary");
const [w5, r5] = variant("split", ["--split", "40"]);
if (r5) {
  check(sameCounts(w5, r5) && r5.files.length === Math.ceil(w5.message_count / 40) &&
        r5.files.every((f) => f.schemas > 0 && f.channels > 0 && f.summary),
        `split: ${r5.files.length} files, each with its own schemas and channels`);
  check(fs.readFileSync(path.join(tmp, "split", "metadata.yaml"), "utf8").includes("storage_identifier: mcap"),
        "split: metadata.yaml");
}
const [w6, r6] = variant("truncated", ["--truncate-at", "0.6"]);
if (r6 && w0) {
  check(r6.truncated && r6.message_count > 0 && r6.message_count < w0.message_count,
        `truncated: readable prefix of ${r6.message_count} of ${w0.message_count} messages`);
}
// Options.
const [, r7] = variant("prefix", ["--prefix", "/car", "--schema-msg-names", "long"]);
if (r7) check(Object.keys(r7.topics).every((t) => t.startsWith("/car/")) && "/car/imu/data" in r7.topics, "prefix: topics under /car (schemas with MSG: pkg/msg/Type)");
const [, r8] = variant("imu_no_orientation", ["--imu-no-orientation"]);
if (r8) {
  const imu = r8.samples["/imu/data"][0];
  check(imu.orientation_covariance[0] === -1 && imu.orientation.w === 0, "imu_no_orientation: orientation_covariance[0] = -1");
}
const [, r9] = variant("nofix", ["--nofix", "0.5:1.0"], 1000);
if (r9) {
  const fixes = r9.samples["/gps/fix"];
  const t0 = BigInt(r9.topics["/camera/right/image_raw"].first_stamp_ns);
  const bad = fixes.filter((f) => {
    const rel = BigInt(f.header.stamp.sec) * 1000000000n + BigInt(f.header.stamp.nanosec) - t0;
    return (rel >= 500000000n && rel < 1000000000n) !== (f.status.status === -1 && f.latitude === "NaN");
  });
  check(fixes.some((f) => f.status.status === -1) && bad.length === 0, "nofix: exactly the fixes in [0.5 s, 1.0 s) are NO_FIX");
}
const [, r10] = variant("speed", ["--speed"]);
if (r10) check(r10.topics["/vehicle/speed"]?.count === r10.topics["/imu/data"].count, "speed: one TwistStamped per OXTS record");
if (w0) {
  const t0 = BigInt(w0.first_stamp_ns);
  const csv = path.join(tmp, "gps.csv");
  fs.writeFileSync(csv, "sigma_v_m,t_ns,lat_deg,lon_deg,alt_m,extra,sigma_h_m\n" +
    `2.0,${t0 + 100000000n},49.0324,8.3429,112.3,x,1.0\n3.0,${t0 + 600000000n},nan,nan,nan,x,1.5\n` +
    `2.0,${t0 + 1100000000n},49.0325,8.3430,112.4,x,1.0\n`);
  const [, r11] = variant("gps_csv", ["--gps-csv", csv], 10);
  if (r11) {
    const s = r11.samples["/gps/fix"].map((f) => f.status.status);
    check(s.join() === "0,-1,0" && r11.samples["/gps/fix"][1].position_covariance_type === 0, "gps_csv: 3 fixes, the nan one NO_FIX");
  }
}

// --check must reject a covariance that is not PSD and a stamp going backwards.
const bad = path.join(tmp, "bad.mcap");
const type = "sensor_msgs/msg/Imu";
const bag = new BagWriter({ out: bad, topics: [{ name: "/imu/data", type }],
                            layout: { useChunks: true, chunkSize: 1 << 20, compress: undefined, summary: true } });
const writer = new MessageWriter(parseMsg(schemaText(type), { ros2: true }));
const imu = (sec, cov) => writer.writeMessage({
  header: { stamp: { sec, nanosec: 0 }, frame_id: "imu_link" }, orientation: { x: 0, y: 0, z: 0, w: 1 },
  orientation_covariance: cov, angular_velocity: { x: 0, y: 0, z: 0 }, angular_velocity_covariance: new Array(9).fill(0),
  linear_acceleration: { x: 0, y: 0, z: 0 }, linear_acceleration_covariance: new Array(9).fill(0),
});
await bag.write("/imu/data", 10n, 10n, imu(10, [1, 0, 0, 0, 1, 0, 0, 0, 1]));
await bag.write("/imu/data", 11n, 11n, imu(9, [1, 2, 0, 2, 1, 0, 0, 0, 1]));  // eigenvalue -1; stamp back
await bag.close();
const rb = node(["inspect_bag.mjs", "--check", bad]);
check(rb.status === 1 && rb.stderr.includes("positive semi-definite") && rb.stderr.includes("backwards"),
      "inspect_bag --check rejects a non-PSD covariance and a stamp going backwards");

console.log(failures ? `self_test: ${failures} check(s) failed` : "self_test: all checks passed");
process.exit(failures ? 1 : 0);
