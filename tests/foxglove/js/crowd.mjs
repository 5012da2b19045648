// Many Foxglove clients on one bridge, one of them stalled: `--clients` - 1
// FoxgloveClient readers subscribe to every channel; one more subscribes to
// every channel and then stops reading its socket (ws pause()). When every
// reader has `--updates` /locaid/update messages, the stalled client reads
// again and the script waits for it to catch up with the newest update the
// readers saw. Prints a JSON summary:
//   { readers: [{updates, last_sequence, errors}], stalled: {updates,
//     last_sequence, statuses, caught_up}, newest_sequence, resumed }
//
//   node crowd.mjs --url ws://127.0.0.1:PORT --clients 20 --updates N [--timeout-s S]
//
// Exits 0 when every reader got its updates (the C++ test judges the rest),
// 3 on timeout (printing what it has). The timeout is a hang guard counted
// from the first update any client gets: the session's drive is rendered
// before that, and a render's length depends on the machine's load.
import { createRequire } from "node:module";

import WebSocket from "ws";

const require = createRequire(import.meta.url);
const { FoxgloveClient } = require("@foxglove/ws-protocol");
const protobuf = require("protobufjs");
require("protobufjs/ext/descriptor"); // adds Root.fromDescriptor

function parseArgs(argv) {
  const args = { timeoutS: 120 };
  for (let i = 0; i < argv.length; i += 2) {
    const [key, value] = [argv[i], argv[i + 1]];
    if (key === "--url") args.url = value;
    else if (key === "--clients") args.clients = Number(value);
    else if (key === "--updates") args.updates = Number(value);
    else if (key === "--timeout-s") args.timeoutS = Number(value);
    else throw new Error(`unknown argument ${key}`);
  }
  if (!args.url || !(args.clients >= 2) || !(args.updates >= 1)) {
    throw new Error("usage: node crowd.mjs --url URL --clients K (>= 2) --updates N [--timeout-s S]");
  }
  return args;
}

// One client subscribed to every channel, counting /locaid/update messages.
function connect(url, onUpdate) {
  const ws = new WebSocket(url, [FoxgloveClient.SUPPORTED_SUBPROTOCOL]);
  const client = new FoxgloveClient({ ws });
  const state = { ws, client, updates: 0, last_sequence: null, statuses: [], errors: [] };
  let updateType = null;
  const updateSubscriptions = new Set();
  client.on("error", (error) => state.errors.push(`client error: ${error?.message ?? error}`));
  client.on("status", (status) => state.statuses.push(status.message));
  client.on("advertise", (channels) => {
    for (const channel of channels) {
      const id = client.subscribe(channel.id);
      if (channel.topic !== "/locaid/update") continue;
      updateType = protobuf.Root.fromDescriptor(Buffer.from(channel.schema, "base64")).lookupType(channel.schemaName);
      updateSubscriptions.add(id);
    }
    state.onSubscribed?.();
  });
  client.on("message", ({ subscriptionId, data }) => {
    if (!updateSubscriptions.has(subscriptionId)) return;
    const message = updateType.decode(new Uint8Array(data.buffer, data.byteOffset, data.byteLength));
    state.updates += 1;
    state.last_sequence = Number(message.sequence);
    onUpdate(state);
  });
  return state;
}

function main() {
  const args = parseArgs(process.argv.slice(2));
  const summary = (s) => ({ updates: s.updates, last_sequence: s.last_sequence, errors: s.errors });
  const readers = [];
  let stalled = null;
  let newest = null;
  let resumed = false;

  const finish = (code) => {
    console.log(JSON.stringify({
      readers: readers.map(summary),
      stalled: stalled && { ...summary(stalled), statuses: stalled.statuses, caught_up: caughtUp() },
      newest_sequence: newest,
      resumed,
    }, null, 2));
    for (const s of [...readers, stalled]) s?.client.close();
    process.exit(code);
  };
  let timer = null;
  const armTimeout = () => {
    if (timer === null) timer = setTimeout(() => finish(3), args.timeoutS * 1000);
  };
  const caughtUp = () => stalled !== null && newest !== null && stalled.last_sequence === newest;

  const onReaderUpdate = (state) => {
    armTimeout();
    newest = Math.max(newest ?? 0, state.last_sequence);
    if (resumed || !readers.every((r) => r.updates >= args.updates)) return;
    // Every reader is served: now the stalled client reads what is left for it.
    resumed = true;
    stalled.ws.resume();
    if (caughtUp()) {
      clearTimeout(timer);
      finish(0);
    }
  };
  for (let i = 0; i < args.clients - 1; i += 1) readers.push(connect(args.url, onReaderUpdate));
  stalled = connect(args.url, () => {
    armTimeout();
    if (resumed && caughtUp()) {
      clearTimeout(timer);
      finish(0);
    }
  });
  // Stop reading right after subscribing: the bridge's queue for this client
  // fills while the others keep receiving.
  stalled.onSubscribed = () => stalled.ws.pause();
}

try {
  main();
} catch (error) {
  console.error(`crowd.mjs: ${error.message}`);
  process.exit(1);
}
