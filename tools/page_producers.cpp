#include "tools/page_producers.h"

#include <algorithm>
#include <atomic>
#include <thread>
#include <vector>

#include "compose/reference_compositor.h"
#include "api/compose/page_composer_access.h"
#include "compose/scene_identity.h"
#include "tools/cli_common.h"

namespace tvt::cli {

Result<std::unique_ptr<PageProducers>> PageProducers::create(const SceneAssets& assets, Method method,
                                                             MipStrategy strategy, bool cpu, const std::string& gpu_name,
                                                             vk::Context* context) {
  std::unique_ptr<PageProducers> p(new PageProducers());
  p->assets_ = &assets;
  p->method_ = method;
  p->strategy_ = strategy;
  p->cpu_ = cpu;
  auto packed = pack_scene(assets, options_for(method, strategy));
  if (!packed) return packed.error();
  p->packed_ = std::move(packed.value());
  if (cpu) {
    p->device_name_ = "cpu-reference";
    return p;
  }
  if (!context) {
    auto ctx = gpu_context(gpu_name);
    if (!ctx) return make_error(ctx.error().message + " (use --cpu for the CPU reference)");
    p->context_ = std::move(ctx.value());
    context = p->context_.get();
  }
  p->device_name_ = context->device_name();
  auto handles = context->device_handles();
  if (!handles) return handles.error();
  auto composer = terravt::detail::ComposeAccess::make_page_composer(handles.value(), assets, method, strategy, 32);
  if (!composer) return composer.error();
  p->composer_ = std::move(composer.value());
  return p;
}

StoreDesc PageProducers::store_desc(int level) const {
  StoreDesc d;
  d.vt = assets_->desc.vt;
  d.scene_hash = scene_identity(assets_->desc, method_, strategy_);
  // The device is part of the producer: fp32 results may differ between GPUs, so parts baked on
  // different devices must not be merged into one store.
  d.producer = (cpu_ ? std::string("cpu") : std::string("gpu")) + " " + std::string(to_string(method_)) + " " +
               (!strategy_.direct() ? to_string(strategy_) + " " : std::string()) + device_name_;
  if (d.producer.size() > 63) d.producer.resize(63);
  d.zstd_level = level;
  return d;
}

GpuComposer* PageProducers::composer() {
  return composer_ ? &terravt::detail::ComposeAccess::composer(*composer_) : nullptr;
}

PageSource PageProducers::source() {
  if (!cpu_)
    return [this](std::span<const PageId> pages, std::vector<std::vector<uint8_t>>& out) -> Status {
      std::vector<terravt::PageRequest> requests;
      requests.reserve(pages.size());
      for (const PageId& p : pages) requests.push_back({p.mip, p.x, p.y, 1});
      return composer_->compose(requests, out);
    };
  return [this](std::span<const PageId> pages, std::vector<std::vector<uint8_t>>& out) -> Status {
    // A bake reads every material: load them up front (once; later calls are free), so the
    // worker threads meet no load error.
    if (auto s = packed_.load_all(); !s) return s;
    out.assign(pages.size(), {});
    std::atomic<size_t> next{0};
    auto work = [&] {
      for (size_t i = next++; i < pages.size(); i = next++) out[i] = std::move(compose_page_reference(packed_, pages[i]).value());
    };
    const unsigned n = std::max(1u, std::min<unsigned>(std::thread::hardware_concurrency(), unsigned(pages.size())));
    std::vector<std::jthread> threads;
    for (unsigned t = 1; t < n; ++t) threads.emplace_back(work);
    work();
    return Ok{};
  };
}

}  // namespace tvt::cli
