// Reads a KITTI raw drive (extract layout) the way locaid's kitti/ module
// does: calib_*.txt "key: numbers" files (row-major matrices), timestamps as
// int64 ns since 1970 UTC (kitti/timestamps.cpp, exact: BigInt digits), OXTS
// records of 30 fields, and T_cam0_imu = R_rect_00 * T_cam0_velo * T_velo_imu
// with the rotation projected onto SO(3) (kitti/calib.cpp ComputeT_cam0_imu).
// The bag's /tf_static carries the raw (unrectified) camera frame, as ROS
// does: CameraInfo's R (= R_rect_00) turns it into the rectified one.
import fs from "node:fs";
import path from "node:path";

export const OXTS_FIELDS = [
  "lat", "lon", "alt", "roll", "pitch", "yaw", "vn", "ve", "vf", "vl", "vu", "ax", "ay", "az",
  "af", "al", "au", "wx", "wy", "wz", "wf", "wl", "wu", "posacc", "velacc", "navstat",
  "numsats", "posmode", "velmode", "orimode",
];

// "key: v1 v2 ..." lines -> {key: "v1 v2 ..."}.
export function readKeyValues(file) {
  const out = {};
  for (const line of fs.readFileSync(file, "utf8").split("\n")) {
    const i = line.indexOf(":");
    if (line.trim() && i > 0) out[line.slice(0, i).trim()] = line.slice(i + 1).trim();
  }
  return out;
}

function numbers(kv, key, count, file) {
  if (!(key in kv)) throw new Error(`${file}: missing key '${key}'`);
  const v = kv[key].split(/\s+/).map(Number);
  if (v.length !== count || v.some((x) => !Number.isFinite(x)))
    throw new Error(`${file}: key '${key}': expected ${count} finite numbers`);
  return v;
}

// 3x3 / 4x4 row-major matrices as arrays of rows.
const rows = (v, c) => Array.from({ length: v.length / c }, (_, r) => v.slice(r * c, r * c + c));
const matMul = (A, B) => A.map((r) => B[0].map((_, j) => r.reduce((s, a, k) => s + a * B[k][j], 0)));
const transpose = (A) => A[0].map((_, j) => A.map((r) => r[j]));

function rigid(R, t) {  // 4x4
  return [[...R[0], t[0]], [...R[1], t[1]], [...R[2], t[2]], [0, 0, 0, 1]];
}

function inverse3(M) {
  const [[a, b, c], [d, e, f], [g, h, i]] = M;
  const A = e * i - f * h, B = -(d * i - f * g), C = d * h - e * g;
  const det = a * A + b * B + c * C;
  return [
    [A / det, -(b * i - c * h) / det, (b * f - c * e) / det],
    [B / det, (a * i - c * g) / det, -(a * f - c * d) / det],
    [C / det, -(a * h - b * g) / det, (a * e - b * d) / det],
  ];
}

// Orthogonal polar factor (= U V^T of the SVD, what calib.cpp computes) by
// Newton iteration R <- (R + R^-T) / 2, to machine precision.
export function projectToRotation(M) {
  let R = M.map((r) => r.slice());
  for (let k = 0; k < 100; ++k) {
    const Rit = transpose(inverse3(R));
    const next = R.map((r, i) => r.map((x, j) => 0.5 * (x + Rit[i][j])));
    const diff = Math.max(...next.flat().map((x, i) => Math.abs(x - R.flat()[i])));
    R = next;
    if (diff < 1e-16) break;
  }
  return R;
}

// Quaternion {x, y, z, w} (w >= 0) of a 3x3 rotation (Shepperd's method).
export function quatFromMatrix(R) {
  const [[m00, m01, m02], [m10, m11, m12], [m20, m21, m22]] = R;
  const tr = m00 + m11 + m22;
  let q;
  if (tr > 0) {
    const s = Math.sqrt(tr + 1) * 2;
    q = { w: s / 4, x: (m21 - m12) / s, y: (m02 - m20) / s, z: (m10 - m01) / s };
  } else if (m00 > m11 && m00 > m22) {
    const s = Math.sqrt(1 + m00 - m11 - m22) * 2;
    q = { w: (m21 - m12) / s, x: s / 4, y: (m01 + m10) / s, z: (m02 + m20) / s };
  } else if (m11 > m22) {
    const s = Math.sqrt(1 + m11 - m00 - m22) * 2;
    q = { w: (m02 - m20) / s, x: (m01 + m10) / s, y: s / 4, z: (m12 + m21) / s };
  } else {
    const s = Math.sqrt(1 + m22 - m00 - m11) * 2;
    q = { w: (m10 - m01) / s, x: (m02 + m20) / s, y: (m12 + m21) / s, z: s / 4 };
  }
  const n = Math.hypot(q.x, q.y, q.z, q.w) * (q.w < 0 ? -1 : 1);
  return { x: q.x / n, y: q.y / n, z: q.z / n, w: q.w / n };
}

// OXTS attitude: Rz(yaw) * Ry(pitch) * Rx(roll) (kitti/oxts_pose.cpp), as a quaternion.
export function quatFromRollPitchYaw(roll, pitch, yaw) {
  const [cr, sr] = [Math.cos(roll / 2), Math.sin(roll / 2)];
  const [cp, sp] = [Math.cos(pitch / 2), Math.sin(pitch / 2)];
  const [cy, sy] = [Math.cos(yaw / 2), Math.sin(yaw / 2)];
  return {
    w: cy * cp * cr + sy * sp * sr,
    x: cy * cp * sr - sy * sp * cr,
    y: cy * sp * cr + sy * cp * sr,
    z: sy * cp * cr - cy * sp * sr,
  };
}

// Calibration of the drive's date folder: cameras 0 and 1, T_cam0_imu (to
// the rectified camera 0), T_imu_cam0 (the raw camera 0 in the IMU frame;
// 4x4 row arrays), baseline from the P matrices.
export function readCalib(dateDir) {
  const c2cFile = path.join(dateDir, "calib_cam_to_cam.txt");
  const c2c = readKeyValues(c2cFile);
  const cams = [0, 1].map((i) => {
    const s = `0${i}`;
    const n = (k, count) => numbers(c2c, `${k}_${s}`, count, c2cFile);
    return { S: n("S", 2), K: n("K", 9), D: n("D", 5), R_rect: n("R_rect", 9), P_rect: n("P_rect", 12) };
  });
  const rigidOf = (name) => {
    const file = path.join(dateDir, name);
    const kv = readKeyValues(file);
    return rigid(rows(numbers(kv, "R", 9, file), 3), numbers(kv, "T", 3, file));
  };
  const T_cam0_velo = rigidOf("calib_velo_to_cam.txt");
  const T_velo_imu = rigidOf("calib_imu_to_velo.txt");
  const T_rect0 = rigid(rows(cams[0].R_rect, 3), [0, 0, 0]);
  const inverse = (T) => {
    const R = projectToRotation(T.map((r) => r.slice(0, 3)).slice(0, 3));
    const t = [T[0][3], T[1][3], T[2][3]];
    const Rt = transpose(R);
    return { T: rigid(R, t), inv: rigid(Rt, Rt.map((r) => -(r[0] * t[0] + r[1] * t[1] + r[2] * t[2]))) };
  };
  const rectified = inverse(matMul(matMul(T_rect0, T_cam0_velo), T_velo_imu));
  const raw = inverse(matMul(T_cam0_velo, T_velo_imu));
  const T_cam0_imu = rectified.T;
  const T_imu_cam0 = raw.inv;  // the raw camera frame: what /tf_static holds
  const P1 = cams[1].P_rect;
  const baseline = P1[0] !== 0 ? -P1[3] / P1[0] : 0;
  return { cams, T_cam0_imu, T_imu_cam0, baseline };
}

const NS_PER_DAY = 86400n * 1000000000n;

function daysFromCivil(y, m, d) {  // H. Hinnant's algorithm, BigInt
  y -= m <= 2n ? 1n : 0n;
  const era = (y >= 0n ? y : y - 399n) / 400n;
  const yoe = y - era * 400n;
  const doy = (153n * (m + (m > 2n ? -3n : 9n)) + 2n) / 5n + d - 1n;
  const doe = yoe * 365n + yoe / 4n - yoe / 100n + doy;
  return era * 146097n + doe - 719468n;
}

// "2011-09-26 13:02:25.964389445" (UTC) -> BigInt ns since 1970.
export function parseTimestamp(line, where) {
  const m = /^(\d{4})-(\d{2})-(\d{2}) (\d{2}):(\d{2}):(\d{2})(?:\.(\d{1,9}))?$/.exec(line.trim());
  if (!m) throw new Error(`${where}: malformed timestamp '${line.trim()}'`);
  const [y, mo, d, h, mi, s] = m.slice(1, 7).map(BigInt);
  const frac = BigInt((m[7] ?? "0").padEnd(9, "0"));
  return daysFromCivil(y, mo, d) * NS_PER_DAY + ((h * 60n + mi) * 60n + s) * 1000000000n + frac;
}

// Line k = frame k; trailing blank lines allowed.
export function readTimestamps(file) {
  const lines = fs.readFileSync(file, "utf8").split("\n");
  while (lines.length && !lines.at(-1).trim()) lines.pop();
  return lines.map((l, i) => parseTimestamp(l, `${file}:${i + 1}`));
}

// Index of a KITTI data file name ("0000000017.png" -> 17), or -1.
function indexOf(name) {
  const m = /^(\d{1,10})\.\w+$/.exec(name);
  return m ? Number(m[1]) : -1;
}

function listIndexed(dir, ext) {
  if (!fs.existsSync(dir)) return new Map();
  const out = new Map();
  for (const f of fs.readdirSync(dir)) {
    if (f.endsWith(ext) && indexOf(f) >= 0) out.set(indexOf(f), path.join(dir, f));
  }
  return out;
}

// OXTS records sorted by time: {index, t_ns, f: {lat, lon, ...}}. Times from
// oxts/timestamps.txt when present; otherwise (extract copies without it) as
// locaid estimates them: t(image_00 frame 0) + 100 ms + index * 10 ms.
export function readOxts(driveDir, tImage0Ns) {
  const files = listIndexed(path.join(driveDir, "oxts", "data"), ".txt");
  const tsFile = path.join(driveDir, "oxts", "timestamps.txt");
  const ts = fs.existsSync(tsFile) ? readTimestamps(tsFile) : null;
  const out = [];
  for (const [index, file] of [...files].sort((a, b) => a[0] - b[0])) {
    const v = fs.readFileSync(file, "utf8").trim().split(/\s+/).map(Number);
    if (v.length !== 30 || v.some((x) => !Number.isFinite(x)))
      throw new Error(`${file}: expected 30 finite numbers`);
    let t;
    if (ts) {
      if (index >= ts.length) continue;  // no time for it
      t = ts[index];
    } else {
      t = tImage0Ns + 100000000n + BigInt(index) * 10000000n;
    }
    out.push({ index, t_ns: t, f: Object.fromEntries(OXTS_FIELDS.map((k, i) => [k, v[i]])) });
  }
  out.sort((a, b) => (a.t_ns < b.t_ns ? -1 : a.t_ns > b.t_ns ? 1 : 0));
  return { records: out, timesEstimated: !ts };
}

// The drive: image files and times per camera (0 = left, 1 = right).
export function readDrive(driveDir) {
  const cams = [0, 1].map((i) => {
    const dir = path.join(driveDir, `image_0${i}`);
    return { times: readTimestamps(path.join(dir, "timestamps.txt")),
             files: listIndexed(path.join(dir, "data"), ".png") };
  });
  return { cams, calib: readCalib(path.dirname(path.resolve(driveDir))) };
}
