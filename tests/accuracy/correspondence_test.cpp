// SPDX-License-Identifier: MIT
// Correspondence accuracy on the plane, for every plugin method that outputs
// proj_col_px (found at run time; methods without it are skipped, saying so):
// the sim's "plane" has direct light only, so any correct column decoder
// gets >= 95 % of lit pixels within one projector column of the truth and
// <= 0.5 % gross errors (|err| > 1 column). Evaluated by
// engine::evaluate_outputs, the evaluators the service and `procam bench` use.
#include <gtest/gtest.h>

#include "plugin_runs.hpp"
#include "procam/engine/evaluate.hpp"

namespace procam {
namespace {

class Correspondence : public ::testing::TestWithParam<suite::MethodCase> {};

TEST_P(Correspondence, PlaneWithinOneColumnAndFewGrossErrors) {
  const suite::MethodCase& c = GetParam();
  suite::SimRun run;
  const bool ran = suite::run_on_sim(c.plugin, c.method, "plane", run);
  if (!run.skip_reason.empty()) GTEST_SKIP() << "needs rig data the shipped sim rig lacks: " << run.skip_reason;
  ASSERT_TRUE(ran);
  if (suite::find_output(run.outputs, "proj_col_px") == nullptr)
    GTEST_SKIP() << c.plugin << "/" << c.method << " outputs no proj_col_px: no correspondence to evaluate";
  auto truth = run.rig->ground_truth(0);
  ASSERT_TRUE(truth.ok()) << truth.status().message();
  const nlohmann::json e = engine::evaluate_outputs(run.outputs, *truth);
  ASSERT_FALSE(e.contains("error")) << e.dump();
  EXPECT_GE(e["within_1col_fraction"].get<double>(), 0.95) << e.dump();
  EXPECT_LE(e["gross_error_fraction"].get<double>(), 0.005) << e.dump();
}

INSTANTIATE_TEST_SUITE_P(AllPluginMethods, Correspondence, ::testing::ValuesIn(suite::all_methods()),
                         [](const ::testing::TestParamInfo<suite::MethodCase>& i) {
                           return suite::case_name(i.param.plugin, i.param.method, "plane");
                         });

}  // namespace
}  // namespace procam
