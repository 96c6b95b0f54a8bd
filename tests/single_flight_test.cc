// server/single_flight.h: concurrent misses of one key load once, with real threads.
#include <atomic>
#include <chrono>
#include <future>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "server/single_flight.h"

namespace bistable {
namespace {

// Eight threads miss the same key while its (slow) load runs: one load, every caller the same value; another
// key loads on its own; a failed load is shared by its waiters but not cached.
TEST(SingleFlight, ConcurrentMissesOfOneKeyLoadOnce) {
  SingleFlightCache<int> cache(60, 8);
  std::atomic<int> calls{0};
  std::promise<void> go;
  std::shared_future<void> start = go.get_future().share();
  auto slow = [&]() -> StatusOr<int> {
    ++calls;
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    return 42;
  };
  std::vector<std::future<StatusOr<int>>> got;
  for (int i = 0; i < 8; ++i)
    got.push_back(std::async(std::launch::async, [&] {
      start.wait();
      return cache.GetOrLoad("sweep\nfrf_db", slow);
    }));
  go.set_value();
  for (auto& f : got) {
    const StatusOr<int> v = f.get();
    ASSERT_TRUE(v.ok());
    EXPECT_EQ(*v, 42);
  }
  EXPECT_EQ(calls.load(), 1);
  EXPECT_EQ(cache.loads(), 1);
  EXPECT_EQ(*cache.GetOrLoad("sweep\nfrf_db", slow), 42);  // cached
  EXPECT_EQ(calls.load(), 1);
  EXPECT_EQ(*cache.GetOrLoad("sweep\nlle", [] { return StatusOr<int>(7); }), 7);
  EXPECT_EQ(cache.loads(), 2);

  int failures = 0;
  auto failing = [&]() -> StatusOr<int> {
    ++failures;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    return Status::NotFound("no map yet");
  };
  auto a = std::async(std::launch::async, [&] { return cache.GetOrLoad("x", failing); });
  auto b = std::async(std::launch::async, [&] { return cache.GetOrLoad("x", failing); });
  EXPECT_FALSE(a.get().ok());
  EXPECT_FALSE(b.get().ok());
  EXPECT_LE(failures, 2);  // shared when b arrived during a's load (it did unless this thread was very late)
  const int before = failures;
  EXPECT_FALSE(cache.GetOrLoad("x", failing).ok());  // not cached: tried again
  EXPECT_EQ(failures, before + 1);
}

TEST(SingleFlight, EntriesExpireAndTheOldestGoesFirst) {
  SingleFlightCache<int> cache(0.05, 2);
  int n = 0;
  auto load = [&]() -> StatusOr<int> { return ++n; };
  EXPECT_EQ(*cache.GetOrLoad("a", load), 1);
  EXPECT_EQ(*cache.GetOrLoad("a", load), 1);
  std::this_thread::sleep_for(std::chrono::milliseconds(80));
  EXPECT_EQ(*cache.GetOrLoad("a", load), 2);  // expired
  EXPECT_EQ(*cache.GetOrLoad("b", load), 3);
  EXPECT_EQ(*cache.GetOrLoad("c", load), 4);  // "a" is dropped (two entries)
  EXPECT_EQ(*cache.GetOrLoad("b", load), 3);
  EXPECT_EQ(*cache.GetOrLoad("a", load), 5);
}

// An exception from the load reaches the caller and leaves no flight behind.
TEST(SingleFlight, AThrowingLoadLeavesNoFlightBehind) {
  SingleFlightCache<int> cache(60, 8);
  EXPECT_THROW(cache.GetOrLoad("k", []() -> StatusOr<int> { throw std::runtime_error("boom"); }), std::runtime_error);
  EXPECT_EQ(*cache.GetOrLoad("k", [] { return StatusOr<int>(3); }), 3);
}

}  // namespace
}  // namespace bistable
