#include "backends/cuda/device_scene.h"

#include <algorithm>
#include <cstring>
#include <stdexcept>

namespace tandem {

namespace {

// Staging offsets keep every array's 16-byte alignment (Vec4, KBvhNode).
constexpr size_t kStagingAlign = 16;
// Pinned memory is slow to allocate: chunks of at least this much.
constexpr size_t kMinStagingChunk = size_t(1) << 20;
size_t align_up(size_t n) {
  return (n + kStagingAlign - 1) & ~(kStagingAlign - 1);
}

}  // namespace

DeviceScene::DeviceScene(DeviceOps& ops) : ops_(ops), copy_stream_(ops) {
  for (BufferSet& set : sets_) {
    set.uploaded = DeviceEventOwner(ops, true);
    set.rendered = DeviceEventOwner(ops, false);
    set.copy_begin = DeviceEventOwner(ops, true);
    set.ready = DeviceEventOwner(ops, true);
    set.d_view = DeviceBuffer(ops, DeviceBuffer::kDevice);
    set.d_view.allocate(sizeof(KernelData));
  }
}

DeviceScene::~DeviceScene() {
  // Destructors must not throw: errors here (a lost device) are ignored,
  // the memory is being abandoned anyway.
  for (BufferSet& set : sets_) {
    for (DeviceEvent e : {set.rendered.get(), set.uploaded.get()}) {
      try {
        ops_.synchronize(e);
      } catch (...) {
      }
    }
    release_buffers(set);
  }
}

void DeviceScene::release_buffers(BufferSet& set) noexcept {
  for (void*& b : set.buffers) {
    if (!b) continue;
    try {
      ops_.free_async(b, copy_stream_.get());
    } catch (...) {
    }
    b = nullptr;
  }
  set.view = KernelData{};
}

size_t DeviceScene::commit(const KernelScene& ks, const KernelChangeLog& log) {
  std::lock_guard<std::mutex> lock(mutex_);
  return commit_locked(ks, log);
}

size_t DeviceScene::commit(const KernelScene& ks, const SceneDelta& delta) {
  std::lock_guard<std::mutex> lock(mutex_);
  own_log_.append(delta);
  return commit_locked(ks, own_log_);
}

void DeviceScene::forget_generations() {
  std::lock_guard<std::mutex> lock(mutex_);
  commits_.forget_generations();
}

size_t DeviceScene::commit_locked(const KernelScene& ks, const KernelChangeLog& log) {
  const uint32_t newest = commits_.current_set();
  const bool amend = commits_.has_committed() && !sets_[newest].claimed;
  const uint32_t target = amend ? newest : (newest + 1) % DoubleBufferedCommits::kSets;
  BufferSet& set = sets_[target];
  if (set.readers > 0) {
    throw std::logic_error(
        "DeviceScene::commit: both buffer sets are being rendered from; at most one render may "
        "be in flight while committing");
  }
  const CommitPlan plan = commits_.plan(ks, target, log);
  try {
    upload(set, plan, ks);
  } catch (...) {
    // Part of the plan may have reached the device, part not, and buffers
    // may have been reallocated: start the set over, once the last render
    // that read it is done (the failed commit may not have queued its wait).
    try {
      ops_.synchronize(set.rendered.get());
    } catch (...) {
    }
    release_buffers(set);
    commits_.invalidate(target);
    set.timing_pending = false;
    throw;
  }
  commits_.complete(plan);
  // The set now holds a frame no render has claimed: a second commit before
  // one does amends it, and the first render to claim it records `ready`.
  set.claimed = false;
  last_commit_bytes_ = plan.total_bytes();
  return last_commit_bytes_;
}

void DeviceScene::upload(BufferSet& set, const CommitPlan& plan, const KernelScene& ks) {
  const DeviceStream copy = copy_stream_.get();
  // The host is about to overwrite this set's staging buffer.
  ops_.synchronize(set.uploaded.get());
  // Renders that read this set must finish before we overwrite it.
  ops_.wait(copy, set.rendered.get());
  if (!set.timing_pending) {
    ops_.record(set.copy_begin.get(), copy);
    set.timing_pending = true;
  }

  // Reallocations first (stream-ordered, so no device-wide sync as with a
  // plain free, and the other set keeps rendering meanwhile).
  for (const ArrayCopy& c : plan.copies) {
    if (c.new_capacity == 0) continue;
    void*& buffer = set.buffers[c.array];
    if (buffer) ops_.free_async(buffer, copy);
    buffer = nullptr;
    buffer = ops_.alloc_async(c.new_capacity * kernel_array_element_size(c.array), copy);
  }
  for (const ArrayCopy& c : plan.copies) {
    if (c.resize) set_kernel_array_view(set.view, c.array, set.buffers[c.array], c.count);
  }
  set.view.constants = ks.constants;
  set.view.bvh = ks.bvh;

  // Pack every range into the staging chunks, then send each piece with one
  // copy (a range that crosses from one chunk into the next is two pieces).
  size_t staging_bytes = plan.view_changed ? align_up(sizeof(KernelData)) : 0;
  for (const ArrayCopy& c : plan.copies)
    staging_bytes += align_up(c.bytes());
  set.staging.reserve(ops_, staging_bytes);
  size_t chunk = 0, offset = 0;
  auto send = [&](void* device_dst, const void* host_src, size_t n) {
    auto* dst = static_cast<unsigned char*>(device_dst);
    const auto* src = static_cast<const unsigned char*>(host_src);
    while (n > 0) {
      if (chunk == set.staging.chunks.size())
        throw std::logic_error("DeviceScene: staging chunks smaller than the commit");
      DeviceBuffer& b = set.staging.chunks[chunk];
      const size_t piece = std::min(n, b.bytes() - offset);
      auto* packed = b.as<unsigned char>() + offset;
      std::memcpy(packed, src, piece);
      ops_.copy_to_device(dst, packed, piece, copy);
      dst += piece;
      src += piece;
      n -= piece;
      offset = std::min(b.bytes(), align_up(offset + piece));
      if (offset == b.bytes()) {
        ++chunk;
        offset = 0;
      }
    }
  };
  for (const ArrayCopy& c : plan.copies) {
    if (c.bytes() == 0) continue;
    const size_t elem = kernel_array_element_size(c.array);
    const auto* src = static_cast<const unsigned char*>(kernel_array_host_data(ks, c.array));
    send(static_cast<unsigned char*>(set.buffers[c.array]) + size_t(c.begin) * elem,
         src + size_t(c.begin) * elem, c.bytes());
  }
  if (plan.view_changed) send(set.d_view.get(), &set.view, sizeof(KernelData));
  ops_.record(set.uploaded.get(), copy);
}

void DeviceScene::Staging::reserve(DeviceOps& ops, size_t bytes) {
  // The packing may skip up to kStagingAlign - 1 bytes at the end of each
  // chunk; one more chunk of what is missing (and at least half of what
  // there is, so that a slowly growing scene adds few chunks) covers it.
  const size_t needed = bytes + chunks.size() * kStagingAlign;
  if (needed <= capacity) return;
  const size_t add = std::max({needed - capacity + kStagingAlign, capacity / 2, kMinStagingChunk});
  DeviceBuffer chunk(ops, DeviceBuffer::kPinned);
  chunk.allocate(add);
  chunks.push_back(std::move(chunk));
  capacity += add;
}

size_t DeviceScene::last_commit_bytes() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return last_commit_bytes_;
}

DeviceScene::RenderTicket DeviceScene::begin_render(DeviceStream stream) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!commits_.has_committed())
    throw std::logic_error("cuda backend: render before a successful sync()");
  const uint32_t s = commits_.current_set();
  BufferSet& set = sets_[s];
  // When the stream could start on this frame, were the upload not in the
  // way: what the commit's copy time is measured against (by the first
  // render after the commit; later ones find the copies long done).
  if (!set.claimed) ops_.record(set.ready.get(), stream);
  ops_.wait(stream, set.uploaded.get());
  set.claimed = true;
  ++set.readers;
  const KernelConstants& k = set.view.constants;
  return RenderTicket{s, set.d_view.as<const KernelData>(), k.camera.width, k.camera.height,
                      k.integrator.max_depth + 1};
}

void DeviceScene::end_render(const RenderTicket& ticket, DeviceStream stream) {
  std::lock_guard<std::mutex> lock(mutex_);
  BufferSet& set = sets_[ticket.set];
  if (set.readers > 0) --set.readers;
  ops_.record(set.rendered.get(), stream);
}

DeviceScene::CommitTiming DeviceScene::take_timing(const RenderTicket& ticket) {
  std::lock_guard<std::mutex> lock(mutex_);
  BufferSet& set = sets_[ticket.set];
  CommitTiming t;
  if (!set.timing_pending) return t;
  set.timing_pending = false;
  t.copy_seconds = std::max(0.0, ops_.elapsed_seconds(set.copy_begin.get(), set.uploaded.get()));
  const double before_ready = ops_.elapsed_seconds(set.copy_begin.get(), set.ready.get());
  t.hidden_seconds = std::clamp(before_ready, 0.0, t.copy_seconds);
  return t;
}

bool DeviceScene::ready() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return commits_.has_committed();
}

uint32_t DeviceScene::newest_set() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return commits_.current_set();
}

size_t DeviceScene::device_bytes() const {
  std::lock_guard<std::mutex> lock(mutex_);
  size_t total = 0;
  for (uint32_t s = 0; s < DoubleBufferedCommits::kSets; ++s)
    for (uint32_t a = 0; a < kKernelArrayCount; ++a)
      total += commits_.capacity(s, a) * kernel_array_element_size(a);
  return total;
}

void DeviceScene::synchronize() {
  ops_.synchronize(copy_stream_.get());
}

std::vector<std::vector<uint8_t>> DeviceScene::read_back(uint32_t s) {
  std::lock_guard<std::mutex> lock(mutex_);
  const DeviceStream copy = copy_stream_.get();
  const BufferSet& set = sets_[s];
  std::vector<std::vector<uint8_t>> out(kKernelArrayCount);
  std::vector<DeviceBuffer> landing;
  for (uint32_t a = 0; a < kKernelArrayCount; ++a) {
    const size_t bytes = size_t(commits_.count(s, a)) * kernel_array_element_size(a);
    landing.emplace_back(ops_, DeviceBuffer::kPinned);
    if (bytes == 0) continue;
    landing.back().allocate(bytes);
    ops_.copy_to_host(landing.back().get(), set.buffers[a], bytes, copy);
  }
  ops_.synchronize(copy);
  for (uint32_t a = 0; a < kKernelArrayCount; ++a) {
    const size_t bytes = size_t(commits_.count(s, a)) * kernel_array_element_size(a);
    const auto* p = landing[a].as<const uint8_t>();
    if (bytes) out[a].assign(p, p + bytes);
  }
  return out;
}

}  // namespace tandem
