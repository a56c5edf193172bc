#include "streaming/page_loader.h"

#include <algorithm>
#include <chrono>

#include "streaming/store_format.h"

namespace tvt {

namespace {
double ms_between(std::chrono::steady_clock::time_point a, std::chrono::steady_clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}
}  // namespace

PageLoader::PageLoader(std::shared_ptr<const PageStoreReader> store, PageLoaderOptions options, std::span<uint8_t> staging)
    : store_(std::move(store)) {
  TVT_CHECK(store_ != nullptr);
  TVT_CHECK(options.staging_slots >= 1);
  page_bytes_ = store_->page_bytes();
  slots_count_ = options.staging_slots;
  const uint64_t need = uint64_t(slots_count_) * page_bytes_;
  if (staging.empty()) {
    own_staging_.resize(size_t(need));
    staging_ = own_staging_;
  } else {
    TVT_CHECK(staging.size() >= need);  // caller memory must hold staging_slots pages
    staging_ = staging.first(size_t(need));
  }
  slots_.resize(slots_count_);
  for (uint32_t i = slots_count_; i-- > 0;) free_slots_.push_back(i);  // slot 0 handed out first
  const uint32_t threads = std::clamp(options.threads, 1u, 64u);
  for (uint32_t i = 0; i < threads; ++i) workers_.emplace_back([this] { worker(); });
}

PageLoader::~PageLoader() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
    queue_.clear();
  }
  work_cv_.notify_all();
  for (std::thread& t : workers_) t.join();
}

void PageLoader::free_slot(uint32_t slot) {
  slots_[slot] = Slot{};
  free_slots_.push_back(slot);
}

bool PageLoader::request(const PageId& page, uint64_t tag) {
  std::unique_lock lock(mutex_);
  if (stop_ || free_slots_.empty()) return false;
  ++stats_.requested;
  if (!store_->contains(page)) {  // answered at once: no slot, no I/O
    finished_.push_back(LoadedPage{page, tag, LoadStatus::failed, PageError::missing});
    if (reported_.insert(page.pack()).second)
      messages_.push_back(store_format::page_where(store_->path(), page) + ": not in the store");
    idle_cv_.notify_all();
    return true;
  }
  const uint32_t slot = free_slots_.back();
  free_slots_.pop_back();
  slots_[slot] = Slot{SlotState::queued, false, page, tag};
  queue_.push_back(slot);
  lock.unlock();
  work_cv_.notify_one();
  return true;
}

void PageLoader::cancel(const PageId& page) {
  std::lock_guard lock(mutex_);
  for (uint32_t s = 0; s < slots_count_; ++s) {
    Slot& slot = slots_[s];
    if (slot.page != page) continue;
    switch (slot.state) {
      case SlotState::queued:
        queue_.erase(std::find(queue_.begin(), queue_.end(), s));
        finished_.push_back(LoadedPage{page, slot.tag, LoadStatus::cancelled, PageError::none});
        free_slot(s);
        break;
      case SlotState::loading:
        slot.cancel = true;  // the worker reports it when the read ends
        break;
      case SlotState::ready:
        for (LoadedPage& r : finished_)
          if (r.staging == s) {
            r.status = LoadStatus::cancelled;
            r.staging = UINT32_MAX;
          }
        free_slot(s);
        break;
      case SlotState::free:
      case SlotState::staged:
        break;
    }
  }
  // A load that already failed (its slot freed) and is not polled yet: withdrawn too, so the
  // caller hears "cancelled" for a page it cancelled, never a later "failed".
  for (LoadedPage& r : finished_)
    if (r.page == page && r.status == LoadStatus::failed) {
      r.status = LoadStatus::cancelled;
      r.error = PageError::none;
    }
  if (queue_.empty() && loading_ == 0) idle_cv_.notify_all();
}

void PageLoader::poll(std::vector<LoadedPage>& out) {
  std::lock_guard lock(mutex_);
  for (const LoadedPage& r : finished_) {
    switch (r.status) {
      case LoadStatus::ok:
        slots_[r.staging].state = SlotState::staged;
        ++stats_.loaded;
        break;
      case LoadStatus::failed: ++stats_.failed; break;
      case LoadStatus::cancelled: ++stats_.cancelled; break;
    }
  }
  out.insert(out.end(), finished_.begin(), finished_.end());
  finished_.clear();
}

std::span<const uint8_t> PageLoader::staged(uint32_t staging) const {
  TVT_CHECK(staging < slots_count_);
  std::lock_guard lock(mutex_);
  if (slots_[staging].state != SlotState::staged) return {};
  return staging_.subspan(size_t(staging_offset(staging)), size_t(page_bytes_));
}

uint64_t PageLoader::staging_offset(uint32_t staging) const {
  TVT_CHECK(staging < slots_count_);
  return uint64_t(staging) * page_bytes_;
}

void PageLoader::release(uint32_t staging) {
  std::lock_guard lock(mutex_);
  if (staging < slots_count_ && slots_[staging].state == SlotState::staged) free_slot(staging);
}

PageLoaderStats PageLoader::stats() const {
  std::lock_guard lock(mutex_);
  PageLoaderStats s = stats_;
  s.outstanding = uint32_t(queue_.size()) + loading_ + uint32_t(finished_.size());
  s.staging_in_use = uint32_t(std::count_if(slots_.begin(), slots_.end(), [](const Slot& slot) {
    return slot.state == SlotState::staged;
  }));
  return s;
}

std::vector<std::string> PageLoader::take_error_messages() {
  std::lock_guard lock(mutex_);
  return std::exchange(messages_, {});
}

void PageLoader::wait_idle() {
  std::unique_lock lock(mutex_);
  idle_cv_.wait(lock, [this] { return queue_.empty() && loading_ == 0; });
}

void PageLoader::worker() {
  const std::unique_ptr<PageStoreReader::Decoder> decoder = store_->make_decoder();
  std::unique_lock lock(mutex_);
  for (;;) {
    work_cv_.wait(lock, [this] { return stop_ || !queue_.empty(); });
    if (stop_) return;
    const uint32_t s = queue_.front();
    queue_.pop_front();
    slots_[s].state = SlotState::loading;
    const PageId page = slots_[s].page;
    ++loading_;
    lock.unlock();

    // I/O and decompression outside the lock, straight into the slot's staging memory.
    std::string message;
    const auto t0 = std::chrono::steady_clock::now();
    PageError error = store_->read_blob(page, *decoder, &message);
    const auto t1 = std::chrono::steady_clock::now();
    const uint64_t read_bytes = error == PageError::none ? decoder->blob().size() : 0;
    if (error == PageError::none)
      error = store_->decode_blob(page, staging_.subspan(size_t(staging_offset(s)), size_t(page_bytes_)), *decoder, &message);
    const auto t2 = std::chrono::steady_clock::now();

    lock.lock();
    --loading_;
    Slot& slot = slots_[s];
    LoadedPage r{page, slot.tag, LoadStatus::ok, error, UINT32_MAX, ms_between(t0, t1), ms_between(t1, t2)};
    stats_.bytes_read += read_bytes;
    if (error == PageError::none) stats_.bytes_decoded += page_bytes_;
    if (slot.cancel) {
      r.status = LoadStatus::cancelled;
      r.error = PageError::none;
      free_slot(s);
    } else if (error != PageError::none) {
      r.status = LoadStatus::failed;
      free_slot(s);  // its bytes are never exposed: the slot is rewritten before it is ever ok
    } else {
      slot.state = SlotState::ready;
      r.staging = s;
    }
    if (error != PageError::none && reported_.insert(page.pack()).second) messages_.push_back(std::move(message));
    finished_.push_back(r);
    if (queue_.empty() && loading_ == 0) idle_cv_.notify_all();
  }
}

}  // namespace tvt
