// SPDX-License-Identifier: MIT
// The worker control protocol (WORKER_PROTOCOL.md): framing over a
// SOCK_SEQPACKET socketpair, a bounds-checked byte reader/writer, sealed
// memfd blobs for bulk data and the frame ring, and the encodings of plans,
// outputs and session requests. Used by the daemon-side proxy
// (worker_proxy.cpp) and the worker executable (worker/worker_main.cpp).
//
// Trust: everything decoded here may come from a hostile process. Readers
// check every length and offset against the buffer and fail with
// Code::corrupt_data naming what was malformed; they never read out of
// bounds and never throw (except std::bad_alloc). Decoded views point into
// the caller's mapping and are valid while it lives.
// Threads: free functions, no shared state.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "procam/core/status.hpp"
#include "procam/host/plugin_host.hpp"
#include "procam/plugin_abi.h"

struct stat;

namespace procam::host::wire {

inline constexpr uint32_t kMagic = 0x4b574350u;  // "PCWK" little-endian
// 3: outputs through the output arena; 4: the daemon may stop the worker
// (SIGSTOP) between a get_outputs reply and its next request; 5: hello may
// carry the worker's shared heap, and outputs may refer into it; 6: end_round
// may ask for the next_plan and get_outputs replies ahead (sent unasked).
inline constexpr uint16_t kVersion = 6;
inline constexpr size_t kHeaderSize = 16;
inline constexpr size_t kMaxPayload = 64 * 1024;      // control messages stay small
inline constexpr size_t kMaxBlob = size_t{4} << 30;   // plans/outputs/requests, bytes
inline constexpr int kControlFd = 3;                  // the socket's number in the worker
// hello's sandbox flags the daemon acts on (worker/sandbox.hpp SandboxFlags).
inline constexpr uint32_t kSandboxLandlockScope = 1u << 5;
inline constexpr uint32_t kSandboxSeccomp = 1u << 6;
inline constexpr uint32_t kSandboxFreezeSafe = 1u << 7;
inline constexpr uint32_t kSandboxPagesStay = 1u << 8;

enum class Msg : uint16_t {
  // daemon -> worker
  create = 1,
  next_plan = 2,
  set_ring = 3,
  add_frame = 4,
  end_round = 5,
  get_outputs = 6,
  stop = 7,  // no more rounds (host::Session::stop)
  end_session = 8,  // session_destroy; the worker waits for the next create
  // worker -> daemon
  hello = 64,
  ok = 65,
  error = 66,
  log = 67,
  progress = 68,
};
const char* msg_name(uint16_t type);  // "create", ..., "unknown"

// An owned file descriptor (closed on destruction; -1 = none).
class UniqueFd {
public:
  UniqueFd() = default;
  explicit UniqueFd(int fd) : fd_(fd) {}
  UniqueFd(UniqueFd&& o) noexcept : fd_(o.release()) {}
  UniqueFd& operator=(UniqueFd&& o) noexcept;
  UniqueFd(const UniqueFd&) = delete;
  UniqueFd& operator=(const UniqueFd&) = delete;
  ~UniqueFd();
  int get() const { return fd_; }
  int release() { int f = fd_; fd_ = -1; return f; }
  explicit operator bool() const { return fd_ >= 0; }

private:
  int fd_ = -1;
};

// A read-only (or, for the daemon's ring, read-write) shared mapping.
class Mapping {
public:
  Mapping() = default;
  Mapping(void* addr, size_t size) : addr_(addr), size_(size) {}
  Mapping(Mapping&& o) noexcept : addr_(o.addr_), size_(o.size_) { o.addr_ = nullptr; o.size_ = 0; }
  Mapping& operator=(Mapping&& o) noexcept;
  Mapping(const Mapping&) = delete;
  Mapping& operator=(const Mapping&) = delete;
  ~Mapping();
  const uint8_t* data() const { return static_cast<const uint8_t*>(addr_); }
  uint8_t* mutable_data() { return static_cast<uint8_t*>(addr_); }
  size_t size() const { return size_; }

private:
  void* addr_ = nullptr;
  size_t size_ = 0;
};

// Little-endian append-only buffer. Three targets, the same bytes:
//  - Writer(): its own growing string (bytes());
//  - Writer::counting(): nothing stored, size() counts (the first pass of a
//    blob written in place, make_sealed_blob(encode));
//  - Writer(dst, capacity): caller memory (a mapped memfd); a write past
//    `capacity` is dropped and overflowed() turns true.
// Offsets (align) count from the start in every mode.
class Writer {
public:
  Writer() = default;
  Writer(char* dst, size_t capacity) : dst_(dst), cap_(capacity), mode_(Mode::fixed) {}
  static Writer counting() {
    Writer w;
    w.mode_ = Mode::count;
    return w;
  }
  void u8(uint8_t v) { raw(&v, 1); }
  void u32(uint32_t v) { raw(&v, 4); }
  void i32(int32_t v) { raw(&v, 4); }
  void u64(uint64_t v) { raw(&v, 8); }
  void f64(double v) { raw(&v, 8); }
  void str(std::string_view s);  // u32 length, bytes, NUL
  void raw(const void* p, size_t n) {
    if (mode_ == Mode::grow) {
      buf_.append(static_cast<const char*>(p), n);
    } else if (mode_ == Mode::fixed) {
      if (n > cap_ - n_) {
        overflowed_ = true;
        return;
      }
      if (n > 0) std::memcpy(dst_ + n_, p, n);
    }
    n_ += n;
  }
  void align(size_t a);
  size_t size() const { return n_; }
  bool overflowed() const { return overflowed_; }
  std::string& bytes() { return buf_; }  // grow mode only

private:
  enum class Mode { grow, count, fixed };
  std::string buf_;
  char* dst_ = nullptr;
  size_t cap_ = 0, n_ = 0;
  Mode mode_ = Mode::grow;
  bool overflowed_ = false;
};

// Bounds-checked reader; after the first failure every read returns 0/"" and
// ok() is false with the reason in error().
class Reader {
public:
  Reader(const uint8_t* p, size_t n) : p_(p), n_(n) {}
  uint8_t u8(const char* what);
  uint32_t u32(const char* what);
  int32_t i32(const char* what);
  uint64_t u64(const char* what);
  double f64(const char* what);
  // A string written by Writer::str; the view's data() is NUL-terminated.
  std::string_view str(const char* what, size_t max = kMaxBlob);
  bool ok() const { return error_.empty(); }
  const std::string& error() const { return error_; }
  bool at_end() const { return pos_ == n_; }
  void fail(const std::string& why);

private:
  bool take(size_t n, const char* what);
  const uint8_t* p_;
  size_t n_;
  size_t pos_ = 0;
  std::string error_;
};

struct Message {
  uint16_t type = 0;
  uint32_t seq = 0;
  std::string payload;
  UniqueFd fd;  // at most one passed descriptor
};

// Sends one packet (header + payload, optionally one fd). MSG_NOSIGNAL: a
// dead peer gives an error, never SIGPIPE. unavailable on failure.
Status send_msg(int sock, Msg type, uint32_t seq, std::string_view payload, int fd = -1);
// Receives one packet, waiting at most `timeout_ms` (< 0: forever).
// timeout: nothing arrived in time; unavailable: the peer closed its end;
// corrupt_data: truncated, oversized, bad magic/version, more than one fd.
Result<Message> recv_msg(int sock, int timeout_ms);
// The header checks of recv_msg on one received packet (no descriptor);
// fills `m` or says what is malformed (corrupt_data). Fuzzed (tests/fuzz).
Status parse_packet(const char* data, size_t n, Message& m);

// Bulk data: a memfd holding `bytes`, sealed against shrinking, growing and
// writing, so the receiver can map it without fear of SIGBUS or changes.
Result<UniqueFd> make_sealed_blob(const std::string& bytes, const char* name);
// The same, written in place: `encode` runs twice, on a counting Writer and
// then on one over the memfd's mapping (pre-faulted with MAP_POPULATE), so
// bulk data (plans, outputs) is copied once, straight into shared memory,
// without a growing buffer in between. `encode` must write the same bytes
// both times (it is a pure function of its data); internal if not.
Result<UniqueFd> make_sealed_blob(const std::function<void(Writer&)>& encode, const char* name);
// corrupt_data unless every page of the memfd `st` describes is allocated
// (no holes); `what` names it in the message.
Status check_fully_written(const struct stat& st, const char* what);
// Maps a received blob read-only after checking its seals and size.
Result<Mapping> map_sealed_blob(int fd, size_t max_size = kMaxBlob);

// A memfd of `size` bytes sealed against resizing (no SIGBUS for anyone who
// maps it), mapped read-write and pre-faulted here (the frame ring, the
// output arena). `what` names it in errors.
struct FixedShared {
  UniqueFd fd;
  Mapping map;
};
Result<FixedShared> make_fixed_shared(const char* name, uint64_t size, const char* what);

// The frame ring, daemon side: `slots` slots of `slot_size` bytes in a memfd
// sealed against resizing, mapped read-write here; `worker_fd` is a
// read-only descriptor of it (the worker cannot write frames).
struct Ring {
  Mapping map;
  UniqueFd worker_fd;
  uint32_t slots = 0;
  uint64_t slot_size = 0;
};
Result<Ring> make_ring(uint32_t slots, uint64_t slot_size);
// Worker side: maps a ring descriptor read-only; checks it holds slots*slot_size.
Result<Mapping> map_ring(int fd, uint32_t slots, uint64_t slot_size);

// Bytes of one sample of a pixel type; 0 for an unknown type.
size_t sample_bytes(uint32_t pixel_type);
// Packed row bytes of a view (width * channels * sample bytes); 0 if unknown type
// or overflow.
size_t packed_row_bytes(const procam_image& v);

// ---- payload encodings (WORKER_PROTOCOL.md "Blobs") ----

struct CreateRequest {
  std::string plugin_file, plugin_name, method, params, rig;
  std::vector<InputImage> inputs;  // decoded: image views point into the mapping
};
std::string encode_create(const CreateRequest& req);
Status decode_create(const Mapping& blob, CreateRequest& out);

std::string encode_plan(const Plan& plan);
void write_plan(Writer& w, const Plan& plan);
// A plan decoded into the C structs the plugin would have returned, ready
// for detail::plan_from_abi; pointers refer to `blob` and to `frames`.
struct AbiPlan {
  procam_plan plan{};
  std::vector<procam_pattern_frame> frames;
};
Status decode_plan(const Mapping& blob, AbiPlan& out);

// Outputs may name where their bulk data lies in the worker's shared heap
// (worker/shared_heap.hpp) instead of carrying it: wire kinds kHeapImage
// and kHeapPoints, written only when get_outputs asked for them.
inline constexpr uint32_t kHeapKind = 0x100;
inline constexpr uint32_t kHeapImage = kHeapKind | PROCAM_OUTPUT_IMAGE;
inline constexpr uint32_t kHeapPoints = kHeapKind | PROCAM_OUTPUT_POINTS;
inline constexpr uint64_t kHeapAlign = 64;  // a heap reference's offset is a multiple of this
// The writer's view of the heap: [base, base + size).
struct HeapSpan {
  const uint8_t* base = nullptr;
  size_t size = 0;
};
// The reader's: the bytes [offset, offset + bytes) of the heap, checked
// (range, written pages) and readable until the session ends, or nullptr
// with the reason in `why`.
using HeapResolver = std::function<const uint8_t*(uint64_t offset, uint64_t bytes, std::string& why)>;

std::string encode_outputs(const std::vector<Output>& outputs);
// With `heap`, a packed image or a point array that lies wholly inside it,
// at an offset that is a multiple of kHeapAlign, is written as a reference.
void write_outputs(Writer& w, const std::vector<Output>& outputs, const HeapSpan* heap = nullptr);
Status decode_outputs(const Mapping& blob, std::vector<procam_output>& out);
// The same over bytes the caller owns (the daemon's copy of the output
// arena, output_arena.hpp); views point into them, and into what `heap`
// gives for references (none allowed without it).
Status decode_outputs(const uint8_t* data, size_t size, std::vector<procam_output>& out,
                      const HeapResolver& heap = {});

// The end_round request's payload (version 6, "Replies ahead"): `ahead` 0
// is end_round alone, 1 + m asks for the next_plan reply and, after "no
// more rounds", the get_outputs reply in mode m ahead (so 1..3). Encoded
// as nothing for 0, else one byte; decoded from nothing or one byte 0..3,
// anything else (more bytes, a byte above 3) is invalid_argument.
inline constexpr uint8_t kMaxAhead = 3;
std::string encode_end_round(uint8_t ahead);
Status decode_end_round(std::string_view payload, uint8_t& ahead);

// An error reply: code, message, hint.
std::string encode_error(const Status& st);
// Decodes an error reply into `out`; corrupt_data if the payload is malformed.
// An unknown code becomes Code::plugin_error.
Status decode_error(std::string_view payload, Status& out);

}  // namespace procam::host::wire
