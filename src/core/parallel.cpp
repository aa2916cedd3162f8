#include "core/parallel.h"

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <exception>
#include <mutex>
#include <system_error>
#include <thread>
#include <vector>

namespace snow {
namespace {

// One parallel loop: indices handed out in order; the first exception is
// kept and stops the hand-out.
struct Loop {
  const std::function<void(size_t)>& fn;
  size_t count;
  std::atomic<size_t> next{0};
  std::atomic<bool> failed{false};
  std::exception_ptr error;
  std::mutex error_mutex;

  void work() {
    for (size_t i = next++; i < count && !failed; i = next++) {
      try {
        fn(i);
      } catch (...) {
        std::lock_guard<std::mutex> lock(error_mutex);
        if (!error) error = std::current_exception();
        failed = true;
      }
    }
  }
};

// Threads kept for the program's life, so that a loop costs no thread starts
// (the stabilizer runs two loops a pass, thousands of passes). One loop at a
// time; a loop started while one runs (from another thread, or nested in one)
// starts threads of its own instead.
class Pool {
 public:
  ~Pool() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    wake_.notify_all();
    for (std::thread& t : threads_) t.join();
  }

  /// Runs `loop` on the calling thread and up to `helpers` pool threads;
  /// false (nothing run) when the pool is busy.
  bool run(Loop& loop, unsigned helpers) {
    std::unique_lock<std::mutex> busy(busy_, std::try_to_lock);
    if (!busy.owns_lock()) return false;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      while (threads_.size() < helpers) {
        try {
          threads_.emplace_back([this] { serve(); });
        } catch (const std::system_error&) {
          break;  // no more threads to be had: the ones there share the work
        }
      }
      loop_ = &loop;
      seats_ = std::min<size_t>(helpers, threads_.size());
      working_ = seats_;
      generation_.fetch_add(1, std::memory_order_release);
    }
    wake_.notify_all();
    loop.work();
    // The helpers finish about when this thread does, and the next loop
    // comes soon (the stabilizer runs two a pass): both sides yield a little
    // before they sleep, as a sleep and wake-up on a virtual machine costs a
    // noticeable share of a short loop.
    for (int spin = 0; spin < kSpins && working_.load(std::memory_order_acquire) != 0; ++spin) {
      std::this_thread::yield();
    }
    std::unique_lock<std::mutex> lock(mutex_);
    done_.wait(lock, [this] { return working_ == 0; });
    loop_ = nullptr;
    return true;
  }

 private:
  void serve() {
    uint64_t seen = 0;
    std::unique_lock<std::mutex> lock(mutex_);
    for (;;) {
      lock.unlock();
      for (int spin = 0; spin < kSpins && generation_.load(std::memory_order_acquire) == seen;
           ++spin) {
        std::this_thread::yield();
      }
      lock.lock();
      wake_.wait(lock, [&] { return stop_ || generation_ != seen; });
      if (stop_) return;
      seen = generation_;
      if (seats_ == 0) continue;  // this loop wants fewer threads
      --seats_;
      Loop* loop = loop_;
      lock.unlock();
      loop->work();
      lock.lock();
      if (--working_ == 0) done_.notify_one();
    }
  }

  std::mutex busy_;  // held while a loop runs
  std::mutex mutex_;
  std::condition_variable wake_, done_;
  std::vector<std::thread> threads_;
  Loop* loop_ = nullptr;
  size_t seats_ = 0;                // pool threads still to join the loop
  std::atomic<size_t> working_{0};  // pool threads joined or to join that have not finished
  std::atomic<uint64_t> generation_{0};
  static constexpr int kSpins = 200;  // yields before a pool thread or the caller sleeps
  bool stop_ = false;
};

// Starts helper threads for one loop (the pool is busy).
void run_on_new_threads(Loop& loop, unsigned helpers) {
  std::vector<std::thread> pool;
  pool.reserve(helpers);
  for (unsigned t = 0; t < helpers; ++t) {
    try {
      pool.emplace_back([&loop] { loop.work(); });
    } catch (const std::system_error&) {
      break;  // no more threads to be had: the ones running share the work
    }
  }
  loop.work();  // the calling thread is one of the workers
  for (std::thread& t : pool) t.join();
}

}  // namespace

unsigned default_threads() { return std::clamp(std::thread::hardware_concurrency(), 1u, 32u); }

void parallel_for(size_t count, const std::function<void(size_t)>& fn, unsigned threads) {
  if (threads == 0) threads = default_threads();
  threads = unsigned(std::min<size_t>(threads, count));
  Loop loop{fn, count};
  if (threads > 1) {
    static Pool pool;
    if (!pool.run(loop, threads - 1)) run_on_new_threads(loop, threads - 1);
  } else {
    loop.work();
  }
  if (loop.error) std::rethrow_exception(loop.error);
}

void parallel_for_ranges(size_t count, size_t chunk,
                         const std::function<void(size_t begin, size_t end)>& fn,
                         unsigned threads) {
  chunk = std::max<size_t>(chunk, 1);
  parallel_for((count + chunk - 1) / chunk,
               [&](size_t c) { fn(c * chunk, std::min(count, (c + 1) * chunk)); }, threads);
}

double parallel_sum(size_t count, size_t chunk,
                    const std::function<double(size_t begin, size_t end)>& part) {
  chunk = std::max<size_t>(chunk, 1);
  std::vector<double> parts((count + chunk - 1) / chunk, 0.0);
  parallel_for_ranges(count, chunk,
                      [&](size_t begin, size_t end) { parts[begin / chunk] = part(begin, end); });
  double sum = 0.0;
  for (const double p : parts) sum += p;
  return sum;
}

}  // namespace snow
