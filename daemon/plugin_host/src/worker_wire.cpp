// SPDX-License-Identifier: MIT
// Worker control protocol: framing, memfd blobs, payload encodings
// (worker_wire.hpp, WORKER_PROTOCOL.md).
#include "worker_wire.hpp"

#include <fcntl.h>
#include <poll.h>
#include <sys/mman.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <string>

namespace procam::host::wire {

const char* msg_name(uint16_t type) {
  switch (static_cast<Msg>(type)) {
    case Msg::create: return "create";
    case Msg::next_plan: return "next_plan";
    case Msg::set_ring: return "set_ring";
    case Msg::add_frame: return "add_frame";
    case Msg::end_round: return "end_round";
    case Msg::get_outputs: return "get_outputs";
    case Msg::stop: return "stop";
    case Msg::end_session: return "end_session";
    case Msg::hello: return "hello";
    case Msg::ok: return "ok";
    case Msg::error: return "error";
    case Msg::log: return "log";
    case Msg::progress: return "progress";
  }
  return "unknown";
}

UniqueFd& UniqueFd::operator=(UniqueFd&& o) noexcept {
  if (this != &o) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = o.release();
  }
  return *this;
}

UniqueFd::~UniqueFd() {
  if (fd_ >= 0) ::close(fd_);
}

Mapping& Mapping::operator=(Mapping&& o) noexcept {
  if (this != &o) {
    if (addr_ != nullptr) ::munmap(addr_, size_);
    addr_ = o.addr_;
    size_ = o.size_;
    o.addr_ = nullptr;
    o.size_ = 0;
  }
  return *this;
}

Mapping::~Mapping() {
  if (addr_ != nullptr) ::munmap(addr_, size_);
}

void Writer::str(std::string_view s) {
  u32(static_cast<uint32_t>(s.size()));
  raw(s.data(), s.size());
  u8(0);
}

void Writer::align(size_t a) {
  while (n_ % a != 0 && !overflowed_) u8(0);
}

void Reader::fail(const std::string& why) {
  if (error_.empty()) error_ = why;
}

bool Reader::take(size_t n, const char* what) {
  if (!ok()) return false;
  if (n > n_ - pos_) {
    fail(std::string("truncated at byte ") + std::to_string(pos_) + " reading " + what);
    return false;
  }
  return true;
}

uint8_t Reader::u8(const char* what) {
  if (!take(1, what)) return 0;
  return p_[pos_++];
}

#define PROCAM_READ_SCALAR(T, name)              \
  T Reader::name(const char* what) {             \
    T v{};                                       \
    if (!take(sizeof v, what)) return v;         \
    std::memcpy(&v, p_ + pos_, sizeof v);        \
    pos_ += sizeof v;                            \
    return v;                                    \
  }
PROCAM_READ_SCALAR(uint32_t, u32)
PROCAM_READ_SCALAR(int32_t, i32)
PROCAM_READ_SCALAR(uint64_t, u64)
PROCAM_READ_SCALAR(double, f64)
#undef PROCAM_READ_SCALAR

std::string_view Reader::str(const char* what, size_t max) {
  const uint32_t n = u32(what);
  if (!ok()) return {};
  if (n > max) {
    fail(std::string(what) + " is " + std::to_string(n) + " bytes, more than " + std::to_string(max));
    return {};
  }
  if (!take(size_t{n} + 1, what)) return {};
  if (p_[pos_ + n] != 0) {
    fail(std::string(what) + " is not NUL-terminated");
    return {};
  }
  std::string_view s(reinterpret_cast<const char*>(p_ + pos_), n);
  pos_ += size_t{n} + 1;
  return s;
}

size_t sample_bytes(uint32_t pixel_type) {
  switch (pixel_type) {
    case PROCAM_PIXEL_U8: return 1;
    case PROCAM_PIXEL_U16: return 2;
    case PROCAM_PIXEL_F32: return 4;
    default: return 0;
  }
}

size_t packed_row_bytes(const procam_image& v) {
  const size_t sb = sample_bytes(v.pixel_type);
  size_t row = 0;
  if (sb == 0 || __builtin_mul_overflow(size_t{v.width}, size_t{v.channels}, &row) ||
      __builtin_mul_overflow(row, sb, &row))
    return 0;
  return row;
}

// ---- framing ----

Status send_msg(int sock, Msg type, uint32_t seq, std::string_view payload, int fd) {
  if (payload.size() > kMaxPayload)
    return Error(Code::internal, std::string("worker message '") + msg_name(static_cast<uint16_t>(type)) +
                                     "' payload of " + std::to_string(payload.size()) + " bytes is over the limit");
  uint8_t header[kHeaderSize];
  const uint32_t magic = kMagic, len = static_cast<uint32_t>(payload.size());
  const uint16_t version = kVersion, t = static_cast<uint16_t>(type);
  std::memcpy(header, &magic, 4);
  std::memcpy(header + 4, &version, 2);
  std::memcpy(header + 6, &t, 2);
  std::memcpy(header + 8, &seq, 4);
  std::memcpy(header + 12, &len, 4);
  iovec iov[2] = {{header, kHeaderSize}, {const_cast<char*>(payload.data()), payload.size()}};
  msghdr mh{};
  mh.msg_iov = iov;
  mh.msg_iovlen = payload.empty() ? 1 : 2;
  alignas(cmsghdr) char cbuf[CMSG_SPACE(sizeof(int))];
  if (fd >= 0) {
    std::memset(cbuf, 0, sizeof cbuf);
    mh.msg_control = cbuf;
    mh.msg_controllen = sizeof cbuf;
    cmsghdr* c = CMSG_FIRSTHDR(&mh);
    c->cmsg_level = SOL_SOCKET;
    c->cmsg_type = SCM_RIGHTS;
    c->cmsg_len = CMSG_LEN(sizeof(int));
    std::memcpy(CMSG_DATA(c), &fd, sizeof(int));
  }
  for (;;) {
    const ssize_t n = ::sendmsg(sock, &mh, MSG_NOSIGNAL);
    if (n >= 0) return {};
    if (errno == EINTR) continue;
    return Error(Code::unavailable, std::string("cannot send to the worker: ") + std::strerror(errno));
  }
}

Result<Message> recv_msg(int sock, int timeout_ms) {
  pollfd pfd{sock, POLLIN, 0};
  for (;;) {
    const int r = ::poll(&pfd, 1, timeout_ms);
    if (r > 0) break;
    if (r == 0) return Error(Code::timeout, "no message in time");
    if (errno != EINTR) return Error(Code::unavailable, std::string("poll: ") + std::strerror(errno));
  }
  std::string buf(kHeaderSize + kMaxPayload + 1, '\0');
  iovec iov{buf.data(), buf.size()};
  alignas(cmsghdr) char cbuf[CMSG_SPACE(sizeof(int) * 4)];
  msghdr mh{};
  mh.msg_iov = &iov;
  mh.msg_iovlen = 1;
  mh.msg_control = cbuf;
  mh.msg_controllen = sizeof cbuf;
  ssize_t n;
  do n = ::recvmsg(sock, &mh, MSG_CMSG_CLOEXEC | MSG_DONTWAIT);
  while (n < 0 && errno == EINTR);
  if (n < 0) return Error(Code::unavailable, std::string("recvmsg: ") + std::strerror(errno));
  // Take ownership of every passed descriptor first, so none leaks on an error.
  std::vector<UniqueFd> fds;
  for (cmsghdr* c = CMSG_FIRSTHDR(&mh); c != nullptr; c = CMSG_NXTHDR(&mh, c)) {
    if (c->cmsg_level != SOL_SOCKET || c->cmsg_type != SCM_RIGHTS) continue;
    const size_t count = (c->cmsg_len - CMSG_LEN(0)) / sizeof(int);
    for (size_t i = 0; i < count; ++i) {
      int f;
      std::memcpy(&f, CMSG_DATA(c) + i * sizeof(int), sizeof f);
      fds.emplace_back(f);
    }
  }
  if (n == 0) return Error(Code::unavailable, "the peer closed the connection");
  if ((mh.msg_flags & (MSG_TRUNC | MSG_CTRUNC)) != 0 || static_cast<size_t>(n) > kHeaderSize + kMaxPayload)
    return Error(Code::corrupt_data, "oversized message (more than " + std::to_string(kMaxPayload) +
                                         " payload bytes or too many descriptors)");
  if (fds.size() > 1) return Error(Code::corrupt_data, std::to_string(fds.size()) + " descriptors in one message");
  Message m;
  PROCAM_TRY(parse_packet(buf.data(), static_cast<size_t>(n), m));
  if (!fds.empty()) m.fd = std::move(fds.front());
  return m;
}

Status parse_packet(const char* data, size_t n, Message& m) {
  if (n > kHeaderSize + kMaxPayload)
    return Error(Code::corrupt_data, "oversized message (more than " + std::to_string(kMaxPayload) + " payload bytes)");
  if (n < kHeaderSize)
    return Error(Code::corrupt_data, "a " + std::to_string(n) + "-byte message, shorter than the header");
  uint32_t magic, seq, len;
  uint16_t version, type;
  std::memcpy(&magic, data, 4);
  std::memcpy(&version, data + 4, 2);
  std::memcpy(&type, data + 6, 2);
  std::memcpy(&seq, data + 8, 4);
  std::memcpy(&len, data + 12, 4);
  char hex[16];
  std::snprintf(hex, sizeof hex, "0x%08x", magic);
  if (magic != kMagic) return Error(Code::corrupt_data, std::string("bad magic ") + hex);
  if (version != kVersion)
    return Error(Code::corrupt_data, "protocol version " + std::to_string(version) + ", expected " +
                                         std::to_string(kVersion));
  if (len != n - kHeaderSize)
    return Error(Code::corrupt_data, "length field " + std::to_string(len) + " but " +
                                         std::to_string(n - kHeaderSize) + " payload bytes");
  m.type = type;
  m.seq = seq;
  m.payload.assign(data + kHeaderSize, len);
  return {};
}

// ---- memfd ----

Result<UniqueFd> make_sealed_blob(const std::string& bytes, const char* name) {
  UniqueFd fd(::memfd_create(name, MFD_CLOEXEC | MFD_ALLOW_SEALING));
  if (!fd) return Error(Code::unavailable, std::string("memfd_create: ") + std::strerror(errno));
  size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t w = ::write(fd.get(), bytes.data() + done, bytes.size() - done);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) return Error(Code::unavailable, std::string("writing a memfd: ") + std::strerror(errno));
    done += static_cast<size_t>(w);
  }
  if (::fcntl(fd.get(), F_ADD_SEALS, F_SEAL_SHRINK | F_SEAL_GROW | F_SEAL_WRITE | F_SEAL_SEAL) != 0)
    return Error(Code::unavailable, std::string("sealing a memfd: ") + std::strerror(errno));
  return fd;
}

Result<UniqueFd> make_sealed_blob(const std::function<void(Writer&)>& encode, const char* name) {
  Writer count = Writer::counting();
  encode(count);
  const size_t n = count.size();
  if (n > kMaxBlob)
    return Error(Code::invalid_argument, std::string(name) + " of " + std::to_string(n) + " bytes is over the " +
                                             std::to_string(kMaxBlob) + "-byte blob limit");
  UniqueFd fd(::memfd_create(name, MFD_CLOEXEC | MFD_ALLOW_SEALING));
  if (!fd) return Error(Code::unavailable, std::string("memfd_create: ") + std::strerror(errno));
  if (n > 0) {
    if (::ftruncate(fd.get(), static_cast<off_t>(n)) != 0)
      return Error(Code::unavailable, std::string("sizing a memfd: ") + std::strerror(errno));
    // MAP_POPULATE: the pages are allocated and mapped in one call instead
    // of one page fault each (costly in a VM; README.md "Process model").
    void* p = ::mmap(nullptr, n, PROT_READ | PROT_WRITE, MAP_SHARED | MAP_POPULATE, fd.get(), 0);
    if (p == MAP_FAILED) return Error(Code::unavailable, std::string("mmap of a memfd: ") + std::strerror(errno));
    Writer w(static_cast<char*>(p), n);
    encode(w);
    ::munmap(p, n);  // F_SEAL_WRITE needs no writable mapping left
    if (w.overflowed() || w.size() != n)
      return Error(Code::internal, std::string(name) + ": the encoder wrote " + std::to_string(w.size()) +
                                       " bytes after counting " + std::to_string(n));
  }
  if (::fcntl(fd.get(), F_ADD_SEALS, F_SEAL_SHRINK | F_SEAL_GROW | F_SEAL_WRITE | F_SEAL_SEAL) != 0)
    return Error(Code::unavailable, std::string("sealing a memfd: ") + std::strerror(errno));
  return fd;
}

Status check_fully_written(const struct stat& st, const char* what) {
  // Every byte was written, so every page exists: a memfd with holes (a
  // sparse one) would make this process allocate the pages it reads, up to
  // kMaxBlob, on the sender's say-so.
  const uint64_t page = static_cast<uint64_t>(::sysconf(_SC_PAGESIZE));
  const uint64_t pages = (static_cast<uint64_t>(st.st_size) + page - 1) / page;
  if (static_cast<uint64_t>(st.st_blocks) * 512 < pages * page)
    return Error(Code::corrupt_data, std::string(what) + " of " + std::to_string(st.st_size) + " bytes with only " +
                                         std::to_string(static_cast<uint64_t>(st.st_blocks) * 512) +
                                         " bytes written (a sparse memfd)");
  return {};
}

Result<Mapping> map_sealed_blob(int fd, size_t max_size) {
  const int seals = ::fcntl(fd, F_GET_SEALS);
  constexpr int need = F_SEAL_SHRINK | F_SEAL_GROW | F_SEAL_WRITE;
  if (seals < 0 || (seals & need) != need)
    return Error(Code::corrupt_data, "a data blob that is not a sealed memfd (it could change or shrink)");
  struct stat st {};
  if (::fstat(fd, &st) != 0 || st.st_size < 0 || static_cast<uint64_t>(st.st_size) > max_size)
    return Error(Code::corrupt_data, "a data blob of " + std::to_string(st.st_size) + " bytes, over the limit of " +
                                         std::to_string(max_size));
  if (st.st_size == 0) return Mapping();
  PROCAM_TRY(check_fully_written(st, "a data blob"));
  // Sealed and complete: MAP_POPULATE maps all pages at once (the reader
  // reads everything: checks, then copies to files).
  void* p = ::mmap(nullptr, static_cast<size_t>(st.st_size), PROT_READ, MAP_SHARED | MAP_POPULATE, fd, 0);
  if (p == MAP_FAILED) return Error(Code::unavailable, std::string("mmap of a data blob: ") + std::strerror(errno));
  return Mapping(p, static_cast<size_t>(st.st_size));
}

Result<FixedShared> make_fixed_shared(const char* name, uint64_t size, const char* what) {
  FixedShared out;
  out.fd = UniqueFd(::memfd_create(name, MFD_CLOEXEC | MFD_ALLOW_SEALING));
  if (!out.fd) return Error(Code::unavailable, std::string("memfd_create: ") + std::strerror(errno));
  if (::ftruncate(out.fd.get(), static_cast<off_t>(size)) != 0 ||
      ::fcntl(out.fd.get(), F_ADD_SEALS, F_SEAL_SHRINK | F_SEAL_GROW | F_SEAL_SEAL) != 0)
    return Error(Code::unavailable, std::string("sizing ") + what + ": " + std::strerror(errno));
  void* p = ::mmap(nullptr, size, PROT_READ | PROT_WRITE, MAP_SHARED | MAP_POPULATE, out.fd.get(), 0);
  if (p == MAP_FAILED) return Error(Code::unavailable, std::string("mmap of ") + what + ": " + std::strerror(errno));
  out.map = Mapping(p, size);
  return out;
}

Result<Ring> make_ring(uint32_t slots, uint64_t slot_size) {
  uint64_t total = 0;
  if (slots == 0 || __builtin_mul_overflow(uint64_t{slots}, slot_size, &total) || total > kMaxBlob)
    return Error(Code::invalid_argument, "frame ring of " + std::to_string(slots) + " x " +
                                             std::to_string(slot_size) + " bytes is too large");
  // Pre-faulted: every frame is copied into it, so all pages get touched anyway.
  auto shm = make_fixed_shared("procam-frames", total, "the frame ring");
  if (!shm) return shm.status();
  UniqueFd fd = std::move(shm->fd);
  Ring ring;
  ring.map = std::move(shm->map);
  ring.slots = slots;
  ring.slot_size = slot_size;
  // A read-only descriptor of the same memfd for the worker.
  const std::string self = "/proc/self/fd/" + std::to_string(fd.get());
  ring.worker_fd = UniqueFd(::open(self.c_str(), O_RDONLY | O_CLOEXEC));
  if (!ring.worker_fd)
    return Error(Code::unavailable, "cannot reopen the frame ring read-only (" + self + "): " + std::strerror(errno),
                 "procamd needs /proc mounted");
  return ring;
}

Result<Mapping> map_ring(int fd, uint32_t slots, uint64_t slot_size) {
  uint64_t total = 0;
  struct stat st {};
  if (slots == 0 || __builtin_mul_overflow(uint64_t{slots}, slot_size, &total) || total > kMaxBlob ||
      ::fstat(fd, &st) != 0 || static_cast<uint64_t>(st.st_size) < total)
    return Error(Code::corrupt_data, "frame ring descriptor does not hold " + std::to_string(slots) + " x " +
                                         std::to_string(slot_size) + " bytes");
  void* p = ::mmap(nullptr, total, PROT_READ, MAP_SHARED | MAP_POPULATE, fd, 0);
  if (p == MAP_FAILED) return Error(Code::unavailable, std::string("mmap of the frame ring: ") + std::strerror(errno));
  return Mapping(p, total);
}

// ---- blobs ----

namespace {

void put_image(Writer& w, const procam_image& v) {
  w.u32(v.width);
  w.u32(v.height);
  w.u32(v.channels);
  w.u32(v.pixel_type);
  w.u32(v.bit_depth);
  w.align(64);
  const size_t row = packed_row_bytes(v);
  for (uint32_t y = 0; y < v.height && row > 0; ++y)
    w.raw(static_cast<const uint8_t*>(v.data) + y * v.stride_bytes, row);
}

}  // namespace

// Blobs are read by a Reader that also knows where it is in the mapping, to
// align and to hand out views.
namespace {
class BlobIn {
public:
  explicit BlobIn(const Mapping& m) : BlobIn(m.data(), m.size()) {}
  BlobIn(const uint8_t* p, size_t n) : p_(p), n_(n), r_(p, n) {}
  Reader& r() { return r_; }
  bool ok() const { return r_.ok(); }
  std::string error() const { return r_.error(); }

  uint32_t u32(const char* w) { return sync(r_.u32(w), 4); }
  int32_t i32(const char* w) { return sync(r_.i32(w), 4); }
  uint64_t u64(const char* w) { return sync(r_.u64(w), 8); }
  double f64(const char* w) { return sync(r_.f64(w), 8); }
  const char* str(const char* w) {
    std::string_view s = r_.str(w);
    if (!r_.ok()) return "";
    pos_ += 4 + s.size() + 1;
    return s.data();
  }
  // Skips to a multiple of `a` and returns a pointer to `n` bytes there.
  const uint8_t* bytes(size_t a, size_t n, const char* what) {
    if (!r_.ok()) return nullptr;
    size_t p = (pos_ + a - 1) / a * a;
    if (p > n_ || n > n_ - p) {
      r_.fail(std::string("truncated: ") + what + " needs " + std::to_string(n) + " bytes at offset " +
              std::to_string(p) + " of a " + std::to_string(n_) + "-byte blob");
      return nullptr;
    }
    pos_ = p + n;
    r_ = Reader(p_ + pos_, n_ - pos_);
    return p_ + p;
  }
  procam_image image(const char* what) {
    procam_image v{};
    v.width = u32(what);
    v.height = u32(what);
    v.channels = u32(what);
    v.pixel_type = u32(what);
    v.bit_depth = u32(what);
    if (!ok()) return v;
    const size_t row = packed_row_bytes(v);
    size_t total = 0;
    if (row == 0 || __builtin_mul_overflow(row, size_t{v.height}, &total)) {
      // Let validate_view name the problem (zero size, unknown type); no data.
      r_.fail(std::string(what) + ": unknown pixel type or impossible size");
      return v;
    }
    v.stride_bytes = row;
    v.data = bytes(64, total, what);
    return v;
  }

private:
  template <class T>
  T sync(T v, size_t n) {
    if (r_.ok()) pos_ += n;
    return v;
  }
  const uint8_t* p_;
  size_t n_;
  size_t pos_ = 0;
  Reader r_{p_, n_};
};

Status blob_error(const char* what, const BlobIn& in) {
  return Error(Code::corrupt_data, std::string("malformed ") + what + " blob: " + in.error());
}

void put_settings(Writer& w, const procam_frame_settings& s) {
  w.u32(s.struct_size);
  w.i32(s.camera_index);
  w.f64(s.exposure_us);
  w.f64(s.gain_db);
  w.f64(s.projector_focus_mm);
  w.f64(s.polarizer_deg);
  w.f64(s.projector_polarizer_deg);
  w.i32(s.light_index);
}

}  // namespace

std::string encode_create(const CreateRequest& req) {
  Writer w;
  w.str(req.plugin_file);
  w.str(req.plugin_name);
  w.str(req.method);
  w.str(req.params);
  w.str(req.rig);
  w.u32(static_cast<uint32_t>(req.inputs.size()));
  for (const InputImage& in : req.inputs) {
    w.str(in.name);
    w.str(in.unit);
    w.str(in.description);
    put_image(w, in.image);
  }
  return std::move(w.bytes());
}

Status decode_create(const Mapping& blob, CreateRequest& out) {
  BlobIn in(blob);
  out.plugin_file = in.str("plugin file");
  out.plugin_name = in.str("plugin name");
  out.method = in.str("method");
  out.params = in.str("params");
  out.rig = in.str("rig");
  const uint32_t n = in.u32("input count");
  if (n > 1024) return Error(Code::corrupt_data, "create request with " + std::to_string(n) + " inputs");
  for (uint32_t i = 0; i < n && in.ok(); ++i) {
    InputImage im;
    im.name = in.str("input name");
    im.unit = in.str("input unit");
    im.description = in.str("input description");
    im.image = in.image("input image");
    out.inputs.push_back(std::move(im));
  }
  if (!in.ok()) return blob_error("create request", in);
  return {};
}

std::string encode_plan(const Plan& plan) {
  Writer w;
  write_plan(w, plan);
  return std::move(w.bytes());
}

void write_plan(Writer& w, const Plan& plan) {
  w.u32(static_cast<uint32_t>(plan.frames.size()));
  w.str(plan.note);
  for (const PlannedFrame& f : plan.frames) {
    w.str(f.label);
    put_settings(w, f.settings);
    put_image(w, f.pattern);
  }
}

Status decode_plan(const Mapping& blob, AbiPlan& out) {
  BlobIn in(blob);
  const uint32_t n = in.u32("frame count");
  if (n > 100000) return Error(Code::corrupt_data, "plan with " + std::to_string(n) + " frames");
  const char* note = in.str("note");
  out.frames.assign(n, procam_pattern_frame{});
  for (uint32_t i = 0; i < n && in.ok(); ++i) {
    procam_pattern_frame& f = out.frames[i];
    f.label = in.str("label");
    procam_frame_settings& s = f.settings;
    s.struct_size = in.u32("settings");
    s.camera_index = in.i32("settings");
    s.exposure_us = in.f64("settings");
    s.gain_db = in.f64("settings");
    s.projector_focus_mm = in.f64("settings");
    s.polarizer_deg = in.f64("settings");
    s.projector_polarizer_deg = in.f64("settings");
    s.light_index = in.i32("settings");
    f.pattern = in.image("pattern");
  }
  if (!in.ok()) return blob_error("plan", in);
  out.plan.frame_count = n;
  out.plan.frames = out.frames.data();
  out.plan.note = note;
  return {};
}

std::string encode_outputs(const std::vector<Output>& outputs) {
  Writer w;
  write_outputs(w, outputs);
  return std::move(w.bytes());
}

namespace {
// Offset of [p, p + n) in the heap when it lies wholly inside at an aligned
// offset; ~0 otherwise.
uint64_t heap_offset(const HeapSpan* heap, const void* p, uint64_t n) {
  if (heap == nullptr || heap->base == nullptr || p == nullptr || n == 0) return ~uint64_t{0};
  const auto* b = static_cast<const uint8_t*>(p);
  if (b < heap->base || b >= heap->base + heap->size) return ~uint64_t{0};
  const uint64_t off = static_cast<uint64_t>(b - heap->base);
  if (off % kHeapAlign != 0 || n > heap->size - off) return ~uint64_t{0};
  return off;
}
}  // namespace

void write_outputs(Writer& w, const std::vector<Output>& outputs, const HeapSpan* heap) {
  w.u32(static_cast<uint32_t>(outputs.size()));
  for (const Output& o : outputs) {
    w.str(o.name);
    // Bulk data already in the shared heap is named, not copied.
    uint64_t off = ~uint64_t{0};
    if (o.kind == PROCAM_OUTPUT_IMAGE) {
      const size_t row = packed_row_bytes(o.image);
      if (row != 0 && o.image.stride_bytes == row) off = heap_offset(heap, o.image.data, uint64_t{row} * o.image.height);
    } else if (o.kind == PROCAM_OUTPUT_POINTS) {
      off = heap_offset(heap, o.points, o.point_count * o.point_stride * sizeof(float));
    }
    const bool ref = off != ~uint64_t{0};
    w.u32(ref ? kHeapKind | static_cast<uint32_t>(o.kind) : static_cast<uint32_t>(o.kind));
    w.str(o.unit);
    w.str(o.description);
    switch (o.kind) {
      case PROCAM_OUTPUT_IMAGE:
        if (!ref) {
          put_image(w, o.image);
          break;
        }
        w.u32(o.image.width);
        w.u32(o.image.height);
        w.u32(o.image.channels);
        w.u32(o.image.pixel_type);
        w.u32(o.image.bit_depth);
        w.u64(off);
        break;
      case PROCAM_OUTPUT_SCALAR: w.f64(o.scalar); break;
      case PROCAM_OUTPUT_POINTS:
        w.u64(o.point_count);
        w.u32(o.point_stride);
        w.str(o.point_fields);
        if (ref) {
          w.u64(off);
          break;
        }
        w.align(4);
        w.raw(o.points, o.point_count * o.point_stride * sizeof(float));
        break;
      case PROCAM_OUTPUT_JSON: w.str(o.json); break;
      default: break;
    }
  }
}

Status decode_outputs(const Mapping& blob, std::vector<procam_output>& out) {
  return decode_outputs(blob.data(), blob.size(), out);
}

Status decode_outputs(const uint8_t* data, size_t size, std::vector<procam_output>& out, const HeapResolver& heap) {
  BlobIn in(data, size);
  const uint32_t n = in.u32("output count");
  if (n > 10000) return Error(Code::corrupt_data, std::to_string(n) + " outputs");
  out.assign(n, procam_output{});
  // A heap reference: `bytes` at the next u64's offset, through `heap`.
  const auto from_heap = [&](uint64_t bytes, const char* what) -> const uint8_t* {
    const uint64_t off = in.u64(what);
    if (!in.ok()) return nullptr;
    if (!heap) {
      in.r().fail(std::string(what) + " refers to a shared heap this reply may not use");
      return nullptr;
    }
    if (off % kHeapAlign != 0) {
      in.r().fail(std::string(what) + " at heap offset " + std::to_string(off) + ", not a multiple of " +
                  std::to_string(kHeapAlign));
      return nullptr;
    }
    std::string why;
    const uint8_t* p = heap(off, bytes, why);
    if (p == nullptr) in.r().fail(std::string(what) + ": " + why);
    return p;
  };
  for (uint32_t i = 0; i < n && in.ok(); ++i) {
    procam_output& o = out[i];
    o.name = in.str("output name");
    const uint32_t wire_kind = in.u32("output kind");
    const bool ref = (wire_kind & kHeapKind) != 0;
    o.kind = ref ? wire_kind & ~kHeapKind : wire_kind;
    o.unit = in.str("output unit");
    o.description = in.str("output description");
    switch (wire_kind) {
      case PROCAM_OUTPUT_IMAGE: o.image = in.image("output image"); break;
      case kHeapImage: {
        procam_image& v = o.image;
        v.width = in.u32("output image");
        v.height = in.u32("output image");
        v.channels = in.u32("output image");
        v.pixel_type = in.u32("output image");
        v.bit_depth = in.u32("output image");
        if (!in.ok()) break;
        const size_t row = packed_row_bytes(v);
        size_t total = 0;
        if (row == 0 || __builtin_mul_overflow(row, size_t{v.height}, &total)) {
          in.r().fail("output image: unknown pixel type or impossible size");
          break;
        }
        v.stride_bytes = row;
        v.data = from_heap(total, "output image");
        break;
      }
      case PROCAM_OUTPUT_SCALAR: o.scalar = in.f64("scalar"); break;
      case PROCAM_OUTPUT_POINTS:
      case kHeapPoints: {
        o.point_count = in.u64("point count");
        o.point_stride = in.u32("point stride");
        o.point_fields = in.str("point fields");
        uint64_t bytes = 0;
        if (o.point_stride > 1024 || __builtin_mul_overflow(o.point_count, uint64_t{o.point_stride} * 4, &bytes)) {
          in.r().fail("impossible point count");
          break;
        }
        o.points = reinterpret_cast<const float*>(ref ? from_heap(bytes, "points") : in.bytes(4, bytes, "points"));
        break;
      }
      case PROCAM_OUTPUT_JSON: o.json = in.str("json"); break;
      default: in.r().fail("unknown output kind " + std::to_string(wire_kind));
    }
  }
  if (!in.ok()) return blob_error("outputs", in);
  return {};
}

std::string encode_end_round(uint8_t ahead) { return ahead == 0 ? std::string() : std::string(1, static_cast<char>(ahead)); }

Status decode_end_round(std::string_view payload, uint8_t& ahead) {
  ahead = 0;
  if (payload.empty()) return {};
  if (payload.size() != 1 || static_cast<uint8_t>(payload[0]) > kMaxAhead)
    return Error(Code::invalid_argument,
                 "malformed end_round: " + (payload.size() != 1 ? std::to_string(payload.size()) + " payload bytes"
                                                                : "ahead " + std::to_string(static_cast<uint8_t>(payload[0]))) +
                     ", expected none or one byte of 0.." + std::to_string(kMaxAhead));
  ahead = static_cast<uint8_t>(payload[0]);
  return {};
}

std::string encode_error(const Status& st) {
  Writer w;
  w.u32(static_cast<uint32_t>(st.code()));
  // Keep the reply under the control-message limit.
  w.str(st.message().substr(0, kMaxPayload / 2));
  w.str(st.hint().substr(0, kMaxPayload / 4));
  return std::move(w.bytes());
}

Status decode_error(std::string_view payload, Status& out) {
  Reader r(reinterpret_cast<const uint8_t*>(payload.data()), payload.size());
  const uint32_t code = r.u32("error code");
  const std::string message(r.str("error message"));
  const std::string hint(r.str("error hint"));
  if (!r.ok() || !r.at_end()) return Error(Code::corrupt_data, "malformed error reply: " + r.error());
  const bool known = code > static_cast<uint32_t>(Code::ok) && code <= static_cast<uint32_t>(Code::internal);
  out = Error(known ? static_cast<Code>(code) : Code::plugin_error, message, hint);
  return {};
}

}  // namespace procam::host::wire
