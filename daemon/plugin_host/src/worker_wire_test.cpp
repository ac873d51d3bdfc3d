// SPDX-License-Identifier: MIT
// The worker protocol's framing and blobs (worker_wire.hpp): round trips, and
// that malformed input from a hostile peer is refused, never read past.
#include "worker_wire.hpp"

#include <gtest/gtest.h>
#include <fcntl.h>
#include <sys/mman.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cmath>
#include <random>

namespace procam::host::wire {
namespace {

Mapping blob_of(const std::string& bytes) {
  auto fd = make_sealed_blob(bytes, "test");
  EXPECT_TRUE(fd.ok());
  auto m = map_sealed_blob(fd->get());
  EXPECT_TRUE(m.ok()) << m.status().to_string();
  return std::move(*m);
}

Plan sample_plan(std::vector<uint8_t>& pixels) {
  Plan p;
  p.note = "why";
  pixels.resize(5 * 3);
  for (size_t i = 0; i < pixels.size(); ++i) pixels[i] = static_cast<uint8_t>(i * 3);
  PlannedFrame f;
  f.label = "col bit 0";
  f.pattern.width = 4;  // a view with padding: stride 5
  f.pattern.height = 3;
  f.pattern.channels = 1;
  f.pattern.pixel_type = PROCAM_PIXEL_U8;
  f.pattern.bit_depth = 8;
  f.pattern.stride_bytes = 5;
  f.pattern.data = pixels.data();
  f.settings.struct_size = sizeof(procam_frame_settings);
  f.settings.exposure_us = 1250;
  f.settings.polarizer_deg = NAN;
  p.frames = {f, f};
  p.frames[1].label = "col bit 0 inverse";
  p.frames[1].settings.light_index = 3;
  return p;
}

// end_round's payload (version 6, "Replies ahead"): empty or one byte 1..3;
// everything else is refused with what was wrong.
TEST(WorkerWire, EndRoundAheadRoundTripsAndIsBounded) {
  for (uint8_t ahead = 0; ahead <= wire::kMaxAhead; ++ahead) {
    const std::string payload = wire::encode_end_round(ahead);
    EXPECT_EQ(payload.size(), ahead == 0 ? 0u : 1u);
    uint8_t got = 99;
    ASSERT_TRUE(wire::decode_end_round(payload, got).ok()) << int{ahead};
    EXPECT_EQ(got, ahead);
  }
  uint8_t got = 0;
  uint8_t zero = 9;  // the one-byte form of 0, as the protocol allows
  ASSERT_TRUE(wire::decode_end_round(std::string(1, '\0'), zero).ok());
  EXPECT_EQ(zero, 0);
  for (const std::string& bad : {std::string(1, '\4'), std::string(1, '\xff'), std::string("\1\1")}) {
    const Status st = wire::decode_end_round(bad, got);
    EXPECT_EQ(st.code(), Code::invalid_argument) << bad.size();
    EXPECT_NE(st.message().find("malformed end_round"), std::string::npos) << st.message();
    EXPECT_EQ(got, 0);
  }
}

TEST(WorkerWire, PlanRoundTripsThroughASealedBlob) {
  std::vector<uint8_t> px;
  const Plan p = sample_plan(px);
  Mapping m = blob_of(encode_plan(p));
  AbiPlan abi;
  ASSERT_TRUE(decode_plan(m, abi).ok());
  ASSERT_EQ(abi.plan.frame_count, 2u);
  EXPECT_STREQ(abi.plan.note, "why");
  EXPECT_STREQ(abi.frames[1].label, "col bit 0 inverse");
  EXPECT_EQ(abi.frames[0].settings.exposure_us, 1250);
  EXPECT_EQ(abi.frames[0].settings.light_index, 0);
  EXPECT_EQ(abi.frames[1].settings.light_index, 3);
  EXPECT_TRUE(std::isnan(abi.frames[0].settings.polarizer_deg));
  const procam_image& v = abi.frames[1].pattern;
  ASSERT_EQ(v.stride_bytes, 4u);  // packed on the wire
  for (uint32_t y = 0; y < 3; ++y)
    for (uint32_t x = 0; x < 4; ++x)
      EXPECT_EQ(static_cast<const uint8_t*>(v.data)[y * 4 + x], px[y * 5 + x]);
  EXPECT_EQ(reinterpret_cast<uintptr_t>(v.data) % 64, 0u);  // pixel runs are aligned
}

// Blobs written in place (counted, then encoded into the mapped memfd) hold
// exactly the bytes of the string encoding, and are sealed like them.
TEST(WorkerWire, InPlaceBlobHoldsTheSameBytesAsTheStringEncoding) {
  std::vector<uint8_t> px;
  const Plan p = sample_plan(px);
  const std::string expect = encode_plan(p);
  auto fd = make_sealed_blob([&](Writer& w) { write_plan(w, p); }, "test-in-place");
  ASSERT_TRUE(fd.ok()) << fd.status().to_string();
  auto m = map_sealed_blob(fd->get());  // checks the seals
  ASSERT_TRUE(m.ok()) << m.status().to_string();
  ASSERT_EQ(m->size(), expect.size());
  EXPECT_EQ(std::string(reinterpret_cast<const char*>(m->data()), m->size()), expect);
  // An empty blob is still a sealed memfd.
  auto empty = make_sealed_blob([](Writer&) {}, "test-empty");
  ASSERT_TRUE(empty.ok());
  EXPECT_TRUE(map_sealed_blob(empty->get()).ok());
}

// A sealed memfd with holes (sized, never written) is refused before it is
// mapped: reading it would allocate its pages here.
TEST(WorkerWire, SparseBlobIsRefused) {
  UniqueFd fd(::memfd_create("sparse", MFD_CLOEXEC | MFD_ALLOW_SEALING));
  ASSERT_TRUE(fd);
  ASSERT_EQ(::ftruncate(fd.get(), 64 << 20), 0);
  ASSERT_EQ(::pwrite(fd.get(), "x", 1, 0), 1);  // one page written of 16384
  ASSERT_EQ(::fcntl(fd.get(), F_ADD_SEALS, F_SEAL_SHRINK | F_SEAL_GROW | F_SEAL_WRITE), 0);
  auto m = map_sealed_blob(fd.get());
  ASSERT_FALSE(m.ok());
  EXPECT_EQ(m.status().code(), Code::corrupt_data);
  EXPECT_NE(m.status().message().find("sparse"), std::string::npos) << m.status().message();
}

TEST(WorkerWire, InPlaceBlobRefusesAnEncoderThatWritesMoreThanItCounted) {
  int pass = 0;
  auto grows = make_sealed_blob([&](Writer& w) { w.u32(pass++ == 0 ? 1 : 2); if (pass > 1) w.u64(7); }, "t");
  EXPECT_EQ(grows.status().code(), Code::internal) << grows.status().to_string();
  pass = 0;
  auto shrinks = make_sealed_blob([&](Writer& w) { if (pass++ == 0) w.u64(7); else w.u32(1); }, "t");
  EXPECT_EQ(shrinks.status().code(), Code::internal) << shrinks.status().to_string();
  // A fixed writer drops what does not fit and says so.
  char buf[6] = {};
  Writer w(buf, sizeof buf);
  w.u32(0x01020304);
  w.u32(5);
  EXPECT_TRUE(w.overflowed());
  EXPECT_EQ(w.size(), 4u);
  EXPECT_EQ(buf[0], 4);
}

TEST(WorkerWire, EveryTruncationOfAPlanIsRefused) {
  std::vector<uint8_t> px;
  const std::string bytes = encode_plan(sample_plan(px));
  for (size_t n = 0; n < bytes.size(); ++n) {
    Mapping m = blob_of(bytes.substr(0, n));
    AbiPlan abi;
    Status st = decode_plan(m, abi);
    EXPECT_FALSE(st.ok()) << "accepted a plan cut at " << n << " of " << bytes.size();
    if (!st.ok()) {
      EXPECT_EQ(st.code(), Code::corrupt_data);
    }
  }
}

TEST(WorkerWire, RandomlyFlippedOutputsNeverReadOutOfBounds) {
  std::vector<Output> outs(3);
  float img[4] = {1, 2, 3, 4};
  float pts[6] = {1, 2, 3, 4, 5, 6};
  outs[0].name = "depth_mm";
  outs[0].kind = PROCAM_OUTPUT_IMAGE;
  outs[0].image = {2, 2, 1, PROCAM_PIXEL_F32, 32, 0, 8, img};
  outs[1].name = "cloud";
  outs[1].kind = PROCAM_OUTPUT_POINTS;
  outs[1].points = pts;
  outs[1].point_count = 2;
  outs[1].point_stride = 3;
  outs[2].name = "report";
  outs[2].kind = PROCAM_OUTPUT_JSON;
  outs[2].json = "{}";
  const std::string bytes = encode_outputs(outs);
  {
    Mapping m = blob_of(bytes);
    std::vector<procam_output> abi;
    ASSERT_TRUE(decode_outputs(m, abi).ok());
    ASSERT_EQ(abi.size(), 3u);
    EXPECT_EQ(abi[1].points[5], 6.0f);
    EXPECT_EQ(static_cast<const float*>(abi[0].image.data)[3], 4.0f);
  }
  std::mt19937 rng(17);
  for (int it = 0; it < 3000; ++it) {
    std::string b = bytes;
    for (int k = 0; k < 3; ++k) b[rng() % b.size()] = static_cast<char>(rng());
    Mapping m = blob_of(b);
    std::vector<procam_output> abi;
    if (!decode_outputs(m, abi).ok()) continue;
    // Whatever decoded lies inside the mapping (ASan builds check the reads).
    for (const procam_output& o : abi) {
      if (o.kind == PROCAM_OUTPUT_POINTS && o.point_count > 0) {
        const auto* end = reinterpret_cast<const uint8_t*>(o.points + o.point_count * o.point_stride);
        EXPECT_LE(end, m.data() + m.size());
      }
    }
  }
}

// Version 5: with the writer's heap span, a packed image or a point array
// that lies inside the heap at an aligned offset is named (offset), not
// copied; the reader resolves it through its own view of the heap and gets
// those very bytes. Anything else is copied as before.
TEST(WorkerWire, OutputsInTheSharedHeapAreNamedNotCopied) {
  const size_t heap_size = size_t{1} << 20;
  void* hp = ::mmap(nullptr, heap_size, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  ASSERT_NE(hp, MAP_FAILED);
  Mapping heap_map(hp, heap_size);
  auto* heap = static_cast<uint8_t*>(hp);
  auto* img = reinterpret_cast<float*>(heap + 4096);     // 64x64 F32 map in the heap
  auto* pts = reinterpret_cast<float*>(heap + 65536);    // 100 points of 3 floats in the heap
  auto* odd = reinterpret_cast<float*>(heap + 131072 + 4);  // in the heap, unaligned: copied
  for (int i = 0; i < 64 * 64; ++i) img[i] = static_cast<float>(i);
  for (int i = 0; i < 300; ++i) pts[i] = static_cast<float>(-i);
  for (int i = 0; i < 16; ++i) odd[i] = 0.5f * static_cast<float>(i);
  float outside[4] = {9, 8, 7, 6};
  std::vector<Output> outs(4);
  outs[0].name = "depth_mm";
  outs[0].kind = PROCAM_OUTPUT_IMAGE;
  outs[0].image = {64, 64, 1, PROCAM_PIXEL_F32, 32, 0, 256, img};
  outs[1].name = "cloud";
  outs[1].kind = PROCAM_OUTPUT_POINTS;
  outs[1].points = pts;
  outs[1].point_count = 100;
  outs[1].point_stride = 3;
  outs[1].point_fields = "x,y,z";
  outs[2].name = "odd";
  outs[2].kind = PROCAM_OUTPUT_IMAGE;
  outs[2].image = {4, 4, 1, PROCAM_PIXEL_F32, 32, 0, 16, odd};
  outs[3].name = "small";
  outs[3].kind = PROCAM_OUTPUT_IMAGE;
  outs[3].image = {2, 2, 1, PROCAM_PIXEL_F32, 32, 0, 8, outside};
  const HeapSpan span{heap, heap_size};
  Writer w;
  write_outputs(w, outs, &span);
  const std::string with_refs = w.bytes();
  const std::string copied = encode_outputs(outs);
  // The two heap blocks (16 KiB + 1200 B) are not in the encoding (each
  // reference adds an 8-byte offset; the copy adds alignment padding).
  EXPECT_LE(with_refs.size() + 16384 + 1200, copied.size() + 16);
  std::vector<std::pair<uint64_t, uint64_t>> asked;
  const HeapResolver resolve = [&](uint64_t off, uint64_t bytes, std::string& why) -> const uint8_t* {
    asked.emplace_back(off, bytes);
    if (off > heap_size || bytes > heap_size - off) {
      why = "out of the heap";
      return nullptr;
    }
    return heap + off;
  };
  std::vector<procam_output> abi;
  auto* data = reinterpret_cast<const uint8_t*>(with_refs.data());
  Status st = decode_outputs(data, with_refs.size(), abi, resolve);
  ASSERT_TRUE(st.ok()) << st.to_string();
  ASSERT_EQ(abi.size(), 4u);
  EXPECT_EQ(abi[0].kind, static_cast<uint32_t>(PROCAM_OUTPUT_IMAGE));
  EXPECT_EQ(abi[0].image.data, img);  // the very bytes, no copy
  EXPECT_EQ(abi[0].image.stride_bytes, 256u);
  EXPECT_EQ(abi[1].kind, static_cast<uint32_t>(PROCAM_OUTPUT_POINTS));
  EXPECT_EQ(abi[1].points, pts);
  EXPECT_EQ(abi[1].point_count, 100u);
  EXPECT_NE(abi[2].image.data, odd);  // unaligned: carried in the encoding
  EXPECT_EQ(static_cast<const float*>(abi[2].image.data)[15], 7.5f);
  EXPECT_EQ(static_cast<const float*>(abi[3].image.data)[3], 6.0f);
  ASSERT_EQ(asked.size(), 2u);
  EXPECT_EQ(asked[0], std::make_pair(uint64_t{4096}, uint64_t{64 * 64 * 4}));
  EXPECT_EQ(asked[1], std::make_pair(uint64_t{65536}, uint64_t{1200}));
  // A reader that allows no heap refuses references, naming why.
  st = decode_outputs(data, with_refs.size(), abi);
  ASSERT_FALSE(st.ok());
  EXPECT_EQ(st.code(), Code::corrupt_data);
  EXPECT_NE(st.message().find("shared heap"), std::string::npos) << st.message();
  // A resolver's refusal is the decode's.
  const HeapResolver refuse = [](uint64_t, uint64_t, std::string& why) -> const uint8_t* {
    why = "unwritten pages";
    return nullptr;
  };
  st = decode_outputs(data, with_refs.size(), abi, refuse);
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.message().find("unwritten pages"), std::string::npos) << st.message();
  // Without the span the same outputs are copied, byte for byte as before.
  Writer plain;
  write_outputs(plain, outs, nullptr);
  EXPECT_EQ(plain.bytes(), copied);
}

// A hostile worker's reference: unaligned offsets are refused before the
// resolver is asked; flipped bytes never make the reader go out of bounds.
TEST(WorkerWire, HeapReferencesAreCheckedBeforeTheyAreResolved) {
  std::vector<Output> outs(1);
  static float block[16 * 16] __attribute__((aligned(64)));
  outs[0].name = "m";
  outs[0].kind = PROCAM_OUTPUT_IMAGE;
  outs[0].image = {16, 16, 1, PROCAM_PIXEL_F32, 32, 0, 64, block};
  const HeapSpan span{reinterpret_cast<const uint8_t*>(block), sizeof block};
  Writer w;
  write_outputs(w, outs, &span);
  std::string bytes = w.bytes();
  ASSERT_EQ(bytes.size(), 4 + (4 + 2) + 4 + (4 + 1) + (4 + 1) + 5 * 4 + 8u);
  int asked = 0;
  const HeapResolver resolve = [&](uint64_t off, uint64_t n, std::string& why) -> const uint8_t* {
    ++asked;
    if (off > sizeof block || n > sizeof block - off) {
      why = "out of the heap";
      return nullptr;
    }
    return reinterpret_cast<const uint8_t*>(block) + off;
  };
  std::vector<procam_output> abi;
  bytes[bytes.size() - 8] = 4;  // offset 4
  Status st = decode_outputs(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size(), abi, resolve);
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.message().find("not a multiple of 64"), std::string::npos) << st.message();
  EXPECT_EQ(asked, 0);
  bytes[bytes.size() - 8] = 64;  // aligned, but 1 KiB from there runs past the block
  st = decode_outputs(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size(), abi, resolve);
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.message().find("out of the heap"), std::string::npos) << st.message();
  bytes[bytes.size() - 8] = 0;
  st = decode_outputs(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size(), abi, resolve);
  EXPECT_TRUE(st.ok()) << st.to_string();
}

TEST(WorkerWire, UnsealedBlobsAreRefused) {
  const int fd = ::memfd_create("unsealed", MFD_CLOEXEC);
  ASSERT_GE(fd, 0);
  ASSERT_EQ(::write(fd, "abcd", 4), 4);
  auto m = map_sealed_blob(fd);
  ::close(fd);
  ASSERT_FALSE(m.ok());
  EXPECT_TRUE(m.status().message().find("not a sealed memfd") != std::string::npos);
}

TEST(WorkerWire, FramingRefusesShortBadAndOversizedPackets) {
  int sv[2];
  ASSERT_EQ(::socketpair(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0, sv), 0);
  ASSERT_TRUE(send_msg(sv[0], Msg::log, 9, "hello").ok());
  auto m = recv_msg(sv[1], 1000);
  ASSERT_TRUE(m.ok());
  EXPECT_EQ(m->type, static_cast<uint16_t>(Msg::log));
  EXPECT_EQ(m->seq, 9u);
  EXPECT_EQ(m->payload, "hello");
  ASSERT_EQ(::write(sv[0], "junk", 4), 4);
  EXPECT_EQ(recv_msg(sv[1], 1000).status().code(), Code::corrupt_data);
  const std::string bad_magic(32, 'x');
  ASSERT_EQ(::write(sv[0], bad_magic.data(), bad_magic.size()), 32);
  auto bm = recv_msg(sv[1], 1000);
  EXPECT_TRUE(bm.status().message().find("bad magic 0x78787878") != std::string::npos) << bm.status().message();
  const std::string huge(kHeaderSize + kMaxPayload + 100, '\0');
  ASSERT_EQ(::write(sv[0], huge.data(), huge.size()), static_cast<ssize_t>(huge.size()));
  EXPECT_EQ(recv_msg(sv[1], 1000).status().code(), Code::corrupt_data);
  EXPECT_EQ(recv_msg(sv[1], 10).status().code(), Code::timeout);
  ::close(sv[0]);
  EXPECT_EQ(recv_msg(sv[1], 1000).status().code(), Code::unavailable);
  ::close(sv[1]);
}

TEST(WorkerWire, ErrorRepliesKeepCodeAndUnknownCodesBecomePluginErrors) {
  Status st;
  ASSERT_TRUE(decode_error(encode_error(Error(Code::failed_precondition, "needs a table", "add one")), st).ok());
  EXPECT_EQ(st.code(), Code::failed_precondition);
  EXPECT_EQ(st.message(), "needs a table");
  EXPECT_EQ(st.hint(), "add one");
  Writer w;
  w.u32(9999);
  w.str("x");
  w.str("");
  ASSERT_TRUE(decode_error(w.bytes(), st).ok());
  EXPECT_EQ(st.code(), Code::plugin_error);
  EXPECT_EQ(decode_error("\x01", st).code(), Code::corrupt_data);
}

}  // namespace
}  // namespace procam::host::wire
