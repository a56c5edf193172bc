// A client's terravt::PageProducer (include/terravt/page_producer.h) as the VT runtime's
// producer (render/page_producer.h): translates pages and answers, and holds the client to the
// contract — only pages it accepted and still owns may be reported, each once.
#pragma once
#include <algorithm>
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

#include "render/page_producer.h"
#include "terravt/page_producer.h"

namespace terravt::detail {

class ClientProducer final : public tvt::PageProducer {
 public:
  // The most requests offered a frame: the client's requests_per_frame(), or `page_budget`
  // when it says 0; never more than `slots` (VirtualTextureDesc::page_budget, cache_slots).
  ClientProducer(std::shared_ptr<terravt::PageProducer> client, uint32_t page_budget, uint32_t slots)
      : client_(std::move(client)) {
    const uint32_t wanted = client_->requests_per_frame();
    per_frame_ = std::min(wanted == 0 ? page_budget : wanted, slots);
  }

  uint32_t requests_per_frame() const override { return per_frame_; }
  void begin_frame(uint64_t frame) override { client_->begin_frame(frame); }
  tvt::ProducerAccept request(const tvt::PageRequest& request) override;
  void cancel(const tvt::PageId& page) override;
  void finish() override { client_->finish(); }
  tvt::Status record(VkCommandBuffer cmd, tvt::ProducerOutcome& outcome) override;
  void add_stats(tvt::VtFrameStats& stats) const override { stats.composed += written_count_; }

 private:
  std::shared_ptr<terravt::PageProducer> client_;
  uint32_t per_frame_ = 0;
  struct Owned {
    tvt::PageId page;  // as terravt asked for it (a client's report is compared field by field)
    uint32_t slot = 0;
  };
  std::unordered_map<uint64_t, Owned> outstanding_;  // accepted pages by PageId::pack()
  std::vector<tvt::PageRequest> cancelled_;              // reported by the next record()
  std::vector<PageTask> written_, failed_;
  uint32_t written_count_ = 0;
};

}  // namespace terravt::detail
