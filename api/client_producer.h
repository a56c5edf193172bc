// A client's terravt::PageProducer (include/terravt/page_producer.h) as the VT runtime's
// producer (render/page_producer.h): translates pages and answers, and holds the client to the
// contract — only pages it accepted and still owns may be reported, each once.
#pragma once
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

#include "render/page_producer.h"
#include "terravt/page_producer.h"

namespace terravt::detail {

class ClientProducer final : public tvt::PageProducer {
 public:
  // `per_frame`: the most requests offered a frame (VirtualTextureDesc::page_budget).
  ClientProducer(std::shared_ptr<terravt::PageProducer> client, uint32_t per_frame)
      : client_(std::move(client)), per_frame_(per_frame) {}

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
