// The node base class generated from tests/schemas/test_nodes/param_node.hnode: its constructor
// declares every parameter of the params block, in order and with what the schema says of it,
// the typed accessors of params() read the defaults before any scheduler starts the node, and a
// scheduler that starts it puts those declarations into the node's store.
#include <gtest/gtest.h>

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "horus/params.hpp"
#include "horus/scheduler.hpp"
#include "test_nodes/param_node.hpp"
#include "topic_test_support.hpp"

namespace {

class ParamNode : public test_nodes::ParamNodeBase {
 public:
  void tick() override {}
};

TEST(GeneratedParamNode, AccessorsReadTheDeclaredDefaults) {
  ParamNode node;
  const ParamNode::Params& params = node.params();
  EXPECT_EQ(params.max_speed(), 1.0);
  EXPECT_EQ(params.gain(), 0.5F);
  EXPECT_EQ(params.offset(), 0);
  EXPECT_EQ(params.wheel_count(), 4U);
  EXPECT_TRUE(params.enabled());
  EXPECT_EQ(params.profile(), "eco");
  EXPECT_EQ(params.mode(), test_msgs::Mode::Run);
  EXPECT_EQ(params.gains(), (std::array<double, 3>{1.0, 0.5, 0.0}));
  EXPECT_EQ(params.mask(), (std::array<bool, 2>{true, false}));
  EXPECT_EQ(params.ticks(), 0U);
}

TEST(GeneratedParamNode, DeclaresEachParameterInSchemaOrderWithItsAttributes) {
  ParamNode node;
  const std::vector<horus::ParamDeclaration>& declared = node.param_declarations();
  std::vector<std::string> names;
  std::vector<std::string> spellings;
  for (const horus::ParamDeclaration& declaration : declared) {
    names.push_back(declaration.name);
    spellings.push_back(declaration.spelling);
  }
  EXPECT_EQ(names,
            (std::vector<std::string>{"max_speed", "gain", "offset", "wheel_count", "enabled",
                                      "profile", "mode", "gains", "mask", "ticks"}));
  EXPECT_EQ(spellings,
            (std::vector<std::string>{"f64", "f32", "i32", "u8", "bool", "String", "test_msgs.Mode",
                                      "[f64; 3]", "[bool; 2]", "u64"}));

  const horus::ParamDeclaration& max_speed = declared.at(0);
  EXPECT_EQ(max_speed.min, 0.0);
  EXPECT_EQ(max_speed.max, 2.0);
  EXPECT_EQ(max_speed.unit, "m/s");
  EXPECT_EQ(max_speed.doc, "Top speed the planner may command.");
  EXPECT_FALSE(max_speed.read_only);

  const horus::ParamDeclaration& gain = declared.at(1);
  EXPECT_EQ(gain.min, 0.0);
  EXPECT_FALSE(gain.max.has_value());

  const horus::ParamDeclaration& offset = declared.at(2);
  EXPECT_EQ(offset.min, -10.0);
  EXPECT_EQ(offset.max, 10.0);
  EXPECT_TRUE(offset.doc.empty());

  EXPECT_TRUE(declared.at(3).read_only);
  EXPECT_EQ(declared.at(5).choices.size(), 2U);
  EXPECT_EQ(declared.at(6).choices.size(), 2U);
  EXPECT_TRUE(declared.at(6).enumeration.has_value());
  EXPECT_EQ(declared.at(7).min, -1.0);
  EXPECT_EQ(declared.at(7).max, 1.0);
  EXPECT_TRUE(declared.at(8).choices.empty());
}

TEST(GeneratedParamNode, AStartedNodesStoreHoldsTheDeclarationsAtTheirDefaults) {
  topic_test::PrivateNamespace ns;
  auto node = std::make_shared<ParamNode>();
  {
    horus::Scheduler sched{horus::SchedulerConfig{}.deterministic(true)};
    test_nodes::ParamNodeBase::add_to(sched, node).build();
    sched.tick_once();
    const horus::ParamStoreReader reader("param_node");
    const std::vector<horus::ParamInfo> params = reader.list();
    ASSERT_EQ(params.size(), 10U);
    EXPECT_EQ(params.at(0).declaration.name, "max_speed");
    EXPECT_EQ(params.at(0).declaration.unit, "m/s");
    EXPECT_EQ(params.at(0).value, params.at(0).declaration.default_value);
    EXPECT_EQ(params.at(0).version, 1U);
    EXPECT_EQ(params.at(6).declaration.spelling, "test_msgs.Mode");
    EXPECT_TRUE(params.at(3).declaration.read_only);
  }
  EXPECT_EQ(node->params().max_speed(), 1.0);
  EXPECT_EQ(node->params().profile(), "eco");
}

}  // namespace
