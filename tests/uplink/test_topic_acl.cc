// The shipped broker ACL (deploy/mosquitto/acl) against the gateway's one list of topics
// (gateway/uplink/topics.h, kTopicTable): every topic the gateway publishes to has its
// `pattern write` line, every topic it subscribes to its `pattern read` line, and the file grants
// a vehicle nothing more. Issue 24 found the shipped file without alarm, state and zone: the
// theft alarm never reached the backend.
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "gateway/uplink/envelope_writer.h"
#include "gateway/uplink/outbox_source.h"
#include "gateway/uplink/topics.h"

namespace fleetgw::uplink {
namespace {

// The `pattern ...` lines of the shipped ACL (the per-vehicle grants), whitespace normalised.
std::vector<std::string> shipped_patterns() {
  const std::string path = std::string(FLEETGW_SOURCE_DIR) + "/deploy/mosquitto/acl";
  std::ifstream in(path);
  EXPECT_TRUE(in) << "cannot read " << path;
  std::vector<std::string> out;
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream words(line);
    std::string w, joined;
    while (words >> w) joined += (joined.empty() ? "" : " ") + w;
    if (joined.starts_with("pattern ")) out.push_back(joined);
  }
  return out;
}

TEST(TopicsAcl, ShippedAclGrantsExactlyTheTopicsOfTheTopicTable) {
  const auto shipped = shipped_patterns();
  const std::set<std::string> granted(shipped.begin(), shipped.end());
  EXPECT_EQ(granted.size(), shipped.size()) << "a pattern line is repeated";
  const auto wanted = acl_patterns("fleet/v1");
  for (const auto& w : wanted) {
    EXPECT_TRUE(granted.contains(w)) << "deploy/mosquitto/acl lacks '" << w << "'";
  }
  const std::set<std::string> wanted_set(wanted.begin(), wanted.end());
  for (const auto& g : granted) {
    EXPECT_TRUE(wanted_set.contains(g))
        << "deploy/mosquitto/acl grants '" << g << "', which no topic of the gateway needs";
  }
}

TEST(TopicsAcl, AclPatternsNameDirectionAndScope) {
  const auto p = acl_patterns("fleet/v1");
  const auto has = [&](const char* line) { return std::find(p.begin(), p.end(), line) != p.end(); };
  EXPECT_TRUE(has("pattern write fleet/v1/%u/alarm"));
  EXPECT_TRUE(has("pattern write fleet/v1/%u/cmd/result"));
  EXPECT_TRUE(has("pattern read fleet/v1/%u/cmd"));
  EXPECT_TRUE(has("pattern read fleet/v1/zones"));
  EXPECT_FALSE(has("pattern write fleet/v1/%u/cmd"));
}

// Every record kind the outbox can hold is published on a topic of the table, marked with that
// kind: the per-kind refusal lanes (uplink_publish.cc) find a publish's kind through it.
TEST(TopicsAcl, EveryRecordKindPublishesOnItsOwnTableTopic) {
  const Topics topics("fleet/v1", "bike-7");
  for (const char* k :
       {kind::kTelemetry, kind::kRide, kind::kFault, kind::kPack, kind::kLock, kind::kInfo,
        kind::kStatus, kind::kCommandResult, kind::kEviction, kind::kAlarm, kind::kZone}) {
    const KindRoute* route = find_route(k);
    ASSERT_NE(route, nullptr) << k;
    const TopicSpec* spec = find_topic(topics, &(topics.*(route->topic)));
    ASSERT_NE(spec, nullptr) << k;
    EXPECT_EQ(spec->direction, TopicDirection::kPublish) << k;
    EXPECT_EQ(spec->record_kind, k);
  }
  EXPECT_EQ(find_topic(topics, &topics.base), nullptr);
  const std::string elsewhere = topics.alarm;
  EXPECT_EQ(find_topic(topics, &elsewhere), nullptr) << "found by address, not by value";
}

TEST(TopicsAcl, TopicsAreBuiltFromTheTable) {
  const Topics t("fleet/v1", "bike-7");
  EXPECT_EQ(t.alarm, "fleet/v1/bike-7/alarm");
  EXPECT_EQ(t.zone, "fleet/v1/bike-7/zone");
  EXPECT_EQ(t.state, "fleet/v1/bike-7/state");
  EXPECT_EQ(t.zones, "fleet/v1/bike-7/zones");
  EXPECT_EQ(t.fleet_zones, "fleet/v1/zones");
  std::set<std::string> names;
  for (const auto& s : kTopicTable) names.insert(t.*s.member);
  EXPECT_EQ(names.size(), kTopicTable.size()) << "two table entries name the same topic";
}

}  // namespace
}  // namespace fleetgw::uplink
