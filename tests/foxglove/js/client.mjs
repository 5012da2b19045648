// Connects to locaid-foxglove with Foxglove's own WebSocket client
// (@foxglove/ws-protocol FoxgloveClient over the `ws` package), subscribes to
// every advertised channel, decodes what arrives and prints a summary as JSON,
// so the C++ tests check the bridge against a client they did not write.
//
//   node client.mjs --url ws://127.0.0.1:PORT --sessions K --updates N [--timeout-s S]
//
// It waits until serverInfo messages have named K sessions (a serverInfo
// without sessionId, sent before the bridge follows one, does not count) and
// the last of them has delivered N /locaid/update messages, then prints the
// summary and exits 0.
// On timeout it prints what it has and exits 3. JSON messages are parsed, their
// required fields (per schema name) checked, and foxglove.* messages validated
// with ajv against @foxglove/schemas' JSON Schemas; /locaid/update is decoded
// with protobufjs from the advertised FileDescriptorSet and its session_id
// compared with the session serverInfo named last. `values` lists, per
// message of /locaid/update, /locaid/pose, /locaid/fix and /locaid/status,
// the figures the C++ test compares with the gRPC stream of the session.
import { createRequire } from "node:module";

import WebSocket from "ws";

// The packages are CommonJS; require gives their full exports.
const require = createRequire(import.meta.url);
const { FoxgloveClient } = require("@foxglove/ws-protocol");
const protobuf = require("protobufjs");
require("protobufjs/ext/descriptor"); // adds Root.fromDescriptor
const Ajv = require("ajv");
const foxgloveJsonSchemas = require("@foxglove/schemas/jsonschema");

// Every foxglove.* message is validated against Foxglove's own published JSON
// Schema (@foxglove/schemas), not the one the bridge advertises.
const ajv = new Ajv({ allErrors: true, strict: false });
const validators = {};
function validatorFor(schemaName) {
  if (!schemaName.startsWith("foxglove.")) return null;
  if (!(schemaName in validators)) {
    const schema = foxgloveJsonSchemas[schemaName.slice("foxglove.".length)];
    validators[schemaName] = schema ? ajv.compile(schema) : null;
  }
  return validators[schemaName];
}

// Required fields of the JSON messages, by schema name.
const REQUIRED = {
  "foxglove.PoseInFrame": ["timestamp", "frame_id", "pose"],
  "foxglove.PosesInFrame": ["timestamp", "frame_id", "poses"],
  "foxglove.FrameTransforms": ["transforms"],
  "foxglove.LocationFix": ["timestamp", "frame_id", "latitude", "longitude", "altitude", "position_covariance",
    "position_covariance_type"],
  "locaid.Status": ["timestamp", "mode", "seconds_since_gps", "gps_outage_active", "horizontal_error_m", "gps_used",
    "gps_rejected", "gps_resets"],
};

// A foxglove time {sec, nsec} as nanoseconds, in a string (exact beyond 2^53).
const nanoseconds = (time) => String(BigInt(time.sec) * 1000000000n + BigInt(time.nsec));

function parseArgs(argv) {
  const args = { timeoutS: 60 };
  for (let i = 0; i < argv.length; i += 2) {
    const [key, value] = [argv[i], argv[i + 1]];
    if (key === "--url") args.url = value;
    else if (key === "--sessions") args.sessions = Number(value);
    else if (key === "--updates") args.updates = Number(value);
    else if (key === "--timeout-s") args.timeoutS = Number(value);
    else throw new Error(`unknown argument ${key}`);
  }
  if (!args.url || !(args.sessions >= 1) || !(args.updates >= 0)) {
    throw new Error("usage: node client.mjs --url URL --sessions K --updates N [--timeout-s S]");
  }
  return args;
}

function main() {
  const args = parseArgs(process.argv.slice(2));
  const result = {
    subprotocol: null,
    server_infos: [],
    channels: {},
    counts: {},
    counts_by_session: {},
    schema_validated: {},
    errors: [],
    update_session_mismatches: 0,
    last_update: null,
    last_status: null,
    last_path_poses: 0,
    first_tf: null,
    values: { update: [], pose: [], fix: [], status: [] },
  };
  const channels = new Map(); // channel id -> { topic, schemaName, decode }
  const subscriptions = new Map(); // subscription id -> channel id
  let session = null;

  const ws = new WebSocket(args.url, [FoxgloveClient.SUPPORTED_SUBPROTOCOL]);
  ws.on("open", () => { result.subprotocol = ws.protocol; }); // what the server selected
  const client = new FoxgloveClient({ ws });
  const finish = (code) => {
    console.log(JSON.stringify(result, null, 2));
    client.close();
    process.exit(code);
  };
  const timer = setTimeout(() => {
    result.errors.push(`timeout after ${args.timeoutS} s`);
    finish(3);
  }, args.timeoutS * 1000);

  const done = () => {
    const named = new Set(result.server_infos.filter((id) => id !== null));
    return named.size >= args.sessions && (result.counts_by_session[session]?.["/locaid/update"] ?? 0) >= args.updates;
  };

  client.on("error", (error) => result.errors.push(`client error: ${error?.message ?? error}`));
  client.on("close", () => {
    if (!done()) {
      result.errors.push("connection closed before the expected data arrived");
      clearTimeout(timer);
      finish(4);
    }
  });
  client.on("status", (status) => result.errors.push(`status from server: ${status.message}`));
  client.on("serverInfo", (info) => {
    session = info.sessionId ?? null;
    result.server_infos.push(session);
  });
  client.on("advertise", (advertised) => {
    for (const channel of advertised) {
      result.channels[channel.topic] = { schemaName: channel.schemaName, encoding: channel.encoding,
        schemaEncoding: channel.schemaEncoding ?? null };
      let decode;
      if (channel.encoding === "protobuf") {
        const root = protobuf.Root.fromDescriptor(Buffer.from(channel.schema, "base64"));
        const type = root.lookupType(channel.schemaName);
        decode = (bytes) => type.toObject(type.decode(bytes), { longs: String, defaults: true });
      } else {
        JSON.parse(channel.schema); // the JSON Schema must itself be JSON
        decode = (bytes) => JSON.parse(new TextDecoder().decode(bytes));
      }
      channels.set(channel.id, { topic: channel.topic, schemaName: channel.schemaName, encoding: channel.encoding,
        decode });
      subscriptions.set(client.subscribe(channel.id), channel.id);
    }
  });
  client.on("message", ({ subscriptionId, data }) => {
    const channel = channels.get(subscriptions.get(subscriptionId));
    if (!channel) {
      result.errors.push(`message for unknown subscription ${subscriptionId}`);
      return;
    }
    const bytes = new Uint8Array(data.buffer, data.byteOffset, data.byteLength);
    let message;
    try {
      message = channel.decode(bytes);
    } catch (error) {
      result.errors.push(`${channel.topic}: cannot decode: ${error.message}`);
      return;
    }
    for (const field of REQUIRED[channel.schemaName] ?? []) {
      if (!(field in message)) result.errors.push(`${channel.topic}: missing field ${field}`);
    }
    const validate = channel.encoding === "json" ? validatorFor(channel.schemaName) : null;
    if (validate) {
      result.schema_validated[channel.topic] = (result.schema_validated[channel.topic] ?? 0) + 1;
      if (!validate(message) && result.errors.length < 20)
        result.errors.push(`${channel.topic}: not a valid ${channel.schemaName}: ${ajv.errorsText(validate.errors)}`);
    }
    result.counts[channel.topic] = (result.counts[channel.topic] ?? 0) + 1;
    const bySession = (result.counts_by_session[session ?? ""] ??= {});
    bySession[channel.topic] = (bySession[channel.topic] ?? 0) + 1;
    if (channel.topic === "/locaid/update") {
      // Root.fromDescriptor keeps the .proto field names (session_id, t_ns).
      if (message.session_id !== session) result.update_session_mismatches += 1;
      result.last_update = { session_id: message.session_id, sequence: message.sequence, t_ns: message.t_ns,
        mode: message.mode };
      const p = message.position_enu_m ?? {};
      result.values.update.push({ sequence: message.sequence, t_ns: message.t_ns, x: p.x ?? 0, y: p.y ?? 0, z: p.z ?? 0,
        mode: message.mode });
    } else if (channel.topic === "/locaid/status") {
      result.last_status = message;
      result.values.status.push({ t_ns: nanoseconds(message.timestamp), sequence: message.sequence, mode: message.mode,
        gps_used: message.gps_used });
    } else if (channel.topic === "/locaid/pose") {
      const p = message.pose.position;
      result.values.pose.push({ t_ns: nanoseconds(message.timestamp), x: p.x, y: p.y, z: p.z });
    } else if (channel.topic === "/locaid/fix") {
      result.values.fix.push({ t_ns: nanoseconds(message.timestamp), latitude: message.latitude,
        longitude: message.longitude, altitude: message.altitude });
    } else if (channel.topic === "/locaid/path") {
      result.last_path_poses = message.poses.length;
    } else if (channel.topic === "/tf" && !result.first_tf) {
      result.first_tf = message;
    }
    if (done()) {
      clearTimeout(timer);
      finish(0);
    }
  });
}

try {
  main();
} catch (error) {
  console.error(`client.mjs: ${error.message}`);
  process.exit(1);
}
