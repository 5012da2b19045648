#!/usr/bin/env node
// Reads a ROS 2 bag (one .mcap file, or a rosbag2 folder of them with its
// metadata.yaml) with the official readers and decodes every message with
// @foxglove/rosmsg2-serialization's MessageReader, built from the ros2msg
// schema stored in the file. Prints JSON: per file its layout, per topic
// {type, count, first/last stamp ns, first/last log time ns}, one decoded
// sample per topic.
//
//   node inspect_bag.mjs [--check] [--samples N] PATH
//
// Every file is read with McapStreamReader (a file cut mid-write, as by a
// killed recorder, reads up to the cut: "truncated": true); a complete file
// with a summary is also read with McapIndexedReader, which must find the
// same messages (when chunked: it reads through chunk indexes) and statistics.
// --check: exit 1 (reasons on stderr) when a message does not
// decode (or leaves > 3 bytes unread), a schema is not ros2msg / cdr, the
// profile is not "ros2", header.stamp goes backwards on a topic, a
// covariance (field name contains "covariance", 9 or 36 numbers) is not
// symmetric positive semi-definite (cov[0] = -1, "no estimate", is
// accepted), the readers disagree, or metadata.yaml's counts differ.
import fs from "node:fs";
import path from "node:path";
import { parseArgs } from "node:util";
import { McapIndexedReader, McapStreamReader } from "@mcap/core";
import { loadDecompressHandlers } from "@mcap/support";
import { parse as parseMsg } from "@foxglove/rosmsg";
import { MessageReader } from "@foxglove/rosmsg2-serialization";
import { covarianceProblem, forEachCovariance, shortForm, stampNs } from "./bag_checks.mjs";

const PIECE = 4 << 20;  // bytes appended to the stream reader at a time
const MAX_ERRORS = 50;

// The .mcap files of PATH, and the parsed counts of its metadata.yaml.
function bagFiles(p) {
  if (!fs.statSync(p).isDirectory()) return { files: [p], meta: null };
  const metaFile = path.join(p, "metadata.yaml");
  if (!fs.existsSync(metaFile)) {
    const files = fs.readdirSync(p).filter((f) => f.endsWith(".mcap"))
      .sort((a, b) => a.localeCompare(b, "en", { numeric: true }));
    return { files: files.map((f) => path.join(p, f)), meta: null };
  }
  const text = fs.readFileSync(metaFile, "utf8");
  const list = /relative_file_paths:\n((?:\s+- .*\n?)+)/.exec(text);
  const files = list ? [...list[1].matchAll(/- (.+)/g)].map((m) => path.join(p, m[1].trim())) : [];
  const total = /^ {2}message_count: (\d+)/m.exec(text);
  const topics = {};
  for (const m of text.matchAll(/name: (\S+)\n[\s\S]*?\n {6}message_count: (\d+)/g)) topics[m[1]] = Number(m[2]);
  return { files, meta: { message_count: total ? Number(total[1]) : null, topics } };
}

// IReadable over a file for McapIndexedReader.
function fileReadable(file) {
  const fd = fs.openSync(file, "r");
  return {
    fd,
    size: async () => BigInt(fs.fstatSync(fd).size),
    read: async (offset, size) => {
      const buf = new Uint8Array(Number(size));
      fs.readSync(fd, buf, 0, buf.length, Number(offset));
      return buf;
    },
  };
}

// rosbag2 writes "MSG: pkg/Type"; its docs show "MSG: pkg/msg/Type", which
// @foxglove/rosmsg does not match with the field types: take both.
const normalizeSchema = (text) => text.replace(/^MSG: ([^/\s]+)\/msg\/(\S+)/gm, "MSG: $1/$2");

class Inspector {
  constructor(nSamples) {
    this.nSamples = nSamples;
    this.topics = {};
    this.samples = {};
    this.errors = [];
  }

  error(msg) {
    if (this.errors.length < MAX_ERRORS) this.errors.push(msg);
    else if (this.errors.length === MAX_ERRORS) this.errors.push("... (more errors not shown)");
  }

  decoderFor(channel, schema) {
    const where = `topic ${channel.topic}`;
    if (!schema) return this.error(`${where}: channel without schema`);
    if (schema.encoding !== "ros2msg" || channel.messageEncoding !== "cdr")
      return this.error(`${where}: schema encoding '${schema.encoding}', message encoding '${channel.messageEncoding}' (expected ros2msg / cdr)`);
    try {
      return new MessageReader(parseMsg(normalizeSchema(new TextDecoder().decode(schema.data)), { ros2: true }));
    } catch (e) {
      return this.error(`${where}: schema ${schema.name} does not parse: ${e.message}`);
    }
  }

  message(channel, schema, reader, m) {
    const t = (this.topics[channel.topic] ??= {
      type: schema?.name ?? null, count: 0, decoded: 0, first_stamp_ns: null, last_stamp_ns: null,
      first_log_time_ns: null, last_log_time_ns: null,
    });
    t.count += 1;
    if (t.first_log_time_ns === null || m.logTime < BigInt(t.first_log_time_ns)) t.first_log_time_ns = m.logTime.toString();
    if (t.last_log_time_ns === null || m.logTime > BigInt(t.last_log_time_ns)) t.last_log_time_ns = m.logTime.toString();
    if (!reader) return;
    const where = `topic ${channel.topic} message ${t.count} (log time ${m.logTime})`;
    let msg;
    try {
      msg = reader.readMessage(m.data);
    } catch (e) {
      return this.error(`${where}: does not decode as ${schema.name}: ${e.message}`);
    }
    const extra = m.data.byteLength - reader.lastReadByteLength();
    if (extra > 3) return this.error(`${where}: ${extra} bytes left after decoding as ${schema.name}`);
    t.decoded += 1;
    const s = stampNs(msg);
    if (s !== null) {
      if (t.last_stamp_ns !== null && s < BigInt(t.last_stamp_ns))
        this.error(`${where}: header.stamp ${s} goes backwards (previous ${t.last_stamp_ns})`);
      if (t.first_stamp_ns === null) t.first_stamp_ns = s.toString();
      t.last_stamp_ns = s.toString();
    }
    forEachCovariance(msg, (p, cov) => {
      const why = covarianceProblem(cov);
      if (why) this.error(`${where}: ${p} ${why}`);
    });
    const samples = (this.samples[channel.topic] ??= []);
    if (samples.length < this.nSamples) samples.push(shortForm(msg));
  }

  // Stream-reads one file; returns its description.
  readFile(file, decompressHandlers) {
    const reader = new McapStreamReader({ includeChunks: true, decompressHandlers, validateCrcs: true });
    const info = { path: file, bytes: fs.statSync(file).size, profile: null, library: null, chunks: 0,
                   chunk_compression: [], messages: 0, schemas: 0, channels: 0, summary: false,
                   complete: false, truncated: false };
    const schemas = new Map(), channels = new Map(), decoders = new Map();
    const fd = fs.openSync(file, "r");
    const buf = new Uint8Array(PIECE);
    let footer = null;
    try {
      for (let n; (n = fs.readSync(fd, buf, 0, PIECE)) > 0;) {
        reader.append(buf.subarray(0, n));
        for (let r; (r = reader.nextRecord());) {
          if (r.type === "Header") Object.assign(info, { profile: r.profile, library: r.library });
          else if (r.type === "Schema") schemas.set(r.id, r);
          else if (r.type === "Channel" && !channels.has(r.id)) {
            channels.set(r.id, r);
            decoders.set(r.id, this.decoderFor(r, schemas.get(r.schemaId)));
          } else if (r.type === "Chunk") {
            info.chunks += 1;
            if (!info.chunk_compression.includes(r.compression)) info.chunk_compression.push(r.compression);
          } else if (r.type === "Message") {
            const ch = channels.get(r.channelId);
            if (!ch) this.error(`${file}: message on unknown channel ${r.channelId}`);
            else this.message(ch, schemas.get(ch.schemaId), decoders.get(r.channelId), r);
            info.messages += 1;
          } else if (r.type === "Footer") footer = r;
        }
      }
    } catch (e) {
      this.error(`${file}: stream reader: ${e.message}`);
    } finally {
      fs.closeSync(fd);
    }
    Object.assign(info, { schemas: schemas.size, channels: channels.size, complete: reader.done(),
                          truncated: !reader.done(), summary: footer !== null && footer.summaryStart !== 0n });
    return info;
  }
}

// A complete file with a summary: McapIndexedReader must find the same messages.
async function indexedCount(file, decompressHandlers) {
  const readable = fileReadable(file);
  try {
    const reader = await McapIndexedReader.Initialize({ readable, decompressHandlers });
    let n = 0;
    for await (const _ of reader.readMessages()) n += 1;
    const stats = reader.statistics ? Number(reader.statistics.messageCount) : null;
    return { messages: n, statistics_message_count: stats, chunk_indexes: reader.chunkIndexes.length };
  } finally {
    fs.closeSync(readable.fd);
  }
}

async function main() {
  const { values, positionals } = parseArgs({
    allowPositionals: true,
    options: { check: { type: "boolean" }, samples: { type: "string", default: "1" } },
  });
  if (positionals.length !== 1) {
    console.error("usage: node inspect_bag.mjs [--check] [--samples N] PATH (an .mcap file or a rosbag2 folder)");
    process.exit(2);
  }
  const { files, meta } = bagFiles(positionals[0]);
  const decompressHandlers = await loadDecompressHandlers();
  const ins = new Inspector(Number(values.samples));
  const fileInfos = [];
  if (files.length === 0) ins.error(`${positionals[0]}: no .mcap file`);
  for (const file of files) {
    if (!fs.existsSync(file)) {
      ins.error(`${file}: listed in metadata.yaml but absent`);
      continue;
    }
    const info = ins.readFile(file, decompressHandlers);
    if (info.profile !== "ros2") ins.error(`${file}: header profile '${info.profile}', expected 'ros2'`);
    if (info.complete && info.summary) {
      try {
        info.indexed = await indexedCount(file, decompressHandlers);
        // McapIndexedReader reads messages through chunk indexes: none in a file without chunks.
        if (info.chunks > 0 && info.indexed.messages !== info.messages)
          ins.error(`${file}: indexed reader read ${info.indexed.messages} messages, stream reader ${info.messages}`);
        if (info.indexed.statistics_message_count !== null && info.indexed.statistics_message_count !== info.messages)
          ins.error(`${file}: statistics say ${info.indexed.statistics_message_count} messages, read ${info.messages}`);
      } catch (e) {
        ins.error(`${file}: indexed reader: ${e.message}`);
      }
    }
    fileInfos.push(info);
  }
  const total = fileInfos.reduce((s, f) => s + f.messages, 0);
  if (meta && !fileInfos.some((f) => f.truncated)) {
    if (meta.message_count !== total) ins.error(`metadata.yaml: message_count ${meta.message_count}, read ${total}`);
    for (const [topic, n] of Object.entries(meta.topics)) {
      const got = ins.topics[topic]?.count ?? 0;
      if (got !== n) ins.error(`metadata.yaml: ${topic} message_count ${n}, read ${got}`);
    }
  }
  const out = {
    path: positionals[0], files: fileInfos, truncated: fileInfos.some((f) => f.truncated),
    message_count: total, topics: ins.topics, samples: ins.samples, errors: ins.errors,
  };
  console.log(JSON.stringify(out, null, 1));
  if (values.check && ins.errors.length) {
    console.error(`inspect_bag --check: ${positionals[0]}: ${ins.errors.length} problem(s):\n  ${ins.errors.join("\n  ")}`);
    process.exit(1);
  }
}

main().catch((e) => {
  console.error(`inspect_bag: ${e.stack ?? e.message}`);
  process.exit(1);
});
