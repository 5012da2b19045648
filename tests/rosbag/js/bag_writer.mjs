// Writes ROS 2 bags as rosbag2's MCAP storage plugin does, with @mcap/core's
// McapWriter: header profile "ros2", one "ros2msg" schema per type, one "cdr"
// channel per topic with the offered_qos_profiles metadata. One .mcap file,
// or (split) a rosbag2 directory: metadata.yaml + NAME_0.mcap, NAME_1.mcap...
// each a complete MCAP with its own schemas and channels.
import fs from "node:fs";
import path from "node:path";
import { McapWriter } from "@mcap/core";
import * as zstd from "@foxglove/wasm-zstd";
import lz4 from "lz4js";
import { schemaText, qosYaml } from "./ros2_schemas.mjs";

export const LIBRARY = "locaid tests/rosbag/js kitti_to_bag (@mcap/core 2.2.2)";

// IWritable over a file descriptor (synchronous writes, tracked position).
class FileWritable {
  constructor(file) {
    this.fd = fs.openSync(file, "w");
    this.pos = 0n;
  }
  async write(buffer) {
    fs.writeSync(this.fd, buffer);
    this.pos += BigInt(buffer.byteLength);
  }
  position() {
    return this.pos;
  }
  close() {
    fs.closeSync(this.fd);
  }
}

// Chunk compressor for McapWriter: "zstd" (standard zstd frames), "lz4" (LZ4
// frame format, as MCAP specifies) or "none".
export async function chunkCompressor(name) {
  if (name === "none") return undefined;
  if (name === "zstd") {
    await zstd.isLoaded;
    return (data) => ({ compression: "zstd", compressedData: zstd.compress(data, 3) });
  }
  if (name === "lz4") {
    return (data) => ({ compression: "lz4", compressedData: Uint8Array.from(lz4.compress(data)) });
  }
  throw new Error(`--compression: '${name}' is not zstd, lz4 or none`);
}

const yamlStr = (s) => JSON.stringify(s);  // a JSON string is a valid YAML double-quoted scalar

export class BagWriter {
  // out: file path (single) or directory (split > 0). topics: [{name, type,
  // transientLocal}]. layout: {useChunks, chunkSize, compress, summary}.
  constructor({ out, split = 0, topics, layout, msgNames = "short" }) {
    this.msgNames = msgNames;
    this.out = out;
    this.split = split;
    this.topics = topics;
    this.layout = layout;
    this.files = [];  // {path, count, first, last}
    this.counts = new Map(topics.map((t) => [t.name, 0]));
    this.writer = null;
  }

  async #openFile() {
    let file = this.out;
    if (this.split > 0) {
      fs.mkdirSync(this.out, { recursive: true });
      file = path.join(this.out, `${path.basename(this.out)}_${this.files.length}.mcap`);
    }
    const { useChunks, chunkSize, compress, summary } = this.layout;
    this.writable = new FileWritable(file);
    this.writer = new McapWriter({
      writable: this.writable,
      useChunks,
      chunkSize,
      compressChunk: compress,
      useStatistics: summary,
      useSummaryOffsets: summary,
      repeatSchemas: summary,
      repeatChannels: summary,
      useAttachmentIndex: summary,
      useMetadataIndex: summary,
      useMessageIndex: summary,
      useChunkIndex: summary,
    });
    await this.writer.start({ profile: "ros2", library: LIBRARY });
    const schemaIds = new Map();
    this.channelIds = new Map();
    for (const t of this.topics) {
      if (!schemaIds.has(t.type)) {
        schemaIds.set(t.type, await this.writer.registerSchema({
          name: t.type, encoding: "ros2msg", data: new TextEncoder().encode(schemaText(t.type, { msgNames: this.msgNames })),
        }));
      }
      this.channelIds.set(t.name, await this.writer.registerChannel({
        topic: t.name, schemaId: schemaIds.get(t.type), messageEncoding: "cdr",
        metadata: new Map([["offered_qos_profiles", qosYaml(t)]]),
      }));
    }
    this.sequence = new Map();
    this.files.push({ path: file, count: 0, first: null, last: null });
  }

  async #closeFile() {
    await this.writer.end();
    this.writable.close();
    this.writer = null;
  }

  // logTime, publishTime: BigInt ns. data: CDR bytes.
  async write(topic, logTime, publishTime, data) {
    if (!this.writer) await this.#openFile();
    let f = this.files.at(-1);
    if (this.split > 0 && f.count >= this.split) {
      await this.#closeFile();
      await this.#openFile();
      f = this.files.at(-1);
    }
    const channelId = this.channelIds.get(topic);
    if (channelId === undefined) throw new Error(`topic ${topic} not declared`);
    const sequence = this.sequence.get(topic) ?? 0;
    this.sequence.set(topic, sequence + 1);
    await this.writer.addMessage({ channelId, sequence, logTime, publishTime, data });
    f.count += 1;
    if (f.first === null || logTime < f.first) f.first = logTime;
    if (f.last === null || logTime > f.last) f.last = logTime;
    this.counts.set(topic, this.counts.get(topic) + 1);
  }

  // Ends the last file; a split bag also gets its metadata.yaml. Returns the paths written.
  async close() {
    if (!this.writer) await this.#openFile();  // an empty bag is still a valid file
    await this.#closeFile();
    const paths = this.files.map((f) => f.path);
    if (this.split > 0) {
      const meta = path.join(this.out, "metadata.yaml");
      fs.writeFileSync(meta, this.#metadataYaml());
      paths.push(meta);
    }
    return paths;
  }

  // rosbag2_bagfile_information (version 5, rosbag2 Humble's layout).
  #metadataYaml() {
    const times = this.files.filter((f) => f.count > 0);
    const start = times.length ? times.reduce((m, f) => (f.first < m ? f.first : m), times[0].first) : 0n;
    const end = times.length ? times.reduce((m, f) => (f.last > m ? f.last : m), times[0].last) : 0n;
    const total = this.files.reduce((s, f) => s + f.count, 0);
    let y = "rosbag2_bagfile_information:\n  version: 5\n  storage_identifier: mcap\n";
    y += `  duration:\n    nanoseconds: ${end - start}\n`;
    y += `  starting_time:\n    nanoseconds_since_epoch: ${start}\n`;
    y += `  message_count: ${total}\n  topics_with_message_count:\n`;
    for (const t of this.topics) {
      y += `    - topic_metadata:\n        name: ${t.name}\n        type: ${t.type}\n`;
      y += `        serialization_format: cdr\n`;
      y += `        offered_qos_profiles: ${yamlStr(qosYaml(t))}\n`;
      y += `      message_count: ${this.counts.get(t.name)}\n`;
    }
    y += `  compression_format: ""\n  compression_mode: ""\n  relative_file_paths:\n`;
    for (const f of this.files) y += `    - ${path.basename(f.path)}\n`;
    y += "  files:\n";
    for (const f of this.files) {
      y += `    - path: ${path.basename(f.path)}\n`;
      y += `      starting_time:\n        nanoseconds_since_epoch: ${f.first ?? 0n}\n`;
      y += `      duration:\n        nanoseconds: ${f.count ? f.last - f.first : 0n}\n`;
      y += `      message_count: ${f.count}\n`;
    }
    return y;
  }
}
