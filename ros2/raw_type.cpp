#include "ros2/raw_type.hpp"

#include <dds/dds.h>
#include <dds/ddsi/ddsi_serdata.h>
#include <dds/ddsi/ddsi_sertype.h>
#include <dds/ddsi/q_radmin.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <new>

namespace locaid::ros2::detail {
namespace {

// The serialized bytes live behind the common part; `capacity` is the size
// rounded up to 4 with zeros, since Cyclone may copy up to that (to_ser).
struct RawSerdata {
  ddsi_serdata c;
  unsigned char* bytes = nullptr;
  uint32_t size = 0;
};

struct RawSertype {
  ddsi_sertype c;
};

RawSerdata* NewSerdata(const ddsi_sertype* type, ddsi_serdata_kind kind, size_t size) {
  auto* d = new RawSerdata{};
  ddsi_serdata_init(&d->c, type, kind);
  d->size = static_cast<uint32_t>(size);
  const size_t capacity = (size + 3) & ~size_t{3};
  d->bytes = new unsigned char[capacity == 0 ? 4 : capacity]();
  return d;
}

RawSerdata* Of(ddsi_serdata* d) { return reinterpret_cast<RawSerdata*>(d); }
const RawSerdata* Of(const ddsi_serdata* d) { return reinterpret_cast<const RawSerdata*>(d); }

// ---------------------------------------------------------------- serdata --

uint32_t SerdataSize(const ddsi_serdata* d) { return Of(d)->size; }

void SerdataFree(ddsi_serdata* d) {
  delete[] Of(d)->bytes;
  delete Of(d);
}

// A received sample: the fragments, which may overlap, copied in order (the
// first one starts at 0 and holds the encapsulation header).
ddsi_serdata* SerdataFromSer(const ddsi_sertype* type, ddsi_serdata_kind kind, const nn_rdata* fragchain,
                             size_t size) {
  RawSerdata* d = NewSerdata(type, kind, size);
  uint32_t off = 0;
  for (const nn_rdata* f = fragchain; f != nullptr; f = f->nextfrag) {
    if (f->maxp1 <= off) continue;  // adds nothing new
    const unsigned char* payload = NN_RMSG_PAYLOADOFF(f->rmsg, NN_RDATA_PAYLOAD_OFF(f));
    const uint32_t end = std::min<uint32_t>(f->maxp1, static_cast<uint32_t>(size));
    if (end > off) std::memcpy(d->bytes + off, payload + (off - f->min), end - off);
    off = std::max(off, end);
  }
  return &d->c;
}

ddsi_serdata* SerdataFromSerIov(const ddsi_sertype* type, ddsi_serdata_kind kind, ddsrt_msg_iovlen_t niov,
                                const ddsrt_iovec_t* iov, size_t size) {
  RawSerdata* d = NewSerdata(type, kind, size);
  size_t off = 0;
  for (ddsrt_msg_iovlen_t i = 0; i < niov && off < size; ++i) {
    const size_t n = std::min<size_t>(iov[i].iov_len, size - off);
    std::memcpy(d->bytes + off, iov[i].iov_base, n);
    off += n;
  }
  return &d->c;
}

ddsi_serdata* SerdataFromKeyhash(const ddsi_sertype* type, const ddsi_keyhash*) {
  return &NewSerdata(type, SDK_KEY, 0)->c;  // keyless: nothing to keep
}

ddsi_serdata* SerdataFromSample(const ddsi_sertype* type, ddsi_serdata_kind kind, const void* sample) {
  const auto* raw = static_cast<const RawSample*>(sample);
  const size_t size = kind == SDK_DATA ? raw->size : 0;
  RawSerdata* d = NewSerdata(type, kind, size);
  if (size > 0) std::memcpy(d->bytes, raw->data, size);
  return &d->c;
}

void SerdataToSer(const ddsi_serdata* d, size_t off, size_t sz, void* buf) {
  std::memcpy(buf, Of(d)->bytes + off, sz);
}

ddsi_serdata* SerdataToSerRef(const ddsi_serdata* d, size_t off, size_t sz, ddsrt_iovec_t* ref) {
  ref->iov_base = Of(d)->bytes + off;
  ref->iov_len = static_cast<ddsrt_iov_len_t>(sz);
  return ddsi_serdata_ref(d);
}

void SerdataToSerUnref(ddsi_serdata* d, const ddsrt_iovec_t*) { ddsi_serdata_unref(d); }

// Samples are only taken as serdata (dds_takecdr); a typed read has nothing
// to fill.
bool SerdataToSample(const ddsi_serdata*, void*, void**, void*) { return false; }

ddsi_serdata* SerdataToUntyped(const ddsi_serdata* d) {
  RawSerdata* u = NewSerdata(d->type, SDK_KEY, 0);
  u->c.type = nullptr;
  return &u->c;
}

bool SerdataUntypedToSample(const ddsi_sertype*, const ddsi_serdata*, void*, void**, void*) { return true; }

bool SerdataEqkey(const ddsi_serdata*, const ddsi_serdata*) { return true; }  // keyless: one instance

size_t SerdataPrint(const ddsi_sertype*, const ddsi_serdata* d, char* buf, size_t bufsize) {
  const int n = std::snprintf(buf, bufsize, "raw CDR, %u bytes", static_cast<unsigned>(Of(d)->size));
  return n < 0 ? 0 : static_cast<size_t>(n);
}

void SerdataGetKeyhash(const ddsi_serdata*, ddsi_keyhash* buf, bool) { std::memset(buf, 0, sizeof *buf); }

const ddsi_serdata_ops kSerdataOps = [] {
  ddsi_serdata_ops ops{};
  ops.eqkey = SerdataEqkey;
  ops.get_size = SerdataSize;
  ops.from_ser = SerdataFromSer;
  ops.from_ser_iov = SerdataFromSerIov;
  ops.from_keyhash = SerdataFromKeyhash;
  ops.from_sample = SerdataFromSample;
  ops.to_ser = SerdataToSer;
  ops.to_ser_ref = SerdataToSerRef;
  ops.to_ser_unref = SerdataToSerUnref;
  ops.to_sample = SerdataToSample;
  ops.to_untyped = SerdataToUntyped;
  ops.untyped_to_sample = SerdataUntypedToSample;
  ops.free = SerdataFree;
  ops.print = SerdataPrint;
  ops.get_keyhash = SerdataGetKeyhash;
  return ops;
}();

// ---------------------------------------------------------------- sertype --

void SertypeFree(ddsi_sertype* t) {
  ddsi_sertype_fini(t);
  delete reinterpret_cast<RawSertype*>(t);
}

void SertypeZeroSamples(const ddsi_sertype*, void* samples, size_t count) {
  std::fill_n(static_cast<RawSample*>(samples), count, RawSample{});
}

void SertypeReallocSamples(void** ptrs, const ddsi_sertype*, void* old, size_t oldcount, size_t count) {
  auto* fresh = new RawSample[count]();
  if (old != nullptr) std::copy_n(static_cast<RawSample*>(old), std::min(oldcount, count), fresh);
  delete[] static_cast<RawSample*>(old);
  for (size_t i = 0; i < count; ++i) ptrs[i] = &fresh[i];
}

void SertypeFreeSamples(const ddsi_sertype*, void** ptrs, size_t count, dds_free_op_t op) {
  // RawSample owns nothing; only the array itself may go.
  if (count > 0 && (op & DDS_FREE_ALL_BIT)) delete[] static_cast<RawSample*>(ptrs[0]);
}

bool SertypeEqual(const ddsi_sertype*, const ddsi_sertype*) { return true; }  // the name says it all
uint32_t SertypeHash(const ddsi_sertype*) { return 0; }

size_t SertypeSerializedSize(const ddsi_sertype*, const void* sample) {
  return static_cast<const RawSample*>(sample)->size;
}

bool SertypeSerializeInto(const ddsi_sertype*, const void* sample, void* dst, size_t dst_size) {
  const auto* raw = static_cast<const RawSample*>(sample);
  if (raw->size > dst_size) return false;
  std::memcpy(dst, raw->data, raw->size);
  return true;
}

const ddsi_sertype_ops kSertypeOps = [] {
  ddsi_sertype_ops ops{};
  ops.version = ddsi_sertype_v0;
  ops.free = SertypeFree;
  ops.zero_samples = SertypeZeroSamples;
  ops.realloc_samples = SertypeReallocSamples;
  ops.free_samples = SertypeFreeSamples;
  ops.equal = SertypeEqual;
  ops.hash = SertypeHash;
  ops.get_serialized_size = SertypeSerializedSize;
  ops.serialize_into = SertypeSerializeInto;
  return ops;
}();

}  // namespace

ddsi_sertype* NewRawSertype(const char* dds_type_name) {
  auto* t = new RawSertype{};
  ddsi_sertype_init_flags(&t->c, dds_type_name, &kSertypeOps, &kSerdataOps, DDSI_SERTYPE_FLAG_TOPICKIND_NO_KEY);
  t->c.allowed_data_representation = DDS_DATA_REPRESENTATION_FLAG_XCDR1;
  return &t->c;
}

std::string_view RawBytes(const ddsi_serdata* serdata) {
  const RawSerdata* d = Of(serdata);
  return {reinterpret_cast<const char*>(d->bytes), d->size};
}

}  // namespace locaid::ros2::detail
