#include "backends/cuda/device_scene.h"

#include <cstring>
#include <vector>

#include "backends/cuda/cuda_check.h"

namespace tandem {

namespace {

// Staging offsets keep every array's 16-byte alignment (Vec4, KBvhNode).
constexpr size_t kStagingAlign = 16;
size_t align_up(size_t n) {
  return (n + kStagingAlign - 1) & ~(kStagingAlign - 1);
}

}  // namespace

DeviceScene::DeviceScene() {
  TANDEM_CUDA_CHECK(cudaStreamCreateWithFlags(&copy_stream_, cudaStreamNonBlocking));
  for (BufferSet& set : sets_) {
    TANDEM_CUDA_CHECK(cudaEventCreateWithFlags(&set.uploaded, cudaEventDisableTiming));
    TANDEM_CUDA_CHECK(cudaEventCreateWithFlags(&set.rendered, cudaEventDisableTiming));
    TANDEM_CUDA_CHECK(cudaMalloc(reinterpret_cast<void**>(&set.d_view), sizeof(KernelData)));
  }
}

DeviceScene::~DeviceScene() {
  // Destructors must not throw: errors here (a lost device) are ignored,
  // the process is releasing the memory anyway.
  cudaStreamSynchronize(copy_stream_);
  for (BufferSet& set : sets_) {
    for (void* b : set.buffers)
      cudaFree(b);
    cudaFree(set.d_view);
    cudaFreeHost(set.staging);
    cudaEventDestroy(set.uploaded);
    cudaEventDestroy(set.rendered);
  }
  cudaStreamDestroy(copy_stream_);
}

void DeviceScene::reserve_staging(BufferSet& set, size_t bytes) {
  if (bytes <= set.staging_capacity) return;
  // The caller has waited for the set's previous upload: no copy reads it.
  TANDEM_CUDA_CHECK(cudaFreeHost(set.staging));
  set.staging = nullptr;
  set.staging_capacity = 0;
  const size_t capacity = bytes + bytes / 4;
  TANDEM_CUDA_CHECK(cudaMallocHost(&set.staging, capacity));
  set.staging_capacity = capacity;
}

size_t DeviceScene::commit(const KernelScene& ks, const SceneDelta& delta) {
  const CommitPlan plan = commits_.plan(ks, delta);
  BufferSet& set = sets_[plan.set];

  // The host is about to overwrite this set's staging buffer.
  TANDEM_CUDA_CHECK(cudaEventSynchronize(set.uploaded));
  // Frames that rendered from this set must finish before we overwrite it.
  TANDEM_CUDA_CHECK(cudaStreamWaitEvent(copy_stream_, set.rendered, 0));

  // Reallocations first (stream-ordered, so no device-wide sync as with
  // cudaFree, and the other set keeps rendering meanwhile).
  for (const ArrayCopy& c : plan.copies) {
    if (c.new_capacity == 0) continue;
    void*& buffer = set.buffers[c.array];
    if (buffer) TANDEM_CUDA_CHECK(cudaFreeAsync(buffer, copy_stream_));
    buffer = nullptr;
    TANDEM_CUDA_CHECK(cudaMallocAsync(&buffer, c.new_capacity * kernel_array_element_size(c.array),
                                      copy_stream_));
  }
  for (const ArrayCopy& c : plan.copies) {
    if (c.resize) set_kernel_array_view(set.view, c.array, set.buffers[c.array], c.count);
  }
  set.view.constants = ks.constants;

  // Pack every range into the staging buffer, then send each with one copy.
  size_t staging_bytes = plan.view_changed ? align_up(sizeof(KernelData)) : 0;
  for (const ArrayCopy& c : plan.copies)
    staging_bytes += align_up(c.bytes());
  reserve_staging(set, staging_bytes);
  auto* staging = static_cast<unsigned char*>(set.staging);
  size_t offset = 0;
  for (const ArrayCopy& c : plan.copies) {
    const size_t n = c.bytes();
    if (n == 0) continue;
    const size_t elem = kernel_array_element_size(c.array);
    const auto* src = static_cast<const unsigned char*>(kernel_array_host_data(ks, c.array));
    std::memcpy(staging + offset, src + size_t(c.begin) * elem, n);
    auto* dst = static_cast<unsigned char*>(set.buffers[c.array]) + size_t(c.begin) * elem;
    TANDEM_CUDA_CHECK(
        cudaMemcpyAsync(dst, staging + offset, n, cudaMemcpyHostToDevice, copy_stream_));
    offset += align_up(n);
  }
  if (plan.view_changed) {
    std::memcpy(staging + offset, &set.view, sizeof(KernelData));
    TANDEM_CUDA_CHECK(cudaMemcpyAsync(set.d_view, staging + offset, sizeof(KernelData),
                                      cudaMemcpyHostToDevice, copy_stream_));
  }
  TANDEM_CUDA_CHECK(cudaEventRecord(set.uploaded, copy_stream_));
  last_commit_bytes_ = plan.total_bytes();
  return last_commit_bytes_;
}

const KernelData* DeviceScene::begin_render(cudaStream_t stream) {
  BufferSet& set = sets_[commits_.current_set()];
  TANDEM_CUDA_CHECK(cudaStreamWaitEvent(stream, set.uploaded, 0));
  return set.d_view;
}

void DeviceScene::end_render(cudaStream_t stream) {
  TANDEM_CUDA_CHECK(cudaEventRecord(sets_[commits_.current_set()].rendered, stream));
}

size_t DeviceScene::device_bytes() const {
  size_t total = 0;
  for (uint32_t s = 0; s < DoubleBufferedCommits::kSets; ++s)
    for (uint32_t a = 0; a < kKernelArrayCount; ++a)
      total += commits_.capacity(s, a) * kernel_array_element_size(a);
  return total;
}

void DeviceScene::synchronize() {
  TANDEM_CUDA_CHECK(cudaStreamSynchronize(copy_stream_));
}

}  // namespace tandem
