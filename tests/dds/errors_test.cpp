// Set-up failures surface as exceptions that name the DDS call, the object
// and Cyclone's error text.
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

#include "dds/dds_error.h"
#include "dds/publisher.h"
#include "dds/qos.h"
#include "dds/subscriber.h"
#include "dds_test_support.h"

namespace rilo::dds {
namespace {


template <class Exception, class F>
std::string messageOf(F&& f) {
  try {
    f();
  } catch (const Exception& e) {
    return e.what();
  }
  ADD_FAILURE() << "no exception";
  return {};
}

TEST(DdsErrors, InvalidTopicNameNamesCallTopicAndReason) {
  Participant participant(testing::loopbackOptions());
  PublisherOptions po;
  po.topics = testing::uniqueTopicNames("errors");
  po.topics.pose = "rt/rilo/bad pose";  // spaces are not allowed in DDS topic names
  const std::string what = messageOf<std::runtime_error>([&] { Publisher pub(participant, po); });
  EXPECT_NE(what.find("dds_create_topic"), std::string::npos) << what;
  EXPECT_NE(what.find("'rt/rilo/bad pose'"), std::string::npos) << what;
  EXPECT_NE(what.find("geometry_msgs::msg::dds_::PoseWithCovarianceStamped_"), std::string::npos) << what;
  EXPECT_NE(what.find("Bad Parameter"), std::string::npos) << what;

  SubscriberOptions so;
  so.topics = testing::uniqueTopicNames("errors_sub");
  so.topics.status = "";
  const std::string sub_what = messageOf<std::runtime_error>([&] { Subscriber sub(participant, so); });
  EXPECT_NE(sub_what.find("dds_create_topic(topic ''"), std::string::npos) << sub_what;
}

TEST(DdsErrors, InvalidDomainWithConfig) {
  const std::string what = messageOf<std::runtime_error>([&] { Participant p(testing::loopbackOptions(300)); });
  EXPECT_NE(what.find("dds_create_domain(domain 300"), std::string::npos) << what;
  EXPECT_NE(what.find("above 232"), std::string::npos) << what;
  EXPECT_NE(what.find("Error"), std::string::npos) << what;
}

TEST(DdsErrors, InvalidDomainWithoutConfig) {
  const std::string what = messageOf<std::runtime_error>([&] { Participant p(ParticipantOptions{301, ""}); });
  EXPECT_NE(what.find("dds_create_participant(domain 301"), std::string::npos) << what;
}

TEST(DdsErrors, DefaultDomainSentinelIsRejected) {
  const std::string what =
      messageOf<std::invalid_argument>([&] { Participant p(ParticipantOptions{DDS_DOMAIN_DEFAULT, ""}); });
  EXPECT_NE(what.find("domain_id"), std::string::npos) << what;
}

TEST(DdsErrors, MalformedConfig) {
  const std::string what =
      messageOf<std::runtime_error>([&] { Participant p(ParticipantOptions{testing::uniqueDomainId(), "<CycloneDDS><Nonsense/>"}); });
  EXPECT_NE(what.find("dds_create_domain"), std::string::npos) << what;
}

TEST(DdsErrors, SameDomainDifferentConfigInOneProcess) {
  Participant first(testing::loopbackOptions());
  ParticipantOptions other = testing::loopbackOptions();
  other.config_xml += "<!-- different -->";
  const std::string what = messageOf<std::invalid_argument>([&] { Participant p(other); });
  EXPECT_NE(what.find("different config_xml"), std::string::npos) << what;
  // Same config: the domain instance is shared.
  Participant second(testing::loopbackOptions());
  EXPECT_EQ(second.domainId(), first.domainId());
}

TEST(DdsErrors, ReaderDepthMustBePositive) {
  const std::string what = messageOf<std::invalid_argument>([&] { readerQos(TopicKind::kOdometry, 0); });
  EXPECT_NE(what.find("odometry_depth"), std::string::npos) << what;
}

TEST(DdsErrors, CheckHelpersFormat) {
  const std::string what =
      messageOf<std::runtime_error>([&] { checkReturn(DDS_RETCODE_TIMEOUT, "dds_write", "topic 'x'"); });
  std::string expected = "dds_write(topic 'x'): ";
  expected += dds_strretcode(DDS_RETCODE_TIMEOUT);
  expected += " (";
  expected += std::to_string(DDS_RETCODE_TIMEOUT);
  expected += ")";
  EXPECT_EQ(what, expected);
  EXPECT_NO_THROW(checkReturn(DDS_RETCODE_OK, "dds_write", "topic 'x'"));
  EXPECT_EQ(checkEntity(5, "dds_create_reader", "r"), 5);
}

}  // namespace
}  // namespace rilo::dds
