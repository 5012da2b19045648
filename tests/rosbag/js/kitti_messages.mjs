// ROS 2 messages (plain objects for @foxglove/rosmsg2-serialization's
// MessageWriter) built from KITTI data.
import fs from "node:fs";
import { decode as decodePng } from "fast-png";
import jpeg from "jpeg-js";
import { quatFromMatrix, quatFromRollPitchYaw } from "./kitti_read.mjs";

export const stampOf = (ns) => ({ sec: Number(ns / 1000000000n), nanosec: Number(ns % 1000000000n) });
const header = (ns, frameId) => ({ stamp: stampOf(ns), frame_id: frameId });
const diag3 = (a, b, c) => [a, 0, 0, 0, b, 0, 0, 0, c];

// Receive delays: deterministic pseudo-random 5..60 ms (mulberry32).
export function delays(seed) {
  let a = seed >>> 0;
  return () => {
    a = (a + 0x6d2b79f5) >>> 0;
    let t = a;
    t = Math.imul(t ^ (t >>> 15), t | 1);
    t ^= t + Math.imul(t ^ (t >>> 7), t | 61);
    const r = ((t ^ (t >>> 14)) >>> 0) / 4294967296;
    return 5000000n + BigInt(Math.floor(r * 55000001));
  };
}

// sensor_msgs/msg/Image from a PNG (8-bit gray -> mono8, 8-bit RGB -> rgb8).
export function imageMsg(file, stampNs, frameId) {
  const png = decodePng(fs.readFileSync(file));
  const enc = { 1: "mono8", 3: "rgb8" }[png.channels];
  if (png.depth !== 8 || !enc) throw new Error(`${file}: ${png.depth}-bit ${png.channels}-channel PNG, expected 8-bit gray or RGB`);
  const data = png.data instanceof Uint8Array ? png.data : Uint8Array.from(png.data);
  return {
    header: header(stampNs, frameId), height: png.height, width: png.width, encoding: enc,
    is_bigendian: 0, step: png.width * png.channels, data,
  };
}

// sensor_msgs/msg/CompressedImage: the PNG file as it is, or re-encoded as
// JPEG (quality 90). format as compressed_image_transport writes it.
export function compressedImageMsg(file, stampNs, frameId, codec) {
  const bytes = fs.readFileSync(file);
  if (codec === "png") {
    return { header: header(stampNs, frameId), format: "mono8; png compressed ", data: new Uint8Array(bytes) };
  }
  const png = decodePng(bytes);
  const n = png.width * png.height;
  const rgba = new Uint8Array(n * 4);
  for (let i = 0; i < n; ++i) {
    const c = png.channels;
    rgba[4 * i] = png.data[c * i];
    rgba[4 * i + 1] = png.data[c * i + (c >= 3 ? 1 : 0)];
    rgba[4 * i + 2] = png.data[c * i + (c >= 3 ? 2 : 0)];
    rgba[4 * i + 3] = 255;
  }
  const jpg = jpeg.encode({ data: rgba, width: png.width, height: png.height }, 90);
  const fmt = png.channels === 1 ? "mono8; jpeg compressed " : "rgb8; jpeg compressed bgr8";
  return { header: header(stampNs, frameId), format: fmt, data: new Uint8Array(jpg.data) };
}

// sensor_msgs/msg/CameraInfo of a raw (unrectified) KITTI camera: size S_0x,
// K_0x, plumb_bob D_0x, R = R_rect_0x, P = P_rect_0x (the right camera's
// P[3] = -fx * baseline, as KITTI and ROS both write it).
export function cameraInfoMsg(cam, stampNs, frameId) {
  return {
    header: header(stampNs, frameId), height: cam.S[1], width: cam.S[0],
    distortion_model: "plumb_bob", d: cam.D, k: cam.K, r: cam.R_rect, p: cam.P_rect,
    binning_x: 0, binning_y: 0,
    roi: { x_offset: 0, y_offset: 0, height: 0, width: 0, do_rectify: false },
  };
}

// 1-sigma values of the covariances written (RT3003-like).
export const SIGMA = { rollPitchRad: 0.03 * Math.PI / 180, yawRad: 0.1 * Math.PI / 180,
                       gyroRadS: 0.01, accelMs2: 0.1 };

// sensor_msgs/msg/Imu from an OXTS record: body frame x forward, y left, z up.
export function imuMsg(rec, frameId, withOrientation) {
  const f = rec.f;
  const { rollPitchRad: rp, yawRad: y, gyroRadS: g, accelMs2: a } = SIGMA;
  return {
    header: header(rec.t_ns, frameId),
    orientation: withOrientation ? quatFromRollPitchYaw(f.roll, f.pitch, f.yaw) : { x: 0, y: 0, z: 0, w: 0 },
    orientation_covariance: withOrientation ? diag3(rp * rp, rp * rp, y * y) : [-1, 0, 0, 0, 0, 0, 0, 0, 0],
    angular_velocity: { x: f.wf, y: f.wl, z: f.wu },
    angular_velocity_covariance: diag3(g * g, g * g, g * g),
    linear_acceleration: { x: f.af, y: f.al, z: f.au },
    linear_acceleration_covariance: diag3(a * a, a * a, a * a),
  };
}

// sensor_msgs/msg/NavSatFix. fix: {t_ns, lat, lon, alt, sigmaH, sigmaV}; lat
// NaN = no fix (status -1, NaN position, covariance unknown).
export function navSatFixMsg(fix, frameId) {
  const noFix = !Number.isFinite(fix.lat) || !Number.isFinite(fix.lon);
  const known = !noFix && Number.isFinite(fix.sigmaH) && Number.isFinite(fix.sigmaV);
  return {
    header: header(fix.t_ns, frameId),
    status: { status: noFix ? -1 : 0, service: 1 },
    latitude: noFix ? NaN : fix.lat,
    longitude: noFix ? NaN : fix.lon,
    altitude: noFix ? NaN : fix.alt,
    position_covariance: known ? diag3(fix.sigmaH ** 2, fix.sigmaH ** 2, fix.sigmaV ** 2) : diag3(0, 0, 0),
    position_covariance_type: known ? 2 : 0,
  };
}

// geometry_msgs/msg/TwistStamped: forward speed vf.
export function speedMsg(rec, frameId) {
  return {
    header: header(rec.t_ns, frameId),
    twist: { linear: { x: rec.f.vf, y: 0, z: 0 }, angular: { x: 0, y: 0, z: 0 } },
  };
}

// tf2_msgs/msg/TFMessage of the static frames (see README of kitti_to_bag.mjs).
export function tfStaticMsg(calib, stampNs) {
  const T = calib.T_imu_cam0;
  const tf = (parent, child, t, q) => ({
    header: header(stampNs, parent), child_frame_id: child,
    transform: { translation: { x: t[0], y: t[1], z: t[2] }, rotation: q },
  });
  const I = { x: 0, y: 0, z: 0, w: 1 };
  return {
    transforms: [
      tf("imu_link", "camera_left", [T[0][3], T[1][3], T[2][3]], quatFromMatrix(T.slice(0, 3).map((r) => r.slice(0, 3)))),
      tf("camera_left", "camera_right", [calib.baseline, 0, 0], I),
      tf("imu_link", "gps_link", [0, 0, 0], I),
    ],
  };
}

// GPS fixes from a CSV with a header naming t_ns, lat_deg, lon_deg, alt_m,
// sigma_h_m, sigma_v_m (any order, other columns ignored).
export function readGpsCsv(file) {
  const lines = fs.readFileSync(file, "utf8").split(/\r?\n/).filter((l) => l.trim());
  const cols = lines[0].split(",").map((s) => s.trim());
  const need = ["t_ns", "lat_deg", "lon_deg", "alt_m", "sigma_h_m", "sigma_v_m"];
  const at = Object.fromEntries(need.map((k) => [k, cols.indexOf(k)]));
  const missing = need.filter((k) => at[k] < 0);
  if (missing.length) throw new Error(`${file}: header lacks column(s) ${missing.join(", ")}`);
  const num = (s) => (s === undefined || s.trim() === "" || /^nan$/i.test(s.trim()) ? NaN : Number(s));
  return lines.slice(1).map((line, i) => {
    const v = line.split(",");
    if (!/^\s*-?\d+\s*$/.test(v[at.t_ns] ?? "")) throw new Error(`${file}:${i + 2}: t_ns is not an integer`);
    return { t_ns: BigInt(v[at.t_ns].trim()), lat: num(v[at.lat_deg]), lon: num(v[at.lon_deg]),
             alt: num(v[at.alt_m]), sigmaH: num(v[at.sigma_h_m]), sigmaV: num(v[at.sigma_v_m]) };
  });
}
