// Reads a ROS 2 bag in MCAP form the way ROS 2 tools do, with the field's
// own TypeScript libraries only: @mcap/core's indexed reader (chunks
// decompressed by @mcap/support), each Schema's ros2msg text parsed by
// @foxglove/rosmsg (ros2 mode) and every message decoded from CDR by
// @foxglove/rosmsg2-serialization's MessageReader. Then checks what a ROS
// user relies on and prints a JSON summary.
//
//   node read_ros2_bag.mjs FILE              summary: counts per topic, the
//                                            first decoded message per topic
//   node read_ros2_bag.mjs --messages FILE   also every decoded message,
//                                            by topic
//
// Checks (any failure: the reasons on stderr, exit 1):
//  - header profile "ros2"; every schema encoding "ros2msg", every channel
//    "cdr" with offered_qos_profiles metadata (reliable; /tf_static
//    transient_local, every other topic volatile);
//  - every message decodes with no bytes left over;
//  - header stamps non-decreasing per topic, and each message's log time is
//    its header stamp;
//  - every covariance (Odometry pose and twist, NavSatFix position) is
//    symmetric and positive semi-definite (Cholesky of C + tol I);
//  - /locaid/odometry: frame_id map, child_frame_id base_link, unit
//    quaternions; /locaid/fix: covariance type KNOWN (3);
//  - /tf and /tf_static form the chain map -> base_link -> camera_left, each
//    frame with one parent;
//  - /locaid/status: a DiagnosticStatus named "locaid" with a level 0..3.
import { McapIndexedReader } from "@mcap/core";
import { FileHandleReadable } from "@mcap/nodejs";
import { loadDecompressHandlers } from "@mcap/support";
import { parse } from "@foxglove/rosmsg";
import { MessageReader } from "@foxglove/rosmsg2-serialization";
import { open } from "node:fs/promises";

const SYMMETRY_TOLERANCE = 1e-9; // relative to the largest |entry|
const PSD_TOLERANCE = 1e-9; // C + tol * max(1, max diag) * I must factor
const MAX_FAILURES = 20;

const failures = [];
function fail(message) {
  if (failures.length < MAX_FAILURES) failures.push(message);
}

function stampNs(stamp) {
  return BigInt(stamp.sec) * 1_000_000_000n + BigInt(stamp.nanosec);
}

// n x n row-major `values`: symmetric, and Cholesky succeeds on C + tol I.
function checkCovariance(where, values, n) {
  if (values.length !== n * n) return fail(`${where}: ${values.length} covariance values, expected ${n * n}`);
  const c = (i, j) => values[i * n + j];
  let largest = 0;
  for (const v of values) {
    if (!Number.isFinite(v)) return fail(`${where}: covariance has a non-finite value`);
    largest = Math.max(largest, Math.abs(v));
  }
  for (let i = 0; i < n; ++i) {
    for (let j = 0; j < i; ++j) {
      if (Math.abs(c(i, j) - c(j, i)) > SYMMETRY_TOLERANCE * Math.max(1, largest)) {
        return fail(`${where}: covariance not symmetric at (${i},${j}): ${c(i, j)} vs ${c(j, i)}`);
      }
    }
  }
  let maxDiag = 1;
  for (let i = 0; i < n; ++i) maxDiag = Math.max(maxDiag, Math.abs(c(i, i)));
  const tol = PSD_TOLERANCE * maxDiag;
  const L = Array.from({ length: n }, () => new Array(n).fill(0));
  for (let i = 0; i < n; ++i) {
    for (let j = 0; j <= i; ++j) {
      let sum = c(i, j) + (i === j ? tol : 0);
      for (let k = 0; k < j; ++k) sum -= L[i][k] * L[j][k];
      if (i === j) {
        if (!(sum > 0)) return fail(`${where}: covariance not positive semi-definite (pivot ${i}: ${sum})`);
        L[i][i] = Math.sqrt(sum);
      } else {
        L[i][j] = sum / L[j][j];
      }
    }
  }
}

function checkQos(channel) {
  const qos = channel.metadata.get("offered_qos_profiles");
  if (qos === undefined) return fail(`${channel.topic}: no offered_qos_profiles metadata`);
  const value = (key) => (qos.match(new RegExp(`^\\s*-?\\s*${key}: (\\S+)$`, "m")) ?? [])[1];
  const reliable = ["1", "reliable"].includes(value("reliability"));
  const wantDurability = channel.topic === "/tf_static" ? ["1", "transient_local"] : ["2", "volatile"];
  if (!reliable) fail(`${channel.topic}: QoS reliability ${value("reliability")}, expected reliable`);
  if (!wantDurability.includes(value("durability"))) {
    fail(`${channel.topic}: QoS durability ${value("durability")}, expected ${wantDurability.join(" or ")}`);
  }
  return qos;
}

// Topic-specific checks of one decoded message.
function checkMessage(topic, type, msg, stamp, tf) {
  const where = `${topic} ${stamp}`;
  if (type === "nav_msgs/msg/Odometry") {
    if (msg.header.frame_id !== "map") fail(`${where}: frame_id '${msg.header.frame_id}', expected map`);
    if (msg.child_frame_id !== "base_link") fail(`${where}: child_frame_id '${msg.child_frame_id}', expected base_link`);
    const q = msg.pose.pose.orientation;
    if (Math.abs(Math.hypot(q.x, q.y, q.z, q.w) - 1) > 1e-9) fail(`${where}: orientation is not a unit quaternion`);
    checkCovariance(`${where} pose`, msg.pose.covariance, 6);
    checkCovariance(`${where} twist`, msg.twist.covariance, 6);
  } else if (type === "sensor_msgs/msg/NavSatFix") {
    checkCovariance(where, msg.position_covariance, 3);
    if (topic === "/locaid/fix" && msg.position_covariance_type !== 3) {
      fail(`${where}: position_covariance_type ${msg.position_covariance_type}, expected 3 (KNOWN)`);
    }
    if (!Number.isFinite(msg.latitude) || !Number.isFinite(msg.longitude)) fail(`${where}: latitude/longitude not finite`);
  } else if (type === "tf2_msgs/msg/TFMessage") {
    for (const t of msg.transforms) {
      const parent = tf.get(t.child_frame_id);
      if (parent !== undefined && parent !== t.header.frame_id) {
        fail(`${where}: ${t.child_frame_id} has two parents, ${parent} and ${t.header.frame_id}`);
      }
      tf.set(t.child_frame_id, t.header.frame_id);
    }
  } else if (type === "diagnostic_msgs/msg/DiagnosticArray") {
    const status = msg.status.find((s) => s.name === "locaid");
    if (!status) fail(`${where}: no DiagnosticStatus named locaid`);
    else if (!(status.level >= 0 && status.level <= 3)) fail(`${where}: level ${status.level}`);
  }
}

async function main(args) {
  const all = args[0] === "--messages";
  const path = all ? args[1] : args[0];
  if (!path) throw new Error("usage: node read_ros2_bag.mjs [--messages] FILE");
  const handle = await open(path, "r");
  try {
    const reader = await McapIndexedReader.Initialize({
      readable: new FileHandleReadable(handle),
      decompressHandlers: await loadDecompressHandlers(),
    });
    if (reader.header.profile !== "ros2") fail(`header profile '${reader.header.profile}', expected ros2`);
    const readers = new Map(); // schema id -> MessageReader
    for (const [id, schema] of reader.schemasById) {
      if (schema.encoding !== "ros2msg") fail(`schema ${schema.name}: encoding ${schema.encoding}, expected ros2msg`);
      const definitions = parse(new TextDecoder().decode(schema.data), { ros2: true });
      readers.set(id, new MessageReader(definitions));
    }
    const topics = {};
    for (const channel of reader.channelsById.values()) {
      if (channel.messageEncoding !== "cdr") fail(`${channel.topic}: message encoding ${channel.messageEncoding}, expected cdr`);
      topics[channel.topic] = {
        type: reader.schemasById.get(channel.schemaId)?.name,
        count: 0,
        qos: checkQos(channel),
        first: undefined,
        ...(all ? { messages: [] } : {}),
      };
    }
    const lastStamp = new Map();
    const tf = new Map(); // child frame -> parent frame
    for await (const message of reader.readMessages()) {
      const channel = reader.channelsById.get(message.channelId);
      const topic = topics[channel.topic];
      const messageReader = readers.get(channel.schemaId);
      let msg;
      try {
        msg = messageReader.readMessage(message.data);
      } catch (error) {
        fail(`${channel.topic}: message ${topic.count} does not decode: ${error.message}`);
        continue;
      }
      if (messageReader.lastReadHadTrailingBytes()) fail(`${channel.topic}: message ${topic.count} has trailing bytes`);
      topic.count += 1;
      topic.first ??= msg;
      if (all) topic.messages.push(msg);
      const stamp = msg.header ? stampNs(msg.header.stamp) : stampNs(msg.transforms[0].header.stamp);
      if (stamp < (lastStamp.get(channel.topic) ?? 0n)) fail(`${channel.topic}: stamp ${stamp} before the previous one`);
      lastStamp.set(channel.topic, stamp);
      if (message.logTime !== stamp) fail(`${channel.topic}: log time ${message.logTime} is not the stamp ${stamp}`);
      checkMessage(channel.topic, topic.type, msg, stamp, tf);
    }
    if (tf.get("base_link") !== "map") fail("/tf: no transform map -> base_link");
    if (tf.get("camera_left") !== "base_link") fail("/tf_static: no transform base_link -> camera_left");
    const summary = { profile: reader.header.profile, library: reader.header.library, topics,
      tf_parents: Object.fromEntries(tf) };
    if (failures.length > 0) {
      throw new Error(`${path} fails ${failures.length} check(s):\n  ${failures.join("\n  ")}`);
    }
    // int64 as strings; fixed-size arrays (float64[36]) decode to typed arrays.
    const plain = (k, v) => (typeof v === "bigint" ? v.toString() : ArrayBuffer.isView(v) ? Array.from(v) : v);
    console.log(JSON.stringify(summary, plain, 2));
  } finally {
    await handle.close();
  }
}

main(process.argv.slice(2)).catch((error) => {
  console.error(`read_ros2_bag: ${error.message}`);
  process.exit(1);
});
