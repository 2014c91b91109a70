// driver::run_contact_scene against a sink that records what it is given: a failed case's sink
// stores why it failed, and the result names the case once, for a case that fails now and for
// one an earlier session stored as failed (a restart reads it back).
#include <gtest/gtest.h>

#include <map>
#include <string>

#include "scene_text.hpp"
#include "subslip/driver/contact_run.hpp"
#include "subslip/io/contact_scene.hpp"
#include "subslip/io/yaml_checked.hpp"

namespace {

using namespace subslip;

// Case 0 was ended (failed) by an earlier session; the others are pending.
class RecordingSink final : public driver::ContactSink {
 public:
  std::map<std::size_t, std::string> stored_why;  // what fail_case was given, per case
  std::size_t running = 0;

  driver::CaseStatus status(std::size_t index) const override {
    return index == 0 ? driver::CaseStatus::failed : driver::CaseStatus::pending;
  }
  driver::StoredContactCase stored_case(std::size_t) const override {
    return {{}, "contact step failed earlier"};
  }
  void begin_case(std::size_t index) override { running = index; }
  void write_state(const contact::ContactState&, int) override {}
  void write_states(std::span<const driver::ContactRow>) override {}
  void complete_case(const driver::ContactSummary&) override {}
  void fail_case(const driver::ContactSummary&, const std::string& why) override {
    stored_why[running] = why;
  }
};

}  // namespace

TEST(ContactRun, AFailedCaseIsNamedOnceAndItsSinkStoresWhy) {
  // One forward-Euler increment over the whole slide with no cutbacks: the step fails.
  const std::string text = subslip::testing::contact_scene_start() + R"(loading:
  - slide: {speed: 1, direction: [1, 0], distance: 2.0}
    increments: 1
integrator: {method: forward_euler, max_cutbacks: 0}
sweep:
  "law.friction.mu_s": [0.097, 0.1]
)";
  const io::ContactScene scene =
      io::parse_contact_scene(io::YamlDocument::from_string(text, "scene.yaml"));
  ASSERT_EQ(scene.cases.size(), 2u);
  for (const int threads : {1, 2}) {  // streamed, and computed in memory then written
    SCOPED_TRACE(std::to_string(threads) + " threads");
    RecordingSink sink;
    driver::ContactRunOptions options;
    options.threads = threads;
    const auto results = driver::run_contact_scene(scene, sink, options);
    ASSERT_EQ(results.size(), 2u);
    const std::string stored = "case '" + scene.cases[0].name + "': ";
    EXPECT_EQ(results[0].failure, stored + "contact step failed earlier");
    ASSERT_EQ(sink.stored_why.count(1), 1u);
    const std::string& why = sink.stored_why[1];
    EXPECT_EQ(why.find("case '"), std::string::npos) << why;
    EXPECT_EQ(results[1].failure, "case '" + scene.cases[1].name + "': " + why);
  }
}
