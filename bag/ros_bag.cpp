#include "bag/ros_bag.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <stdexcept>

namespace locaid::bag {
namespace fs = std::filesystem;
namespace {

// The split files of a rosbag2 directory, in order.
std::vector<fs::path> FilesOfDirectory(const fs::path& dir) {
  std::vector<fs::path> files;
  const fs::path metadata = dir / "metadata.yaml";
  if (fs::exists(metadata)) {
    YAML::Node root;
    try {
      root = YAML::LoadFile(metadata.string());
    } catch (const YAML::Exception& e) {
      throw std::runtime_error(metadata.string() + ": not readable YAML (" + e.what() + ")");
    }
    const YAML::Node info = root["rosbag2_bagfile_information"];
    if (!info) throw std::runtime_error(metadata.string() + ": no rosbag2_bagfile_information (not a rosbag2 bag)");
    const std::string storage = info["storage_identifier"] ? info["storage_identifier"].as<std::string>("") : "";
    if (!storage.empty() && storage != "mcap") {
      throw std::runtime_error(metadata.string() + ": storage '" + storage +
                               "' (locaid reads mcap bags; convert with `ros2 bag convert`)");
    }
    const std::string compression =
        info["compression_format"] ? info["compression_format"].as<std::string>("") : std::string();
    if (!compression.empty()) {
      throw std::runtime_error(metadata.string() + ": rosbag2 file compression '" + compression +
                               "' not supported (MCAP's own chunk compression is)");
    }
    for (const auto& f : info["relative_file_paths"]) {
      const fs::path p = dir / f.as<std::string>();
      if (!fs::is_regular_file(p))
        throw std::runtime_error(metadata.string() + " lists " + p.string() + ", which does not exist");
      files.push_back(p);
    }
    if (files.empty()) throw std::runtime_error(metadata.string() + ": relative_file_paths lists no file");
    return files;
  }
  for (const auto& e : fs::directory_iterator(dir))
    if (e.is_regular_file() && e.path().extension() == ".mcap") files.push_back(e.path());
  // Name order with numbers compared as numbers: bag_2 before bag_10.
  std::sort(files.begin(), files.end(), [](const fs::path& a, const fs::path& b) {
    const std::string x = a.filename().string(), y = b.filename().string();
    return x.size() != y.size() ? x.size() < y.size() : x < y;
  });
  if (files.empty()) throw std::runtime_error(dir.string() + ": no metadata.yaml and no .mcap file");
  return files;
}

bool Usable(const McapChannel& channel, const McapSchema* schema) {
  return channel.message_encoding == "cdr" && schema != nullptr &&
         (schema->encoding == "ros2msg" || schema->encoding == "ros2idl");
}

}  // namespace

std::string BagMessage::Where() const {
  return std::string(file) + ": topic " + std::string(topic) + ", message " + std::to_string(index);
}

RosBag::RosBag(const fs::path& path) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) {
    files_ = FilesOfDirectory(path);
  } else if (fs::is_regular_file(path, ec)) {
    files_ = {path};
  } else {
    throw std::runtime_error(path.string() + ": no such bag (a .mcap file or a rosbag2 directory)");
  }
  for (const auto& f : files_) total_bytes_ += fs::file_size(f);
  OpenNext();  // the first file's magic and header are checked here
}

bool RosBag::OpenNext() {
  if (reader_) {
    NoteFile(*reader_);
    bytes_before_current_ += reader_->report().file_bytes;
    reader_.reset();
  }
  if (next_file_ >= files_.size()) return false;
  current_file_ = files_[next_file_].string();
  reader_ = std::make_unique<McapReader>(files_[next_file_++]);
  return true;
}

void RosBag::NoteFile(const McapReader& reader) {
  const McapReadReport& r = reader.report();
  if (r.truncated) notes_.push_back(reader.path().string() + ": " + r.truncation);
  if (r.chunks_bad_crc > 0) {
    notes_.push_back(reader.path().string() + ": " + std::to_string(r.chunks_bad_crc) +
                     " chunk(s) with a bad CRC skipped (" + std::to_string(r.messages_in_bad_chunks) +
                     " messages lost)");
  }
}

bool RosBag::Next(BagMessage& out) {
  McapMessage m;
  while (reader_) {
    if (!reader_->Next(m)) {
      if (!OpenNext()) return false;
      continue;
    }
    const McapChannel& channel = reader_->channels().at(m.channel_id);
    const auto schema_it = reader_->schemas().find(channel.schema_id);
    const McapSchema* schema = schema_it == reader_->schemas().end() ? nullptr : &schema_it->second;
    if (!Usable(channel, schema)) {
      ++skipped_[channel.topic];
      continue;
    }
    out.topic = channel.topic;
    out.type = schema->name;
    out.data = m.data;
    out.log_time_ns = m.log_time_ns;
    out.file = current_file_;
    out.index = m.index;
    return true;
  }
  return false;
}

uint64_t RosBag::bytes_done() const { return bytes_before_current_; }

std::vector<std::string> RosBag::notes() const {
  std::vector<std::string> out = notes_;
  if (reader_) {
    const McapReadReport& r = reader_->report();
    if (r.truncated) out.push_back(reader_->path().string() + ": " + r.truncation);
  }
  for (const auto& [topic, n] : skipped_)
    out.push_back("topic " + topic + ": " + std::to_string(n) + " messages not CDR with a ros2msg schema, skipped");
  return out;
}

}  // namespace locaid::bag
