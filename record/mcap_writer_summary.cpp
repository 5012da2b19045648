// McapWriter's end of file: Data End, the summary (Schema, Channel, Chunk
// Index and Statistics groups), one Summary Offset per group, Footer, magic.
#include "record/mcap_writer.hpp"

#include <tuple>
#include <vector>

namespace locaid::record {

using mcap::Op;

void McapWriter::WriteSummaryAndFooter() {
  std::string data_end;
  const size_t end_start = mcap::BeginRecord(data_end, Op::kDataEnd);
  mcap::PutU32(data_end, data_crc_.Value());
  mcap::EndRecord(data_end, end_start);
  WriteToFile(data_end);

  // The summary, its offsets and the footer are built in memory: their size
  // grows with the chunk count (about 100 bytes a chunk), not the message count.
  const uint64_t summary_start = offset_;
  std::string summary;
  std::vector<std::tuple<Op, uint64_t, uint64_t>> groups;  // opcode, file offset, byte length
  auto group = [&](Op op, auto&& append_records) {
    const size_t before = summary.size();
    append_records();
    if (summary.size() > before) groups.emplace_back(op, summary_start + before, summary.size() - before);
  };

  group(Op::kSchema, [&] {
    for (size_t i = 0; i < schemas_.size(); ++i) {
      mcap::AppendSchemaRecord(summary, static_cast<uint16_t>(i + 1), schemas_[i].name, schemas_[i].encoding,
                               schemas_[i].data);
    }
  });
  group(Op::kChannel, [&] {
    for (size_t i = 0; i < channels_.size(); ++i) {
      const Channel& c = channels_[i];
      mcap::AppendChannelRecord(summary, static_cast<uint16_t>(i + 1), c.schema_id, c.topic, c.message_encoding,
                                c.metadata);
    }
  });
  group(Op::kChunkIndex, [&] {
    for (const ChunkIndex& chunk : chunk_indexes_) {
      const size_t start = mcap::BeginRecord(summary, Op::kChunkIndex);
      mcap::PutU64(summary, chunk.start_time);
      mcap::PutU64(summary, chunk.end_time);
      mcap::PutU64(summary, chunk.chunk_offset);
      mcap::PutU64(summary, chunk.chunk_length);
      mcap::PutU16U64Map(summary, chunk.message_index_offsets);
      mcap::PutU64(summary, chunk.message_index_length);
      mcap::PutString(summary, zstd_ ? "zstd" : "");
      mcap::PutU64(summary, chunk.compressed_size);
      mcap::PutU64(summary, chunk.uncompressed_size);
      mcap::EndRecord(summary, start);
    }
  });
  group(Op::kStatistics, [&] {
    std::vector<std::pair<uint16_t, uint64_t>> channel_counts;  // channel ids ascend with i
    for (size_t i = 0; i < channels_.size(); ++i) {
      if (channels_[i].message_count > 0) channel_counts.emplace_back(static_cast<uint16_t>(i + 1), channels_[i].message_count);
    }
    const size_t start = mcap::BeginRecord(summary, Op::kStatistics);
    mcap::PutU64(summary, message_count_);
    mcap::PutU16(summary, static_cast<uint16_t>(schemas_.size()));
    mcap::PutU32(summary, static_cast<uint32_t>(channels_.size()));
    mcap::PutU32(summary, 0);  // attachments: this writer has none
    mcap::PutU32(summary, 0);  // metadata records: none
    mcap::PutU32(summary, static_cast<uint32_t>(chunk_indexes_.size()));
    mcap::PutU64(summary, start_time_);
    mcap::PutU64(summary, end_time_);
    mcap::PutU16U64Map(summary, channel_counts);
    mcap::EndRecord(summary, start);
  });

  const uint64_t summary_offset_start = summary_start + summary.size();
  for (const auto& [op, group_start, group_length] : groups) {
    const size_t start = mcap::BeginRecord(summary, Op::kSummaryOffset);
    mcap::PutU8(summary, static_cast<uint8_t>(op));
    mcap::PutU64(summary, group_start);
    mcap::PutU64(summary, group_length);
    mcap::EndRecord(summary, start);
  }

  const size_t footer = mcap::BeginRecord(summary, Op::kFooter);
  mcap::PutU64(summary, summary_start);
  mcap::PutU64(summary, summary_offset_start);
  // The CRC covers the footer's own length field: set it before computing.
  mcap::EndRecord(summary, footer, /*content_bytes_elsewhere=*/4);
  mcap::PutU32(summary, mcap::ComputeCrc32(summary));  // from the summary up to this field
  summary.append(mcap::kMagic);
  WriteToFile(summary);
}

}  // namespace locaid::record
