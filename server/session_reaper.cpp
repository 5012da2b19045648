#include "server/session_reaper.hpp"

#include <utility>

namespace locaid::server {

void SessionReaper::Start() {
  std::lock_guard lock(mu_);
  if (thread_.joinable() || stopping_) return;
  thread_ = std::thread([this] { Run(); });
}

void SessionReaper::Retire(std::shared_ptr<Session> session) {
  if (!session || !session->MarkRetired()) return;
  std::lock_guard lock(mu_);
  queue_.push_back(std::move(session));
  cv_.notify_one();
}

void SessionReaper::Stop() {
  {
    std::lock_guard lock(mu_);
    stopping_ = true;
  }
  cv_.notify_one();
  if (thread_.joinable()) thread_.join();
  // Retired after the thread ended (or it never started): the caller's thread.
  std::deque<std::shared_ptr<Session>> left;
  {
    std::lock_guard lock(mu_);
    left.swap(queue_);
  }
  for (auto& s : left) s->Join();
}

void SessionReaper::Run() {
  std::unique_lock lock(mu_);
  for (;;) {
    cv_.wait(lock, [this] { return stopping_ || !queue_.empty(); });
    if (queue_.empty()) return;  // stopping, nothing left
    std::shared_ptr<Session> session = std::move(queue_.front());
    queue_.pop_front();
    lock.unlock();
    session->Stop();
    session->Join();
    session.reset();  // the last reference, unless a stream still holds one
    lock.lock();
  }
}

}  // namespace locaid::server
