// SPDX-License-Identifier: MIT
// The structured-light claims of thesis ch. 3, checked on every scene of the
// sim library against its ground truth. Each test runs
//   procam bench --only-listed 1 --scene <scene> --method ... --out <tmp>
// (in process: sim rig -> plugin session -> engine::run_scan -> evaluation)
// and reads bench.json. Terms, all over the truth's lit pixels:
//   ok(m)    = decoded within one projector column (within_1col_fraction);
//   wrong(m) = decoded with |column error| > 1 (gross errors over decoded ×
//              decoded fraction) — a wrong depth the user would get;
//   failed(m) = 1 − ok(m): wrong or not decoded.
// Every bound is a claim of the thesis or a goal of issue 4, written as an
// inequality between methods or against a fixed tolerance; none is a copy of
// a measured output. The numbers seen are printed for the report.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <ostream>
#include <unistd.h>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace {
namespace fs = std::filesystem;

struct Eval {
  double decoded = 0, gross = 0, ok = 0, patterns = 0;
  double wrong() const { return gross * decoded; }
  double failed() const { return 1.0 - ok; }
};

using Runs = std::map<std::string, Eval>;

// Runs the bench for one scene and the given methods (labels as in bench.md).
// extra: more bench arguments (e.g. --param M.key=value).
Runs run(const std::string& scene, const std::vector<std::string>& methods, const std::string& extra = "") {
  const fs::path out = fs::temp_directory_path() /
                       ("procam-claims-" + fs::path(scene).stem().string() + "-" + std::to_string(::getpid()));
  fs::remove_all(out);
  std::string cmd = std::string(PROCAM_BINARY_DIR) + "/bin/procam bench --only-listed 1 --threads 2 --scene " + scene +
                    " --plugins " + PROCAM_PLUGIN_DIR + " --out " + out.string();
  for (const auto& m : methods) cmd += " --method " + m;
  cmd += extra + " 2>" + (out.string() + ".log");
  const int rc = std::system(cmd.c_str());
  Runs runs;
  std::ifstream in(out / "bench.json");
  if (rc != 0 || !in) {
    std::ifstream log(out.string() + ".log");
    std::string text((std::istreambuf_iterator<char>(log)), std::istreambuf_iterator<char>());
    ADD_FAILURE() << "procam bench failed (rc " << rc << "): " << cmd << "\n" << text;
    return runs;
  }
  const auto doc = nlohmann::json::parse(in, nullptr, false);
  for (const auto& r : doc.value("runs", nlohmann::json::array())) {
    if (!r.value("ok", false)) {
      ADD_FAILURE() << scene << " / " << r.value("method", "?") << ": " << r.value("error", "");
      continue;
    }
    const auto& e = r["evaluation"];
    Eval v{e.value("decoded_fraction", 0.0), e.value("gross_error_fraction", 0.0), e.value("within_1col_fraction", 0.0),
           r.value("patterns", 0.0)};
    runs[r.value("method", "")] = v;
    std::printf("%-15s %-22s ok %6.2f%%  decoded %6.2f%%  wrong %6.3f%%  (gross %.3f%% of decoded)\n", scene.c_str(),
                r.value("method", "").c_str(), 100 * v.ok, 100 * v.decoded, 100 * v.wrong(), 100 * v.gross);
  }
  for (const auto& m : methods) EXPECT_TRUE(runs.count(m)) << scene << ": no run for " << m;
  fs::remove_all(out);
  fs::remove(out.string() + ".log");
  return runs;
}

const std::vector<std::string> kBinary = {"gray", "xor02", "xor04", "minsw"};

// The single codes decoded as the thesis decodes them: no one-edge intervals
// and no noise rule (both added for real captures in issue 16; they let
// XOR-02 keep blurred marble pixels as intervals, which is what a product
// wants but not what the thesis's claims about the codes are about).
const std::string kThesisDecoders =
    " --param xor02.max_uncertainty_px=0 --param xor04.max_uncertainty_px=0 --param minsw.max_uncertainty_px=0"
    " --param xor02.noise_k=0 --param xor04.noise_k=0 --param minsw.noise_k=0";

double best_single_wrong(Runs& r) {
  double best = 1;
  for (const auto& m : kBinary) best = std::min(best, r[m].wrong());
  return best;
}

// Direct light only: every method is right almost everywhere.
void expect_direct_scene(const std::string& scene) {
  auto r = run(scene, {"gray", "xor02", "xor04", "minsw", "ensemble", "phase-shift"});
  for (auto& [m, e] : r) {
    EXPECT_GE(e.ok, 0.85) << scene << " / " << m;
    EXPECT_LE(e.wrong(), 0.005) << scene << " / " << m;
  }
}

TEST(SceneClaims, Plane) { expect_direct_scene("plane"); }
TEST(SceneClaims, TiltedBox) { expect_direct_scene("tilted-box"); }
TEST(SceneClaims, Sphere) { expect_direct_scene("sphere"); }

// §3.2–3.3: long-range inter-reflections in a concavity break the
// low-frequency planes of conventional Gray codes (and phase shifting); the
// logical XOR codes keep every plane high-frequency and survive.
TEST(SceneClaims, VGrooveInterreflections) {
  auto r = run("v-groove", {"gray", "xor02", "xor04", "ensemble", "phase-shift"});
  for (const char* m : {"xor02", "xor04", "ensemble"}) {
    EXPECT_GE(r[m].ok, 0.98) << m;
    EXPECT_LE(r[m].wrong(), 0.005) << m;
  }
  EXPECT_GE(r["gray"].failed(), 0.02) << "Gray should fail in the concavity";
  EXPECT_GE(r["gray"].failed(), 4 * r["xor04"].failed());
  EXPECT_GE(r["phase-shift"].failed(), 4 * r["xor04"].failed());
}

// Fig. 3.11: light diffuses through the curtain to the wall and back — long
// range. Gray and phase shifting err; the logical codes and min-SW do not;
// modulated phase shifting (Chen et al.) removes phase shifting's errors.
TEST(SceneClaims, ShowerCurtain) {
  auto r = run("shower-curtain", {"gray", "xor02", "xor04", "minsw", "ensemble", "phase-shift", "modulated-phase-shift"});
  for (const char* m : {"xor02", "xor04", "ensemble"}) {
    EXPECT_GE(r[m].ok, 0.95) << m;
    EXPECT_LE(r[m].wrong(), 0.005) << m;
  }
  EXPECT_GE(r["gray"].failed(), 0.05);
  EXPECT_GE(r["phase-shift"].wrong(), 0.05) << "phase shifting should give wrong depths on the curtain";
  EXPECT_LE(r["modulated-phase-shift"].wrong(), r["phase-shift"].wrong() / 5);
}

// Fig. 3.3: sub-surface scattering blurs the high-frequency planes. XOR-02,
// whose base plane is the finest, cannot be decoded; min-SW (finest stripe
// 8 px) and Gray (only its finest plane is lost, ±1 column) can.
TEST(SceneClaims, MarbleSlabSubsurface) {
  auto r = run("marble-slab", {"gray", "xor02", "xor04", "minsw", "ensemble"}, kThesisDecoders);
  EXPECT_GE(r["minsw"].ok, 0.9);
  EXPECT_GE(r["gray"].ok, 0.9);
  EXPECT_LE(r["minsw"].wrong(), 0.005);
  EXPECT_GE(r["xor02"].failed(), r["minsw"].failed() + 0.15) << "XOR-02 should fail on the slab";
  EXPECT_GE(r["xor02"].wrong(), 3 * r["minsw"].wrong()) << "and give wrong columns, not only gaps";
  EXPECT_GE(r["ensemble"].ok, r["xor02"].ok);
}

// Fig. 2.5 candle: wax scatters more than marble; same ordering.
TEST(SceneClaims, WaxCandleSubsurface) {
  auto r = run("wax-candle", {"gray", "xor02", "minsw", "ensemble-nocorr", "ensemble"});
  EXPECT_GE(r["minsw"].ok, 0.85);
  EXPECT_GE(r["xor02"].failed(), 2 * r["minsw"].failed());
  EXPECT_GE(r["ensemble"].ok, r["xor02"].ok);
  // Correction rounds only take values whose projector pixel is still lit
  // (codes_session.cpp): they must not add wrong pixels.
  EXPECT_LE(r["ensemble"].wrong(), r["ensemble-nocorr"].wrong() + 0.0002);
}

// Fig. 3.1, the mixed scene: inter-reflections in the bowl break Gray's and
// min-SW's low-frequency planes, sub-surface scattering in the marble breaks
// XOR-02's (and some of XOR-04's) finest base plane; the ensemble's vote
// takes whichever pair of codes still agrees. Issue 4's goal: the ensemble's
// gross errors <= 1/5 of the best single code's.
//
// Thesis setting: every code binarizes by L > L̄ alone (Eq. 3.5, no rejection
// margin: min_bit_margin = 0), so each code decodes every lit pixel and its
// failures show up as wrong columns — the comparison the thesis makes.
TEST(SceneClaims, BowlOnMarbleEnsembleThesisSetting) {
  const std::vector<std::string> methods = {"gray", "xor02", "xor04", "minsw", "ensemble-nocorr"};
  std::string hard;
  for (const auto& m : methods) hard += " --param " + m + ".min_bit_margin=0";
  auto r = run("bowl-on-marble", methods, hard + kThesisDecoders);
  const double best = best_single_wrong(r);
  std::printf("bowl-on-marble, margin 0: ensemble wrong %.4f%%, best single code %.4f%%, ratio %.3f\n",
              100 * r["ensemble-nocorr"].wrong(), 100 * best, r["ensemble-nocorr"].wrong() / best);
  EXPECT_LE(r["ensemble-nocorr"].wrong(), 0.2 * best);  // issue 4's goal
  for (const auto& m : kBinary) {
    EXPECT_LT(r["ensemble-nocorr"].wrong(), r[m].wrong()) << m;
    EXPECT_GE(r["ensemble-nocorr"].ok, r[m].ok) << m;  // beats every code on coverage too
  }
  EXPECT_GE(r["xor02"].wrong(), 0.01);  // the marble breaks XOR-02 (§3.3.1)
}

// Product defaults (min_bit_margin 0.1): the single codes reject pixels whose
// planes lost their margin instead of guessing, so XOR-02/04 have almost no
// wrong pixels but lose part of the marble (XOR-02 keeps most of it only as
// one-edge intervals, max_uncertainty_px 0.5; without them it lost 80 %). The
// ensemble keeps the goal against every code that decodes >= 90 % of the lit
// pixels, and decodes far more than the XOR codes. (It decodes ~2 % less than
// Gray here: Gray keeps marble pixels through its tolerated finest plane that
// no second code confirms.)
TEST(SceneClaims, BowlOnMarbleEnsembleDefaults) {
  auto r = run("bowl-on-marble", {"gray", "xor02", "xor04", "minsw", "ensemble"});
  for (const auto& m : kBinary) {
    if (r[m].decoded >= 0.9) {
      EXPECT_LE(r["ensemble"].wrong(), 0.2 * r[m].wrong()) << m;
    }
  }
  EXPECT_GE(r["ensemble"].ok, r["xor02"].ok + 0.05);
  EXPECT_GE(r["ensemble"].ok, r["xor04"].ok + 0.05);
}

// Fig. 3.12 lamp: glossy inter-reflections, the failure case of every code.
// The ensemble's vote cuts the errors; correction rounds (§3.4) then recover
// most of the pixels the detector flags ("we progressively reduce the
// errors"), within issue 4's 0.5 % goal. Since issue 18 a round keeps only
// answers all four codes agree on (measured: 8 wrong of ~80 000 resolved),
// so the rounds must not raise the gross-error rate at all (tolerance: the
// report's 0.005 percentage-point rounding, which also covers the capture
// noise between the two separate scans).
TEST(SceneClaims, MetalLampEnsembleAndCorrection) {
  auto r = run("metal-lamp", {"gray", "xor02", "xor04", "minsw", "ensemble-nocorr", "ensemble"});
  const double best = best_single_wrong(r);
  EXPECT_LT(r["ensemble-nocorr"].wrong(), best);
  EXPECT_GE(r["ensemble"].ok, r["ensemble-nocorr"].ok + 0.05);
  EXPECT_LE(r["ensemble"].gross, r["ensemble-nocorr"].gross + 5e-5);
  EXPECT_LE(r["ensemble"].gross, 0.005);
}

// Issue 18: correction rounds and auto must pay for their patterns. On every
// scene: the ensemble with rounds and auto have gross-error rates (of decoded
// pixels) <= the ensemble without rounds (tolerance as above), auto uses <=
// the ensemble's patterns and is within 0.02 percentage points of the best
// binary method's gross-error rate (tolerance 0.01 pp: two separate captures of the same first pass differed by 0.005 pp on corner-wax with no round run). `rounds_skipped`: where the probe
// must have skipped every round (nothing it can fix), the ensemble uses at
// most 44 + 3 (first pass + one probe) patterns.
void expect_rounds_pay(const std::string& scene, bool rounds_skipped, bool auto_near_best = true) {
  auto r = run(scene, {"gray", "xor02", "xor04", "minsw", "ensemble-nocorr", "ensemble", "auto"});
  double best = 1;
  for (const auto& [m, e] : r) best = std::min(best, e.gross);
  std::printf("%s: best gross %.4f%%, ensemble %.4f%% (%g patterns), auto %.4f%% (%g patterns), nocorr %.4f%%\n",
              scene.c_str(), 100 * best, 100 * r["ensemble"].gross, r["ensemble"].patterns, 100 * r["auto"].gross,
              r["auto"].patterns, 100 * r["ensemble-nocorr"].gross);
  EXPECT_LE(r["ensemble"].gross, r["ensemble-nocorr"].gross + 1e-4) << scene;
  EXPECT_LE(r["auto"].gross, r["ensemble-nocorr"].gross + 1e-4) << scene;
  EXPECT_LE(r["auto"].patterns, r["ensemble"].patterns) << scene;
  if (auto_near_best) {
    EXPECT_LE(r["auto"].gross, best + 2e-4) << scene;
  }
  if (rounds_skipped) {
    EXPECT_LE(r["ensemble"].patterns, 47) << scene << ": the probe should have skipped the round";
  }
}

// Development scenes (the rules were tuned on these and the library):
// corner + wax (the corner's inter-reflections reach the wax, whose flagged
// pixels a mask cannot fix: the probe skips the round) and a glossy pipe
// (mirror paths; one round pays).
TEST(SceneClaims, Issue18CornerWaxRoundSkipped) { expect_rounds_pay("corner-wax", true); }
TEST(SceneClaims, Issue18GlossyPipeRoundPays) { expect_rounds_pay("glossy-pipe", false); }

// Issue 18's acceptance on every scene of the four sets reported in
// docs/report/issue18/README.md: the library, the first validation set
// (val-*, development data since session 11 tuned the two-code midpoint and
// the discard rule on it), the second (val2-*, development data since
// session 13 found the probe's over-forecast on its chrome dish) and the
// third (val3-*, written after the session-13 rules were frozen). Scenes are
// named (library) or paths (validation sets). `auto_near_best` is false only
// where the report states the measured miss of "auto within 0.02 pp of the
// best method" with numbers; the other criteria (rounds and auto never above
// ensemble-nocorr, auto's patterns) are asserted on every scene.
// `rounds_skipped`: the probe must skip the round (ensemble <= 47 patterns):
// on the chrome dish its pixels are too dark under the mask for the round to
// decode (docs/structured-light.md, session 13; before, a round of 42
// patterns was projected and discarded at acceptance 0.08).
struct Issue18Scene {
  const char* scene;
  bool auto_near_best;
  bool rounds_skipped = false;
};
std::ostream& operator<<(std::ostream& o, const Issue18Scene& s) { return o << s.scene; }

class Issue18 : public ::testing::TestWithParam<Issue18Scene> {};

TEST_P(Issue18, RoundsAndAutoPay) {
  const Issue18Scene& s = GetParam();
  std::string scene = s.scene;
  if (scene.rfind("val", 0) == 0) scene = std::string(PROCAM_SOURCE_DIR) + "/configs/scenes/validation/" + scene + ".json";
  expect_rounds_pay(scene, s.rounds_skipped, s.auto_near_best);
}

std::string issue18_name(const ::testing::TestParamInfo<Issue18Scene>& i) {
  std::string n = i.param.scene;
  for (char& c : n)
    if (c == '-') c = '_';
  return n;
}

INSTANTIATE_TEST_SUITE_P(Library, Issue18,
                         ::testing::Values(Issue18Scene{"bowl-on-marble", true}, Issue18Scene{"deep-scene", true},
                                           Issue18Scene{"marble-slab", true}, Issue18Scene{"metal-lamp", true},
                                           Issue18Scene{"plane", true}, Issue18Scene{"shower-curtain", true},
                                           Issue18Scene{"sphere", true}, Issue18Scene{"tilted-box", true},
                                           Issue18Scene{"v-groove", true}, Issue18Scene{"wax-candle", true}),
                         issue18_name);
INSTANTIATE_TEST_SUITE_P(ValidationDev, Issue18,
                         ::testing::Values(Issue18Scene{"val-mixed-depths", true}, Issue18Scene{"val-room-corner", true},
                                           Issue18Scene{"val-steel-sphere-rod", true},
                                           Issue18Scene{"val-wax-among-matte", true}),
                         issue18_name);
INSTANTIATE_TEST_SUITE_P(Validation2, Issue18,
                         ::testing::Values(Issue18Scene{"val2-shelf-corners", true},
                                           Issue18Scene{"val2-chrome-dish-post", true, true},
                                           Issue18Scene{"val2-jade-acrylic-blocks", true},
                                           Issue18Scene{"val2-depth-staircase", true}),
                         issue18_name);
INSTANTIATE_TEST_SUITE_P(Validation3, Issue18,
                         ::testing::Values(Issue18Scene{"val3-niche-corners", true},
                                           // session 13's miss (auto 2.886 % vs xor02 2.326 %) closed
                                           // by the rounds' re-check of first-pass claims (session 14)
                                           Issue18Scene{"val3-copper-nickel-cylinders", true},
                                           Issue18Scene{"val3-alabaster-silicone", true},
                                           Issue18Scene{"val3-near-ramp-far", true}),
                         issue18_name);
// val4-* (fresh in session 14, development since session 15): auto missed
// "within 0.02 pp of the best method" on the milk-glass stack and the near
// box (0.023 / 0.050 %) through the vote's values (the Gray pair's min-SW
// value, the row refinement across a crease); session 15's value rules.
INSTANTIATE_TEST_SUITE_P(Validation4, Issue18,
                         ::testing::Values(Issue18Scene{"val4-crate-corners", true},
                                           Issue18Scene{"val4-brass-bowl-aluminium", true},
                                           Issue18Scene{"val4-milkglass-soap-stack", true},
                                           Issue18Scene{"val4-near-box-far-floor", true}),
                         issue18_name);
// val5-* (fresh in session 16: written before the session-15 value rules were
// measured, measured once after the freeze; all four met every criterion, so
// they guard the rules from here on and are development data now).
INSTANTIATE_TEST_SUITE_P(Validation5, Issue18,
                         ::testing::Values(Issue18Scene{"val5-chrome-bronze-tube", true},
                                           Issue18Scene{"val5-gutter-corners", true},
                                           Issue18Scene{"val5-near-board-ceiling", true},
                                           Issue18Scene{"val5-ptfe-gelatin-opal", true}),
                         issue18_name);

// §2.5 / Fig. 3.4: beyond the depth of field defocus blurs the finest planes.
// min-SW (long minimum stripe) keeps decoding, without errors, where XOR-02
// (finest base plane) cannot. (Gray keeps decoding too, but only through its
// tolerated finest plane: ±1 column, max_weak_error_px.)
TEST(SceneClaims, DeepSceneDefocus) {
  auto r = run("deep-scene", {"gray", "xor02", "minsw"}, kThesisDecoders);
  EXPECT_GE(r["minsw"].ok, r["xor02"].ok + 0.2);
  EXPECT_LE(r["minsw"].wrong(), 0.005);
  EXPECT_GE(r["xor02"].wrong(), 0.01);
}

// Issue 16: min-SW spreads its 1023 stripe edges evenly over its planes, so
// every camera pixel lies within half a column of some plane's edge, and a
// blurred edge fails the margin rule. The product default gives such a pixel
// the interval of its two columns (max_uncertainty_px 0.5): on the defocused
// deep scene and on the bowl's marble it must keep clearly more lit pixels
// (>= 2 points, ~20 000 pixels) than the thesis decoder, with wrong pixels
// not above it (tolerance 0.02 points of lit pixels). Measured: deep scene
// 83.5 -> 91.7 %, bowl 94.3 -> 96.8 %.
TEST(SceneClaims, MinswEdgeIntervalsKeepBlurredPixels) {
  for (const char* scene : {"deep-scene", "bowl-on-marble"}) {
    auto product = run(scene, {"minsw"});
    auto thesis = run(scene, {"minsw"}, kThesisDecoders);
    EXPECT_GE(product["minsw"].ok, thesis["minsw"].ok + 0.02) << scene;
    EXPECT_LE(product["minsw"].wrong(), thesis["minsw"].wrong() + 2e-4) << scene;
  }
}

}  // namespace
