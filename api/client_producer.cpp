#include "api/client_producer.h"

namespace terravt {

PageProducer::~PageProducer() = default;

namespace detail {
namespace {

PageTask task_of(const tvt::PageId& page, uint32_t slot) { return PageTask{page.mip, page.x, page.y, slot}; }

std::string describe(const PageTask& t) {
  return "mip " + std::to_string(t.mip) + " page (" + std::to_string(t.x) + ", " + std::to_string(t.y) + ") slot " +
         std::to_string(t.slot);
}

}  // namespace

tvt::ProducerAccept ClientProducer::request(const tvt::PageRequest& r) {
  switch (client_->request(task_of(r.page, r.slot))) {
    case ProducerAccept::accepted:
      outstanding_[r.page.pack()] = Owned{r.page, r.slot};
      return tvt::ProducerAccept::accepted;
    case ProducerAccept::unavailable: return tvt::ProducerAccept::unavailable;
    case ProducerAccept::busy: break;
  }
  return tvt::ProducerAccept::busy;  // also for a value outside the enum: asked again later
}

void ClientProducer::cancel(const tvt::PageId& page) {
  const auto it = outstanding_.find(page.pack());
  if (it == outstanding_.end()) return;
  client_->cancel(task_of(page, it->second.slot));
  cancelled_.push_back(tvt::PageRequest{page, it->second.slot});
  outstanding_.erase(it);
}

tvt::Status ClientProducer::record(VkCommandBuffer cmd, tvt::ProducerOutcome& out) {
  out.cancelled.insert(out.cancelled.end(), cancelled_.begin(), cancelled_.end());
  cancelled_.clear();
  written_.clear();
  failed_.clear();
  Status s = client_->record(cmd, written_, failed_);
  std::string contract;  // the first report that breaks the contract
  const auto take = [&](const std::vector<PageTask>& tasks, std::vector<tvt::PageRequest>& to) {
    for (const PageTask& t : tasks) {
      const tvt::PageId page{t.mip, t.x, t.y};
      const auto it = outstanding_.find(page.pack());
      // Field by field: pack() is only unique for pages of the VT, and a report may be anything.
      if (it == outstanding_.end() || it->second.slot != t.slot || it->second.page.mip != t.mip ||
          it->second.page.x != t.x || it->second.page.y != t.y) {
        if (contract.empty()) contract = describe(t) + " is not a page it accepted and still owns";
        continue;
      }
      to.push_back(tvt::PageRequest{it->second.page, t.slot});
      outstanding_.erase(it);
    }
  };
  const size_t written_before = out.written.size();
  take(written_, out.written);
  take(failed_, out.failed);
  written_count_ = uint32_t(out.written.size() - written_before);
  if (!s) {
    // A failed Vulkan call keeps its kind and VkResult (the VirtualTexture latches it); any
    // other failure, host memory included, is the producer's and passes.
    const Error& e = s.error();
    const bool device_level = e.vk_result != 0 || e.kind == ErrorKind::vulkan || e.kind == ErrorKind::device_lost;
    return Error{device_level ? e.kind : ErrorKind::producer_failed, "page producer: " + e.message, e.vk_result};
  }
  if (!contract.empty())
    return Error{ErrorKind::misuse, "page producer: record() reported " + contract + " (ignored)"};
  return Ok{};
}

}  // namespace detail
}  // namespace terravt
