#include "backends/cuda/svgf_device.h"

#include <array>
#include <chrono>
#include <cstring>
#include <utility>

#include "backends/cuda/device_launch.h"
#include "core/util/log.h"

namespace tandem {

struct DeviceSvgf::Impl {
  std::shared_ptr<DeviceOps> dev;
  DeviceStreamOwner stream;
  size_t pixels = 0;  // what the buffers below are sized for
  DeviceBuffer features, prev_features, radiance, output, slope, guide, material, prev_color,
      prev_moments, history, moments, a, b;
  DeviceBuffer host;  // pinned: the inputs on their way, then the outputs

  explicit Impl(std::shared_ptr<DeviceOps> d) : dev(std::move(d)), stream(*dev) {
    for (DeviceBuffer* buffer : device_buffers())
      *buffer = DeviceBuffer(*dev, DeviceBuffer::kDevice);
    host = DeviceBuffer(*dev, DeviceBuffer::kPinned);
  }

  std::array<DeviceBuffer*, 13> device_buffers() {
    return {&features,   &prev_features, &radiance, &output,  &slope, &guide, &material,
            &prev_color, &prev_moments,  &history,  &moments, &a,     &b};
  }

  // Sizes every buffer for n pixels (a new size drops the old buffers).
  void resize(size_t n) {
    if (n == pixels) return;
    pixels = 0;  // until every buffer exists
    features.allocate(n * sizeof(PixelFeatures));
    prev_features.allocate(n * sizeof(PixelFeatures));
    radiance.allocate(n * sizeof(Vec3));
    output.allocate(n * sizeof(Vec3));
    slope.allocate(n * sizeof(Vec2));
    guide.allocate(n * sizeof(SvgfGuide));
    material.allocate(n * sizeof(uint32_t));
    for (DeviceBuffer* v : {&prev_color, &prev_moments, &history, &moments, &a, &b})
      v->allocate(n * sizeof(Vec4));
    host.allocate(n * (2 * sizeof(PixelFeatures) + sizeof(Vec3) + 2 * sizeof(Vec4)));
    pixels = n;
  }
};

DeviceSvgf::DeviceSvgf(std::shared_ptr<DeviceOps> device)
    : impl_(std::make_unique<Impl>(std::move(device))) {}

DeviceSvgf::~DeviceSvgf() {
  try {
    impl_->dev->synchronize(impl_->stream.get());
  } catch (...) {  // a failed device: nothing to wait for
  }
}

SvgfStageSeconds DeviceSvgf::run(const SvgfParams& p, const SvgfFrame& fr) {
  SvgfStageSeconds t;
  const size_t n = size_t(p.width) * p.height;
  if (n == 0) return t;
  const auto start = std::chrono::steady_clock::now();
  Impl& m = *impl_;
  DeviceOps& dev = *m.dev;
  const DeviceStream s = m.stream.get();
  m.resize(n);
  // The inputs, packed into the pinned buffer and sent.
  auto* host = m.host.as<unsigned char>();
  size_t offset = 0;
  auto send = [&](DeviceBuffer& dst, const void* src, size_t bytes) {
    std::memcpy(host + offset, src, bytes);
    dev.copy_to_device(dst.get(), host + offset, bytes, s);
    offset += bytes;
  };
  send(m.features, fr.features, n * sizeof(PixelFeatures));
  send(m.radiance, fr.radiance, n * sizeof(Vec3));
  if (fr.prev_features) {
    send(m.prev_features, fr.prev_features, n * sizeof(PixelFeatures));
    send(m.prev_color, fr.prev_color, n * sizeof(Vec4));
    send(m.prev_moments, fr.prev_moments, n * sizeof(Vec4));
  }
  const LaunchDims dims = svgf_launch_dims(p.width, p.height);
  const SvgfTemporalBuffers tb{m.features.as<PixelFeatures>(),
                               m.radiance.as<Vec3>(),
                               fr.prev_features ? m.prev_features.as<PixelFeatures>() : nullptr,
                               m.prev_color.as<Vec4>(),
                               m.prev_moments.as<Vec4>(),
                               m.a.as<Vec4>(),
                               m.moments.as<Vec4>(),
                               m.slope.as<Vec2>(),
                               m.guide.as<SvgfGuide>(),
                               m.material.as<uint32_t>()};
  launch_kernel<SvgfTemporal>(dev, dims, SvgfTemporalArgs{p, tb}, s);
  launch_kernel<SvgfVariance>(
      dev, dims,
      SvgfVarianceArgs{p, SvgfVarianceBuffers{m.guide.as<SvgfGuide>(), m.material.as<uint32_t>(),
                                              m.slope.as<Vec2>(), m.a.as<Vec4>(),
                                              m.moments.as<Vec4>(), m.b.as<Vec4>()}},
      s);
  // The ping-pong of svgf_run_cpu: b -> history -> a -> b -> ...
  const Vec4* in = m.b.as<Vec4>();
  for (uint32_t it = 0; it < p.iterations; ++it) {
    const bool last = it + 1 == p.iterations;
    Vec4* out = it == 0
                    ? m.history.as<Vec4>()
                    : (last ? nullptr : (in == m.a.as<Vec4>() ? m.b.as<Vec4>() : m.a.as<Vec4>()));
    SvgfAtrousArgs args{p,
                        SvgfAtrousBuffers{m.guide.as<SvgfGuide>(), m.material.as<uint32_t>(),
                                          m.slope.as<Vec2>(), in},
                        out,
                        m.features.as<PixelFeatures>(),
                        last ? m.output.as<Vec3>() : nullptr,
                        1u << it};
    launch_kernel<SvgfAtrous>(dev, dims, args, s);
    in = out;
  }
  if (p.iterations == 0) {
    launch_kernel<SvgfModulate>(
        dev, dims,
        SvgfModulateArgs{p, m.features.as<PixelFeatures>(), m.b.as<Vec4>(), m.output.as<Vec3>()},
        s);
  }
  // The outputs come back through the same pinned buffer, after the
  // kernels that read its inputs' device copies (stream order).
  const Vec4* history = p.iterations == 0 ? m.b.as<Vec4>() : m.history.as<Vec4>();
  dev.copy_to_host(host, history, n * sizeof(Vec4), s);
  dev.copy_to_host(host + n * sizeof(Vec4), m.moments.get(), n * sizeof(Vec4), s);
  dev.copy_to_host(host + 2 * n * sizeof(Vec4), m.output.get(), n * sizeof(Vec3), s);
  dev.synchronize(s);
  std::memcpy(fr.history_color_out, host, n * sizeof(Vec4));
  std::memcpy(fr.moments_out, host + n * sizeof(Vec4), n * sizeof(Vec4));
  std::memcpy(fr.output, host + 2 * n * sizeof(Vec4), n * sizeof(Vec3));
  t.atrous = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return t;
}

namespace {

class DeviceSvgfOffload final : public SvgfOffload {
 public:
  explicit DeviceSvgfOffload(std::shared_ptr<DeviceOps> device)
      : name_(device->name()), filter_(std::make_unique<DeviceSvgf>(std::move(device))) {}

  bool run(const SvgfParams& params, const SvgfFrame& frame, SvgfStageSeconds* seconds) override {
    if (!filter_) return false;
    try {
      *seconds = filter_->run(params, frame);
      return true;
    } catch (const DeviceError& e) {
      log_warning("the denoiser's device (" + name_ + ") failed (" + e.what() +
                  "); denoising on the CPU from now on");
      filter_.reset();
      return false;
    }
  }

 private:
  std::string name_;
  std::unique_ptr<DeviceSvgf> filter_;
};

}  // namespace

std::shared_ptr<SvgfOffload> make_device_svgf_offload(std::shared_ptr<DeviceOps> device) {
  return std::make_shared<DeviceSvgfOffload>(std::move(device));
}

}  // namespace tandem
