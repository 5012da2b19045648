// Reads an MCAP file with Foxglove's own TypeScript reader (@mcap/core, its
// chunk decompression from @mcap/support) and prints what it found as JSON,
// so the C++ tests can check locaid's writer against a reader they did not
// write. Every message is also decoded by its channel's schema: protobuf
// with the FileDescriptorSet stored in the file (@mcap/support's
// protobufFromBinaryDescriptor), JSON with JSON.parse.
//
//   node read_mcap.mjs FILE           indexed reader (footer, summary, chunk
//                                     indexes) and stream reader; both must
//                                     read the whole file and agree
//   node read_mcap.mjs --stream FILE  stream reader only; a file that ends
//                                     before its footer (a killed recorder)
//                                     is reported as "truncated", not an error
//
// Exits 1 with the error on stderr when a reader rejects the file.
import { open } from "node:fs/promises";

import { McapIndexedReader, McapStreamReader } from "@mcap/core";
import { FileHandleReadable } from "@mcap/nodejs";
import { loadDecompressHandlers, protobufFromBinaryDescriptor } from "@mcap/support";

// Small pieces make the stream reader resume mid-record, as it would on a pipe.
const STREAM_PIECE_BYTES = 64 * 1024;

// A decoder per schema (by schema id), built from the schema record itself.
function decoderFor(schema) {
  if (schema.encoding === "protobuf") {
    const type = protobufFromBinaryDescriptor(schema.data).lookupType(schema.name);
    return (data) => type.toObject(type.decode(data), { longs: String });
  }
  if (schema.encoding === "jsonschema") {
    JSON.parse(new TextDecoder().decode(schema.data)); // the schema itself must be JSON
    return (data) => JSON.parse(new TextDecoder().decode(data));
  }
  throw new Error(`schema ${schema.name}: unexpected encoding ${schema.encoding}`);
}

// Per topic: messages seen, how many decoded by their schema, and whether
// each channel's sequence numbers ran 0, 1, 2, ... with no gap (the tests
// number their messages that way).
class MessageTally {
  constructor() {
    this.topics = {};
    this.start = undefined;
    this.end = undefined;
    this.decode_errors = [];
  }

  add(topic, message, decode) {
    const t = (this.topics[topic] ??= { count: 0, decoded: 0, sequences_in_order: true });
    if (message.sequence !== t.count) t.sequences_in_order = false;
    t.count += 1;
    if (decode) {
      try {
        decode(message.data);
        t.decoded += 1;
      } catch (error) {
        if (this.decode_errors.length < 10) this.decode_errors.push(`${topic}: ${error.message}`);
      }
    }
    if (this.start === undefined || message.logTime < this.start) this.start = message.logTime;
    if (this.end === undefined || message.logTime > this.end) this.end = message.logTime;
  }

  toJSON() {
    const total = Object.values(this.topics).reduce((sum, t) => sum + t.count, 0);
    return { message_count: total, topics: this.topics, start_time: String(this.start ?? 0n), end_time: String(this.end ?? 0n),
      decode_errors: this.decode_errors };
  }
}

async function readIndexed(path, handlers) {
  const handle = await open(path, "r");
  try {
    const reader = await McapIndexedReader.Initialize({ readable: new FileHandleReadable(handle), decompressHandlers: handlers });
    const tally = new MessageTally();
    const decoders = new Map();
    for (const [id, schema] of reader.schemasById) decoders.set(id, decoderFor(schema));
    for await (const message of reader.readMessages()) {
      const channel = reader.channelsById.get(message.channelId);
      tally.add(channel.topic, message, decoders.get(channel.schemaId));
    }
    const stats = reader.statistics;
    return {
      ...tally.toJSON(),
      schemas: [...reader.schemasById.values()].map((s) => s.name).sort(),
      chunk_count: reader.chunkIndexes.length,
      statistics: stats && {
        message_count: String(stats.messageCount),
        schema_count: stats.schemaCount,
        channel_count: stats.channelCount,
        chunk_count: stats.chunkCount,
        start_time: String(stats.messageStartTime),
        end_time: String(stats.messageEndTime),
      },
      summary_offset_opcodes: [...reader.summaryOffsetsByOpcode.keys()].sort((a, b) => a - b),
    };
  } finally {
    await handle.close();
  }
}

async function readStream(path, handlers) {
  const reader = new McapStreamReader({ includeChunks: true, decompressHandlers: handlers, validateCrcs: true });
  const channels = new Map();
  const schemas = new Set();
  const decoders = new Map();
  const tally = new MessageTally();
  let chunkCount = 0;
  let sawDataEnd = false;
  const handle = await open(path, "r");
  try {
    const piece = Buffer.alloc(STREAM_PIECE_BYTES);
    for (;;) {
      const { bytesRead } = await handle.read(piece, 0, piece.length, null);
      if (bytesRead === 0) break;
      reader.append(piece.subarray(0, bytesRead));
      for (let record; (record = reader.nextRecord()); ) {
        if (record.type === "Chunk") chunkCount += 1;
        else if (record.type === "Schema") {
          schemas.add(record.name);
          decoders.set(record.id, decoderFor(record));
        }
        else if (record.type === "Channel") channels.set(record.id, record);
        else if (record.type === "DataEnd") sawDataEnd = true;
        else if (record.type === "Message") {
          const channel = channels.get(record.channelId);
          if (!channel) throw new Error(`message on channel ${record.channelId} before its Channel record`);
          tally.add(channel.topic, record, decoders.get(channel.schemaId));
        }
      }
    }
  } finally {
    await handle.close();
  }
  return {
    ...tally.toJSON(),
    schemas: [...schemas].sort(),
    chunk_count: chunkCount,
    complete: reader.done(),
    data_end_seen: sawDataEnd,
    bytes_left_unread: reader.bytesRemaining(),
  };
}

// Per-topic figures compared by topic name: the indexed reader meets topics
// in log-time order, the stream reader in file order.
function sameCounts(a, b) {
  const canonical = (topics) => JSON.stringify(Object.keys(topics).sort().map((t) => [t, topics[t]]));
  return canonical(a.topics) === canonical(b.topics) && a.chunk_count === b.chunk_count;
}

async function main(args) {
  const streamOnly = args[0] === "--stream";
  const path = streamOnly ? args[1] : args[0];
  if (!path) throw new Error("usage: node read_mcap.mjs [--stream] FILE");
  const handlers = await loadDecompressHandlers();

  const stream = await readStream(path, handlers);
  if (streamOnly) {
    console.log(JSON.stringify({ mode: "stream", truncated: !stream.complete, stream }, null, 2));
    return;
  }
  if (!stream.complete) throw new Error(`stream reader: file ends before its footer (${stream.bytes_left_unread} bytes unread)`);
  const indexed = await readIndexed(path, handlers);
  if (!sameCounts(indexed, stream)) throw new Error("indexed and stream readers disagree on messages or chunks");
  console.log(JSON.stringify({ mode: "full", indexed, stream }, null, 2));
}

main(process.argv.slice(2)).catch((error) => {
  console.error(`read_mcap: ${error.message}`);
  process.exit(1);
});
