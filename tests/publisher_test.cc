// The publisher on its own (server/publisher.h, issue 40): one thread runs the steps, in order; a sweep
// asked for again while its step waits is stepped once; callers that wait share the step's outcome; a close
// runs what is queued.
#include "server/publisher.h"

#include <chrono>
#include <future>
#include <mutex>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

namespace bistable {
namespace {

// A step that records what it ran and on which thread, and can be held until the test lets it go.
struct Steps {
  std::mutex mu;
  std::condition_variable cv;
  bool hold = false;
  std::vector<std::string> ran;
  std::vector<std::thread::id> threads;
  std::vector<std::pair<std::string, Status>> failures;
  StatusOr<std::string> Run(const std::string& id) {
    std::unique_lock<std::mutex> lock(mu);
    ran.push_back(id);
    threads.push_back(std::this_thread::get_id());
    cv.notify_all();
    cv.wait(lock, [&] { return !hold; });
    if (id == "broken") return Status::IoError("map", "disk full");
    if (id == "refining") return Status::FailedPrecondition("refining");
    return "maps/" + id + ".h5";
  }
  void Release() {
    std::lock_guard<std::mutex> lock(mu);
    hold = false;
    cv.notify_all();
  }
  // Waits until `n` steps have started.
  void AwaitStarted(size_t n) {
    std::unique_lock<std::mutex> lock(mu);
    cv.wait_for(lock, std::chrono::seconds(10), [&] { return ran.size() >= n; });
  }
  std::unique_ptr<Publisher> Make() {
    return std::make_unique<Publisher>([this](const std::string& id) { return Run(id); },
                                       [this](const std::string& id, const Status& st) {
                                         std::lock_guard<std::mutex> lock(mu);
                                         failures.emplace_back(id, st);
                                       });
  }
};

TEST(Publisher, RunWaitsForTheStepOnThePublishersOwnThread) {
  Steps steps;
  auto p = steps.Make();
  auto path = p->Run("a");
  ASSERT_TRUE(path.ok());
  EXPECT_EQ(*path, "maps/a.h5");
  ASSERT_EQ(steps.threads.size(), 1u);
  EXPECT_NE(steps.threads[0], std::this_thread::get_id()) << "a caller never publishes on its own thread";
  EXPECT_EQ(p->Run("broken").status().code(), Status::Code::kIoError);
  EXPECT_TRUE(steps.failures.empty()) << "a failure someone waited for is theirs to report";
}

TEST(Publisher, ASweepAskedForAgainWhileItsStepWaitsIsSteppedOnce) {
  Steps steps;
  steps.hold = true;
  auto p = steps.Make();
  p->Post("a");
  steps.AwaitStarted(1);  // a's step runs (held): b is queued behind it
  p->Post("b");
  p->Post("b");
  auto waiter = std::async(std::launch::async, [&] { return p->Run("b"); });  // joins the queued step
  for (int i = 0; i < 2000 && p->waiting() < 1; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  ASSERT_EQ(p->waiting(), 1);
  steps.Release();
  auto b = waiter.get();
  ASSERT_TRUE(b.ok());
  EXPECT_EQ(*b, "maps/b.h5");
  p->Close();
  EXPECT_EQ(steps.ran, (std::vector<std::string>{"a", "b"}));
  EXPECT_EQ(p->steps(), 2);
}

TEST(Publisher, ASweepAskedForWhileItsStepRunsIsSteppedAgain) {
  Steps steps;
  steps.hold = true;
  auto p = steps.Make();
  p->Post("a");
  steps.AwaitStarted(1);
  p->Post("a");  // the running step may have read the sweep before what this caller saw
  steps.Release();
  p->Close();
  EXPECT_EQ(steps.ran, (std::vector<std::string>{"a", "a"}));
}

TEST(Publisher, CloseRunsWhatIsQueuedThenRefusesMore) {
  Steps steps;
  steps.hold = true;
  auto p = steps.Make();
  p->Post("x");
  steps.AwaitStarted(1);
  p->Post("y");
  p->Post("broken");
  p->Post("refining");
  auto closing = std::async(std::launch::async, [&] { p->Close(); });
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  steps.Release();
  closing.get();
  EXPECT_EQ(steps.ran, (std::vector<std::string>{"x", "y", "broken", "refining"}));
  // Unwaited failures are said, except FailedPrecondition (cancelled or refining meanwhile).
  ASSERT_EQ(steps.failures.size(), 1u);
  EXPECT_EQ(steps.failures[0].first, "broken");
  EXPECT_EQ(p->Run("z").status().code(), Status::Code::kFailedPrecondition);
  p->Post("z");
  EXPECT_EQ(steps.ran.size(), 4u);
}

}  // namespace
}  // namespace bistable
