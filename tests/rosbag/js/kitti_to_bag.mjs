#!/usr/bin/env node
// Writes a KITTI raw drive (extract layout) as a ROS 2 bag: MCAP with the
// "ros2" profile, "ros2msg" schemas, CDR messages (@mcap/core McapWriter,
// @foxglove/rosmsg + @foxglove/rosmsg2-serialization), as rosbag2 writes it.
// The reference writer locaid's bag reader is tested against.
//
//   node kitti_to_bag.mjs --drive DIR --out PATH [options]
//
// Topics (under --prefix P, default none), frames and tf:
//   P/camera/{left,right}/image_raw         sensor_msgs/msg/Image mono8 (camera_left / camera_right)
//   P/camera/{left,right}/image_raw/compressed  CompressedImage instead, with --images png|jpeg
//   P/camera/{left,right}/camera_info       sensor_msgs/msg/CameraInfo: S_0x, K_0x, D_0x (plumb_bob),
//                                           R = R_rect_0x, P = P_rect_0x; one per image, same stamp
//                                           (P_rect_0x is for KITTI's rectified 1242x375 crop; roi zero)
//   P/imu/data                              sensor_msgs/msg/Imu (imu_link) from OXTS
//   P/gps/fix                               sensor_msgs/msg/NavSatFix (gps_link) from OXTS or --gps-csv
//   P/vehicle/speed                         geometry_msgs/msg/TwistStamped (base_link), --speed only
//   P/tf_static                             tf2_msgs/msg/TFMessage, once, stamp = first image:
//     imu_link -> camera_left:  T_imu_cam0 = inverse(T_cam0_velo * T_velo_imu), the raw camera-0
//                               optical frame as ROS has it (CameraInfo's R = R_rect_00 rectifies it;
//                               R_rect_00 * that = kitti/calib.cpp ComputeT_cam0_imu)
//     camera_left -> camera_right: (baseline, 0, 0), identity rotation (the rectified pair's offset,
//                               an approximation of the raw right camera; readers use P, not this)
//     imu_link -> gps_link:      identity (OXTS reports the IMU position)
// Log and publish time = stamp + a seeded pseudo-random 5..60 ms receive delay (--log-time stamp: none),
// raised to 1 us after the topic's previous message where needed (a topic arrives in stamp order);
// messages are written in log-time order, as a recorder receives them.
import fs from "node:fs";
import path from "node:path";
import { parseArgs } from "node:util";
import { parse as parseMsg } from "@foxglove/rosmsg";
import { MessageWriter } from "@foxglove/rosmsg2-serialization";
import { readDrive, readOxts } from "./kitti_read.mjs";
import { schemaText } from "./ros2_schemas.mjs";
import { BagWriter, chunkCompressor } from "./bag_writer.mjs";
import * as M from "./kitti_messages.mjs";

const USAGE = `usage: node kitti_to_bag.mjs --drive DIR --out PATH [options]
  --prefix P              topics under namespace P (e.g. /car)
  --images raw|png|jpeg   Image mono8 (default) or CompressedImage
  --imu-no-orientation    Imu without orientation (orientation_covariance[0] = -1)
  --gps-csv FILE          fixes from a CSV (t_ns, lat_deg, lon_deg, alt_m, sigma_h_m, sigma_v_m)
  --nofix S0:S1           fixes in [S0, S1) s after the first image are NO_FIX (repeatable)
  --speed                 also /vehicle/speed (TwistStamped, linear.x = vf)
  --log-time delay|stamp  log time = stamp + 5..60 ms (default) or = stamp
  --seed N                seed of the delays (default 1)
  --chunk-size BYTES      default 1048576
  --no-chunks             messages outside chunks
  --compression zstd|lz4|none   chunk compression (default zstd)
  --no-summary            no summary section, indexes or statistics
  --split N               a rosbag2 folder of MCAP files of about N messages each + metadata.yaml
  --truncate-at F         cut the written file at F (0..1) of its bytes
  --first-frame N, --max-frames N   image frames [N, N + max)
  --schema-msg-names short|long     dependency lines "MSG: std_msgs/Header" as rosbag2_cpp
                          writes them (default) or "MSG: std_msgs/msg/Header" as its docs show`;

function options() {
  const { values } = parseArgs({
    options: {
      drive: { type: "string" }, out: { type: "string" }, prefix: { type: "string", default: "" },
      images: { type: "string", default: "raw" }, "imu-no-orientation": { type: "boolean" },
      "gps-csv": { type: "string" }, nofix: { type: "string", multiple: true, default: [] },
      speed: { type: "boolean" }, "log-time": { type: "string", default: "delay" },
      seed: { type: "string", default: "1" }, "chunk-size": { type: "string", default: "1048576" },
      "no-chunks": { type: "boolean" }, compression: { type: "string", default: "zstd" },
      "no-summary": { type: "boolean" }, split: { type: "string", default: "0" },
      "truncate-at": { type: "string" }, "first-frame": { type: "string", default: "0" },
      "max-frames": { type: "string" }, "schema-msg-names": { type: "string", default: "short" },
      help: { type: "boolean" },
    },
  });
  if (values.help) {
    console.log(USAGE);
    process.exit(0);
  }
  const fail = (why) => {
    console.error(`kitti_to_bag: ${why}\n${USAGE}`);
    process.exit(2);
  };
  if (!values.drive || !values.out) fail("--drive and --out are required");
  const int = (k, min) => {
    const v = Number(values[k]);
    if (!Number.isInteger(v) || v < min) fail(`--${k} must be an integer >= ${min}`);
    return v;
  };
  if (!["raw", "png", "jpeg"].includes(values.images)) fail("--images must be raw, png or jpeg");
  if (!["delay", "stamp"].includes(values["log-time"])) fail("--log-time must be delay or stamp");
  if (!["short", "long"].includes(values["schema-msg-names"])) fail("--schema-msg-names must be short or long");
  const nofix = values.nofix.map((s) => {
    const m = /^([\d.]+):([\d.]+)$/.exec(s);
    if (!m || !(Number(m[1]) <= Number(m[2]))) fail(`--nofix '${s}': expected S0:S1 with S0 <= S1`);
    return [BigInt(Math.round(Number(m[1]) * 1e9)), BigInt(Math.round(Number(m[2]) * 1e9))];
  });
  let truncateAt = null;
  if (values["truncate-at"] !== undefined) {
    truncateAt = Number(values["truncate-at"]);
    if (!(truncateAt > 0 && truncateAt < 1)) fail("--truncate-at must be in (0, 1)");
  }
  const split = int("split", 0);
  if (split > 0 && truncateAt !== null) fail("--truncate-at applies to a single file, not --split");
  let prefix = values.prefix.replace(/\/+$/, "");
  if (prefix && !prefix.startsWith("/")) prefix = `/${prefix}`;
  return {
    ...values, prefix, nofix, truncateAt, split, seed: int("seed", 0), chunkSize: int("chunk-size", 1),
    firstFrame: int("first-frame", 0),
    maxFrames: values["max-frames"] === undefined ? Infinity : int("max-frames", 1),
  };
}

// The messages of the bag, in stamp order per topic, each {topic, stamp,
// make()}: make() builds the message when it is written (images are large).
function plan(opt, drive, topics) {
  const events = [];
  const side = ["left", "right"];
  const cams = drive.cams;
  const nFrames = cams[0].times.length;
  const last = Math.min(nFrames, opt.firstFrame + opt.maxFrames);
  let t0 = null, t1 = null;
  for (let c = 0; c < 2; ++c) {
    const frame = `camera_${side[c]}`;
    for (let i = opt.firstFrame; i < last; ++i) {
      const file = cams[c].files.get(i);
      const t = cams[c].times[i];
      if (!file || t === undefined) continue;  // missing image (left 23, right 22 in the shared copy)
      if (t0 === null || t < t0) t0 = t;
      if (t1 === null || t > t1) t1 = t;
      events.push(opt.images === "raw"
        ? { topic: topics.image[c], stamp: t, make: () => M.imageMsg(file, t, frame) }
        : { topic: topics.image[c], stamp: t, make: () => M.compressedImageMsg(file, t, frame, opt.images) });
      events.push({ topic: topics.info[c], stamp: t, make: () => M.cameraInfoMsg(drive.calib.cams[c], t, frame) });
    }
  }
  if (t0 === null) throw new Error("no image in the selected frames");
  const inWindow = (t) => t >= t0 && t <= t1;
  const oxts = readOxts(opt.drive, cams[0].times[0]).records.filter((r) => inWindow(r.t_ns));
  for (const r of oxts) {
    events.push({ topic: topics.imu, stamp: r.t_ns, make: () => M.imuMsg(r, "imu_link", !opt["imu-no-orientation"]) });
    if (opt.speed) events.push({ topic: topics.speed, stamp: r.t_ns, make: () => M.speedMsg(r, "base_link") });
  }
  const fixes = opt["gps-csv"]
    ? M.readGpsCsv(opt["gps-csv"]).filter((f) => inWindow(f.t_ns))
    : oxts.map((r) => ({ t_ns: r.t_ns, lat: r.f.lat, lon: r.f.lon, alt: r.f.alt,
                         sigmaH: r.f.posacc, sigmaV: 2 * r.f.posacc }));
  for (const fix of fixes) {
    const rel = fix.t_ns - t0;
    if (opt.nofix.some(([a, b]) => rel >= a && rel < b)) Object.assign(fix, { lat: NaN, lon: NaN, alt: NaN });
    events.push({ topic: topics.gps, stamp: fix.t_ns, make: () => M.navSatFixMsg(fix, "gps_link") });
  }
  // Log times: a receive delay per message; /tf_static first, at the first image's stamp.
  const delay = M.delays(opt.seed);
  events.sort((a, b) => (a.stamp < b.stamp ? -1 : a.stamp > b.stamp ? 1 : 0));
  const lastLog = new Map();  // a topic's messages arrive in order (one publisher, in-order delivery)
  events.forEach((e, i) => {
    e.order = i + 1;
    e.logTime = e.stamp + (opt["log-time"] === "delay" ? delay() : 0n);
    const prev = lastLog.get(e.topic);
    if (prev !== undefined && e.logTime <= prev) e.logTime = prev + 1000n;
    lastLog.set(e.topic, e.logTime);
  });
  events.unshift({ topic: topics.tf, stamp: t0, logTime: t0, order: 0, make: () => M.tfStaticMsg(drive.calib, t0) });
  events.sort((a, b) => (a.logTime < b.logTime ? -1 : a.logTime > b.logTime ? 1 : a.order - b.order));
  return { events, t0, t1, oxtsCount: oxts.length };
}

async function main() {
  const opt = options();
  const started = process.hrtime.bigint();
  const P = opt.prefix;
  const imgSuffix = opt.images === "raw" ? "" : "/compressed";
  const imgType = opt.images === "raw" ? "sensor_msgs/msg/Image" : "sensor_msgs/msg/CompressedImage";
  const topics = {
    image: ["left", "right"].map((s) => `${P}/camera/${s}/image_raw${imgSuffix}`),
    info: ["left", "right"].map((s) => `${P}/camera/${s}/camera_info`),
    imu: `${P}/imu/data`, gps: `${P}/gps/fix`, speed: `${P}/vehicle/speed`, tf: `${P}/tf_static`,
  };
  const declared = [
    { name: topics.tf, type: "tf2_msgs/msg/TFMessage", transientLocal: true },
    ...topics.image.map((name) => ({ name, type: imgType })),
    ...topics.info.map((name) => ({ name, type: "sensor_msgs/msg/CameraInfo" })),
    { name: topics.imu, type: "sensor_msgs/msg/Imu" },
    { name: topics.gps, type: "sensor_msgs/msg/NavSatFix" },
    ...(opt.speed ? [{ name: topics.speed, type: "geometry_msgs/msg/TwistStamped" }] : []),
  ];
  const drive = readDrive(opt.drive);
  const { events, t0, t1, oxtsCount } = plan(opt, drive, topics);

  const serializers = new Map();
  for (const t of declared) {
    if (!serializers.has(t.type)) serializers.set(t.type, new MessageWriter(parseMsg(schemaText(t.type), { ros2: true })));
  }
  const typeOf = new Map(declared.map((t) => [t.name, t.type]));
  if (fs.existsSync(opt.out)) fs.rmSync(opt.out, { recursive: true });
  fs.mkdirSync(path.dirname(path.resolve(opt.out)), { recursive: true });
  const bag = new BagWriter({
    out: opt.out, split: opt.split, topics: declared, msgNames: opt["schema-msg-names"],
    layout: { useChunks: !opt["no-chunks"], chunkSize: opt.chunkSize, compress: await chunkCompressor(opt.compression),
              summary: !opt["no-summary"] },
  });
  for (const e of events) {
    const data = serializers.get(typeOf.get(e.topic)).writeMessage(e.make());
    await bag.write(e.topic, e.logTime, e.logTime, data);
  }
  const paths = await bag.close();
  let truncated = null;
  if (opt.truncateAt !== null) {
    const size = fs.statSync(paths[0]).size;
    truncated = { from_bytes: size, to_bytes: Math.floor(size * opt.truncateAt) };
    fs.truncateSync(paths[0], truncated.to_bytes);
  }
  const bytes = Object.fromEntries(paths.map((p) => [p, fs.statSync(p).size]));
  console.log(JSON.stringify({
    paths, bytes, total_bytes: Object.values(bytes).reduce((a, b) => a + b, 0),
    messages: Object.fromEntries(bag.counts), message_count: events.length,
    first_stamp_ns: t0.toString(), last_stamp_ns: t1.toString(), oxts_records: oxtsCount,
    compression: opt["no-chunks"] ? "none (no chunks)" : opt.compression, truncated,
    seconds: Number(process.hrtime.bigint() - started) / 1e9,
  }));
}

main().catch((e) => {
  console.error(`kitti_to_bag: ${e.message}`);
  process.exit(1);
});
