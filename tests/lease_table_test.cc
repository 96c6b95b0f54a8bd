// The lease table on its own (server/lease_table.h, issue 40), on a fake clock the test steps: grants,
// expiry, renewal, revocation (a new plan reassigns the jobs), reports being stored and finished ones.
#include "server/lease_table.h"

#include <set>
#include <string>

#include <gtest/gtest.h>

namespace bistable {
namespace {

struct Table {
  double now = 1000;
  LeaseTable t{[this] { return now; }, 60};
  std::string Grant(const std::string& sweep, const std::string& worker, const std::string& identity = "") {
    return t.Grant({sweep, worker, identity, {0}, 1, 0});
  }
};

TEST(LeaseTable, AGrantLastsLeaseSecondsOnTheInjectedClockAndItsIdIsUnguessable) {
  Table x;
  std::set<std::string> ids;
  for (int i = 0; i < 200; ++i) ids.insert(x.Grant("abc", "w"));
  EXPECT_EQ(ids.size(), 200u);
  const std::string id = *ids.begin();
  EXPECT_EQ(id.rfind("abc-", 0), 0u) << id;
  EXPECT_EQ(id.size(), 4 + 32u) << "128 bits in hex";
  ASSERT_NE(x.t.Find(id), nullptr);
  EXPECT_EQ(x.t.Find(id)->deadline, 1060);
  EXPECT_EQ(x.t.outstanding(), 200);
}

TEST(LeaseTable, ALeaseExpiresOnlyPastItsDeadline) {
  Table x;
  const std::string a = x.Grant("s", "w1");
  x.now = 1030;
  const std::string b = x.Grant("s", "w2");  // deadline 1090
  x.now = 1060;                              // a's deadline: not past it yet
  EXPECT_TRUE(x.t.TakeExpired().empty());
  EXPECT_FALSE(x.t.Expired(*x.t.Find(a)));
  x.now = 1060.5;
  EXPECT_TRUE(x.t.Expired(*x.t.Find(a)));
  auto expired = x.t.TakeExpired();
  ASSERT_EQ(expired.size(), 1u);
  EXPECT_EQ(expired[0].worker, "w1");
  EXPECT_EQ(x.t.Find(a), nullptr) << "handed back to be requeued, gone from the table";
  EXPECT_NE(x.t.Find(b), nullptr);
  EXPECT_EQ(x.t.Extend(a, "").code(), Status::Code::kNotFound);
}

TEST(LeaseTable, RenewalPushesTheDeadlineBackForTheHolderOnly) {
  Table x;
  const std::string id = x.Grant("s", "w", "alice");
  x.now = 1050;
  EXPECT_EQ(x.t.Extend(id, "mallory").code(), Status::Code::kPermissionDenied);
  ASSERT_TRUE(x.t.Extend(id, "alice").ok());
  EXPECT_EQ(x.t.Find(id)->deadline, 1110);
  x.now = 1100;  // past the first deadline, within the renewed one
  EXPECT_TRUE(x.t.TakeExpired().empty());
  x.now = 1111;
  EXPECT_EQ(x.t.Extend(id, "alice").code(), Status::Code::kFailedPrecondition) << "too late: expired";
  EXPECT_EQ(x.t.TakeExpired().size(), 1u);
}

TEST(LeaseTable, RevokingASweepTakesItsLeasesOnly) {
  Table x;
  const std::string a1 = x.Grant("a", "w1"), a2 = x.Grant("a", "w2"), b = x.Grant("b", "w1");
  EXPECT_EQ(x.t.HoldersBySweep(), (std::map<std::string, int>{{"a", 2}, {"b", 1}}));
  auto revoked = x.t.Revoke("a");  // a new plan of sweep a: its jobs are planned (and leased) anew
  EXPECT_EQ(revoked.size(), 2u);
  EXPECT_EQ(x.t.Find(a1), nullptr);
  EXPECT_EQ(x.t.Find(a2), nullptr);
  EXPECT_NE(x.t.Find(b), nullptr);
  EXPECT_EQ(x.t.HoldersBySweep(), (std::map<std::string, int>{{"b", 1}}));
}

TEST(LeaseTable, AReportBeingStoredCannotExpireAndAStoredOneIsRememberedAsFinished) {
  Table x;
  const std::string id = x.Grant("s", "w");
  x.t.BeginCommit(id, *x.t.Find(id));  // leaves the active leases
  EXPECT_TRUE(x.t.Committing(id));
  EXPECT_EQ(x.t.Find(id), nullptr);
  EXPECT_EQ(x.t.outstanding(), 1);
  x.now = 5000;  // the store is slow: the lease must not be requeued meanwhile
  EXPECT_TRUE(x.t.TakeExpired().empty());
  x.t.EndCommit(id, /*restore=*/false);
  x.t.Finish(id, "s");
  EXPECT_FALSE(x.t.Committing(id));
  EXPECT_TRUE(x.t.Finished(id));
  EXPECT_EQ(x.t.outstanding(), 0);
  EXPECT_TRUE(x.t.Extend(id, "").ok()) << "a heartbeat racing its own report is answered";
  EXPECT_FALSE(x.t.Take(id).has_value()) << "a stale second report finds no active lease";
}

TEST(LeaseTable, AFailedStoreGivesTheLeaseBackToItsHolder) {
  Table x;
  const std::string id = x.Grant("s", "w");
  x.t.BeginCommit(id, *x.t.Take(id));
  x.t.EndCommit(id, /*restore=*/true);
  ASSERT_NE(x.t.Find(id), nullptr) << "the worker may retry while the lease lasts";
  EXPECT_FALSE(x.t.Finished(id));
}

TEST(LeaseTable, FinishedLeasesAreRememberedUpToABound) {
  Table x;
  for (size_t i = 0; i <= LeaseTable::kRemembered; ++i) x.t.Finish("lease-" + std::to_string(i), "s");
  EXPECT_FALSE(x.t.Finished("lease-0")) << "the oldest is forgotten";
  EXPECT_TRUE(x.t.Finished("lease-1"));
  EXPECT_TRUE(x.t.Finished("lease-" + std::to_string(LeaseTable::kRemembered)));
}

}  // namespace
}  // namespace bistable
