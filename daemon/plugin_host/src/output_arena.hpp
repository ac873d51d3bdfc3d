// SPDX-License-Identifier: MIT
// Outputs without a fresh memfd per scan (WORKER_PROTOCOL.md "Output arena",
// README.md "Speed"): the worker keeps one grow-only shared-memory arena and
// encodes each session's outputs into it; the daemon maps the arena once and,
// at each get_outputs reply, copies the used bytes into its own grow-only
// buffer before decoding and checking them.
//
// Why a copy on the daemon side: the worker keeps a writable mapping of the
// arena (it is reused), and no seal can take that away from a live mapping,
// so a plugin thread could change bytes after the reply. The daemon decodes,
// checks and hands out only its private copy, taken once per reply: what it
// returned cannot change underneath its client, and the header (counts,
// sizes, offsets) is read from the copy, never twice from shared memory.
// Both buffers are warm after the first scan of a reused worker, so the
// kernel's zeroing and page faults of a fresh 32 MB memfd per scan (the cost
// this replaces) are gone; what remains is two memcpys (worker: maps ->
// arena; daemon: arena -> copy).
//
// When the worker can be frozen (WorkerProxy::freeze: stopped with SIGSTOP,
// its sandbox keeping anything else from writing the arena or resuming it;
// README.md "Speed") the daemon decodes and hands out views into the arena
// itself (view()) until it resumes the worker at the session's end: then the
// copy above is not taken. Maps the plugin allocated in the worker's shared
// heap (worker/shared_heap.hpp) are not in the arena at all then: the reply
// names them and the daemon reads them in the heap (heap_in_place()), so no
// output byte is copied on either side.
//
// Ownership: OutputArena belongs to the worker (one per process, kept across
// sessions); OutputSnapshot to one WorkerProxy (kept across the sessions of a
// reused worker). The views into OutputSnapshot::data() are valid until the
// next take() or destruction.
// Threads: one thread at a time each. Errors: Status, nothing throws except
// std::bad_alloc.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "procam/core/status.hpp"
#include "worker_wire.hpp"

namespace procam::host::wire {

// Worker side.
class OutputArena {
public:
  struct Written {
    uint64_t used = 0;  // bytes of this reply, from offset 0
    int new_fd = -1;    // the arena's descriptor when it is new (send it), else -1
  };
  // Counts what `encode` writes, grows the arena if it does not fit (a new
  // memfd of 5/4 the size, sealed against shrinking, pre-faulted), then
  // encodes into it. `encode` must write the same bytes both times.
  Result<Written> write(const std::function<void(Writer&)>& encode);
  uint64_t capacity() const { return map_.size(); }

private:
  UniqueFd fd_;
  Mapping map_;  // read-write, shared
};

// Daemon side.
class OutputSnapshot {
public:
  OutputSnapshot() = default;
  ~OutputSnapshot();  // the copy buffer goes to a small daemon-wide spare list
  OutputSnapshot(const OutputSnapshot&) = delete;
  OutputSnapshot& operator=(const OutputSnapshot&) = delete;
  // A new arena from the worker: it must be a memfd sealed against
  // shrinking (so a mapped page never vanishes: no SIGBUS), at most
  // kMaxBlob bytes, fully written (no holes), then it is mapped read-only.
  // A worker that punches holes later (only one without the default
  // sandbox: its seccomp filter denies that, hello flag 256) makes take()
  // read zero pages, which the kernel allocates: at most the arena's size,
  // which it had allocated itself when it was adopted; the decode checks
  // catch the zeros.
  Status adopt(int fd);
  // Copies bytes [0, used) of the arena into the private buffer (grown as
  // needed); corrupt_data if no arena was adopted or `used` is beyond it.
  Status take(uint64_t used);
  // Bytes [0, used) of the arena itself, no copy: only while the worker
  // cannot run (the daemon froze it, WorkerProxy::freeze), until it is
  // resumed. Same checks as take().
  Status view(uint64_t used);
  const uint8_t* data() const { return data_; }
  uint64_t size() const { return used_; }
  bool has_arena() const { return arena_.size() > 0; }

  // The worker's shared heap (WORKER_PROTOCOL.md "Shared heap"), sent with
  // its hello: a memfd sealed against shrinking and growing, at most
  // kMaxBlob bytes, mapped read-only once and not pre-faulted (it is
  // sparse: only what the plugin allocated has pages).
  Status adopt_heap(int fd);
  bool has_heap() const { return heap_.size() > 0; }
  // Resolvers for decode_outputs' heap references. In place: views into
  // the heap itself, only while the worker is frozen (as view()). Copied:
  // each referenced range copied into private memory now, valid until the
  // next take()/view(). Both check the range against the heap and that
  // every page of it was written (mincore, then SEEK_DATA for pages not
  // resident: a hole would make this process allocate what it reads).
  HeapResolver heap_in_place();
  HeapResolver heap_copied();
  // True only when the worker cannot remove pages from its heap (its
  // sandbox denies it: hello's kSandboxPagesStay): a page found written
  // once stays written, and the resolvers check only pages not checked
  // before (~0.1 ms less per outputs reply of 32 MB on the project's VM).
  void set_pages_stay(bool stay) { pages_stay_ = stay; }
  bool pages_stay() const { return pages_stay_; }

private:
  const uint8_t* heap_range(uint64_t offset, uint64_t bytes, std::string& why);
  Mapping arena_;  // read-only, shared with the worker
  Mapping copy_;   // private, anonymous, grow-only
  UniqueFd heap_fd_;
  Mapping heap_;                    // read-only, shared with the worker
  std::vector<Mapping> heap_copies_;  // heap_copied()'s ranges
  std::vector<uint8_t> populated_;    // per heap page: checked written and mapped here (heap_range)
  bool pages_stay_ = false;           // set_pages_stay
  const uint8_t* data_ = nullptr;  // copy_ after take(), arena_ after view()
  uint64_t used_ = 0;
};

}  // namespace procam::host::wire
