// One Foxglove WebSocket client for bench/foxglove/bridge_latency.sh: subscribes
// to /locaid/update, decodes each PoseUpdate (protobufjs, from the advertised
// descriptor set) and records receipt time minus PoseUpdate.published_unix_ns
// (the server's hand-over to its gRPC subscribers; same machine clock). Prints
// {"delays_ms": [...]} when `--count` updates arrived or at `--timeout-s`.
import { createRequire } from "node:module";
import path from "node:path";
import { fileURLToPath } from "node:url";

const here = path.dirname(fileURLToPath(import.meta.url));
// The packages pinned for the tests (tests/foxglove/js, installed by its setup.sh).
const require = createRequire(path.join(here, "../../tests/foxglove/js/package.json"));
const { FoxgloveClient } = require("@foxglove/ws-protocol");
const WebSocket = require("ws");
const protobuf = require("protobufjs");
require("protobufjs/ext/descriptor");

const args = Object.fromEntries(process.argv.slice(2).reduce((a, v, i, all) => (i % 2 ? a : [...a, [v.slice(2), all[i + 1]]]), []));
const count = Number(args.count ?? 300), timeoutS = Number(args["timeout-s"] ?? 120);
const delays = [];
const client = new FoxgloveClient({ ws: new WebSocket(args.url, [FoxgloveClient.SUPPORTED_SUBPROTOCOL]) });
let type, updateChannel;
const done = () => {
  console.log(JSON.stringify({ delays_ms: delays }));
  client.close();
  process.exit(0);
};
setTimeout(done, timeoutS * 1000);
client.on("advertise", (channels) => {
  for (const c of channels) {
    if (c.topic !== "/locaid/update") continue;
    type = protobuf.Root.fromDescriptor(Buffer.from(c.schema, "base64")).lookupType(c.schemaName);
    updateChannel = client.subscribe(c.id);
  }
});
client.on("message", ({ subscriptionId, data }) => {
  if (subscriptionId !== updateChannel) return;
  const nowNs = BigInt(Math.round((performance.timeOrigin + performance.now()) * 1e6));  // wall clock, ~us
  const msg = type.toObject(type.decode(new Uint8Array(data.buffer, data.byteOffset, data.byteLength)), { longs: String });
  delays.push(Number(nowNs - BigInt(msg.published_unix_ns)) / 1e6);
  if (delays.length >= count) done();
});
