// SPDX-License-Identifier: MIT
// The material library (medium_library.hpp, docs/materials.md): the shipped
// JSON's consistency and its cross-check against pbrt-v3's independent copy
// of the table, Eq. 4.8 scaling and Eq. 4.9-4.10 mixtures against hand
// computations with the thesis's printed numbers, and scene files naming a
// material.
#include "procam/hw/sim/medium_library.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <map>
#include <sstream>

namespace procam::sim {
namespace {

nlohmann::json shipped_json() {
  std::ifstream in(PROCAM_MATERIALS_JSON_FILE);
  std::stringstream ss;
  ss << in.rdbuf();
  return nlohmann::json::parse(ss.str(), nullptr, false);
}

// ---- the data file -----------------------------------------------------------

TEST(MaterialLibraryFile, FortyRowsWithValidCoefficients) {
  const nlohmann::json doc = shipped_json();
  ASSERT_FALSE(doc.is_discarded()) << PROCAM_MATERIALS_JSON_FILE << " is not valid JSON";
  const auto& rows = doc.at("materials");
  ASSERT_EQ(rows.size(), 40u);  // thesis §4.4: forty materials
  std::map<std::string, int> names;
  for (const auto& e : rows) {
    const std::string name = e.at("name").get<std::string>();
    EXPECT_EQ(++names[name], 1) << "duplicate name " << name;
    for (size_t c = 0; c < 3; ++c) {
      const double s = e.at("sigma_t_per_mm").at(c).get<double>();
      const double b = e.at("sigma_s_per_mm").at(c).get<double>();
      EXPECT_GT(s, 0) << name;
      EXPECT_GE(b, 0) << name;
      EXPECT_LE(b, s) << name << " channel " << c << ": beta > sigma";
      EXPECT_LT(s, 0.04) << name << ": §4.4 says every coefficient is < 0.04/mm";
      const auto& g = e.at("g").at(c);
      // g is undefined (null) exactly where the table prints "—", i.e. β = 0.
      EXPECT_EQ(g.is_null(), b == 0) << name << " channel " << c;
      if (!g.is_null()) {
        EXPECT_LT(std::abs(g.get<double>()), 1.0) << name;
      }
    }
    const auto& v = e.at("volume_ml");
    if (!v.is_null()) {
      EXPECT_GT(v.get<double>(), 0) << name;
    }
  }
}

// pbrt-v3 prints σ'_s = β(1 − g) and σ_a = σ − β at natural concentration,
// i.e. the table row divided by c = V/23000 (for two powders pbrt applied no
// dilution factor: "agrees_unscaled"). Every checked row must satisfy it
// within the file's stated tolerance; the counts are those of docs/materials.md.
TEST(MaterialLibraryFile, CrossCheckAgainstPbrtHoldsWithinTolerance) {
  const nlohmann::json doc = shipped_json();
  const double tol = doc.at("check_tolerance_rel").get<double>();
  EXPECT_LE(tol, 0.001);
  std::map<std::string, int> counts;
  for (const auto& e : doc.at("materials")) {
    const std::string check = e.at("check").get<std::string>();
    ++counts[check];
    if (check == "not_in_pbrt") {
      EXPECT_FALSE(e.contains("pbrt"));
      continue;
    }
    ASSERT_TRUE(check == "agrees" || check == "agrees_unscaled") << check;
    const double conc = (check == "agrees_unscaled" || e.at("volume_ml").is_null())
                            ? 1.0
                            : e.at("volume_ml").get<double>() / 23000.0;
    const auto& p = e.at("pbrt");
    for (size_t c = 0; c < 3; ++c) {
      const double s = e.at("sigma_t_per_mm").at(c).get<double>();
      const double b = e.at("sigma_s_per_mm").at(c).get<double>();
      const double g = e.at("g").at(c).is_null() ? 0.0 : e.at("g").at(c).get<double>();
      const double sp = p.at("sigma_prime_s_per_mm").at(c).get<double>();
      const double sa = p.at("sigma_a_per_mm").at(c).get<double>();
      const double pred_sp = b * (1 - g) / conc, pred_sa = (s - b) / conc;
      // Relative to the larger value; values under 1e-3 of the channel's
      // largest are compared to that (pbrt prints 5 significant digits).
      double sp_max = 0, sa_max = 0;
      for (size_t k = 0; k < 3; ++k) {
        sp_max = std::max(sp_max, p.at("sigma_prime_s_per_mm").at(k).get<double>());
        sa_max = std::max(sa_max, p.at("sigma_a_per_mm").at(k).get<double>());
      }
      const std::string name = e.at("name").get<std::string>();
      EXPECT_LE(std::abs(pred_sp - sp), tol * std::max({sp, pred_sp, 1e-3 * sp_max}))
          << name << " channel " << c << ": sigma'_s " << pred_sp << " vs pbrt " << sp;
      EXPECT_LE(std::abs(pred_sa - sa), tol * std::max({sa, pred_sa, 1e-3 * sa_max}))
          << name << " channel " << c << ": sigma_a " << pred_sa << " vs pbrt " << sa;
    }
  }
  EXPECT_EQ(counts["agrees"], 33);
  EXPECT_EQ(counts["agrees_unscaled"], 2);
  EXPECT_EQ(counts["not_in_pbrt"], 5);
}

TEST(MaterialLibrary, CompiledInCopyMatchesTheFile) {
  const nlohmann::json doc = shipped_json();
  const auto& lib = material_library();
  ASSERT_EQ(lib.size(), doc.at("materials").size());
  for (size_t i = 0; i < lib.size(); ++i) {
    const auto& e = doc.at("materials").at(i);
    EXPECT_EQ(lib[i].name, e.at("name").get<std::string>());
    for (size_t c = 0; c < 3; ++c) {
      EXPECT_DOUBLE_EQ(lib[i].sigma_t_per_mm[c], e.at("sigma_t_per_mm").at(c).get<double>());
      EXPECT_DOUBLE_EQ(lib[i].sigma_s_per_mm[c], e.at("sigma_s_per_mm").at(c).get<double>());
      EXPECT_EQ(std::isnan(lib[i].g[c]), e.at("g").at(c).is_null());
    }
  }
}

// ---- lookup, Eq. 4.8, Eq. 4.9-4.10 (numbers typed from the thesis table) ---------

TEST(MaterialLibrary, LooksUpByEitherNameCaseInsensitive) {
  ASSERT_NE(find_material("merlot"), nullptr);
  EXPECT_EQ(find_material("Wine (merlot)"), find_material("MERLOT"));
  EXPECT_EQ(find_material("milk"), find_material("Lowfat Milk"));
  EXPECT_EQ(find_material("  Espresso "), find_material("Coffee (espresso)"));
  EXPECT_EQ(find_material("unobtainium"), nullptr);
  EXPECT_DOUBLE_EQ(find_material("Lemon Tea Powder")->volume_ml, 5 * 4.92892);  // "5tsp", US teaspoon
  EXPECT_DOUBLE_EQ(find_material("Pacific Ocean Surface Water")->concentration(), 1.0);
}

TEST(MaterialLibrary, TableDilutionReproducesTheTableRow) {
  // Lowfat milk, 16 ml in 23 l, green: 1.0748, 1.0744 (×1e-2/mm), g 0.902.
  const Result<Medium> m = material_medium("Lowfat Milk", 16, 23, ColorChannel::green);
  ASSERT_TRUE(m.ok()) << m.status().message();
  EXPECT_NEAR(m->sigma_t_per_mm, 1.0748e-2, 1e-12);
  EXPECT_NEAR(m->sigma_s_per_mm, 1.0744e-2, 1e-12);
  EXPECT_NEAR(m->g, 0.902, 1e-12);
}

TEST(MaterialLibrary, Eq48ScalesWithVolumeAndTank) {
  // Merlot, table 1500 ml, red σ 0.7639e-2, β 0.0053e-2, g 0.974.
  // 20 ml in 23 l: × 20/1500; the same 20 ml in 11.5 l: twice that.
  const Result<Medium> a = material_medium("Merlot", 20, 23, ColorChannel::red);
  const Result<Medium> b = material_medium("Merlot", 20, 11.5, ColorChannel::red);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_NEAR(a->sigma_t_per_mm, 0.7639e-2 * 20 / 1500, 1e-12);
  EXPECT_NEAR(a->sigma_s_per_mm, 0.0053e-2 * 20 / 1500, 1e-12);
  EXPECT_NEAR(a->g, 0.974, 1e-12);  // g does not scale
  EXPECT_NEAR(b->sigma_t_per_mm, 2 * 0.7639e-2 * 20 / 1500, 1e-12);
  // Green Merlot has β = 0: g is undefined in the table and 0 here (no NaN).
  const Result<Medium> gm = material_medium("Merlot", 1500, 23, ColorChannel::green);
  ASSERT_TRUE(gm.ok());
  EXPECT_EQ(gm->sigma_s_per_mm, 0.0);
  EXPECT_EQ(gm->g, 0.0);
  EXPECT_NEAR(gm->sigma_t_per_mm, 1.6429e-2, 1e-12);
  // Ocean water is tabulated at natural concentration: 23 l of it = the row.
  const Result<Medium> ocean = material_medium("Pacific Ocean Surface Water", 23000, 23, ColorChannel::blue);
  ASSERT_TRUE(ocean.ok());
  EXPECT_NEAR(ocean->sigma_t_per_mm, 3.2428e-2, 1e-12);
}

TEST(MaterialLibrary, Eq49And410MixMilkAndEspresso) {
  // "milk + espresso 1:3", 24 ml in 23 l, green: 6 ml lowfat milk (table
  // 16 ml: σ 1.0748, β 1.0744, g 0.902) + 18 ml espresso (table 8 ml:
  // σ 0.5115, β 0.2828, g 0.896), all ×1e-2/mm.
  const double bm = 1.0744e-2 * 6 / 16, be = 0.2828e-2 * 18 / 8;
  const double sigma = 1.0748e-2 * 6 / 16 + 0.5115e-2 * 18 / 8;
  const double g = (0.902 * bm + 0.896 * be) / (bm + be);
  const Result<std::vector<MixturePart>> parts = parse_mixture_spec("milk + espresso 1:3", 24);
  ASSERT_TRUE(parts.ok()) << parts.status().message();
  ASSERT_EQ(parts->size(), 2u);
  EXPECT_DOUBLE_EQ((*parts)[0].volume_ml, 6);
  EXPECT_DOUBLE_EQ((*parts)[1].volume_ml, 18);
  const Result<Medium> m = mixture_medium(*parts, 23, ColorChannel::green);
  ASSERT_TRUE(m.ok()) << m.status().message();
  EXPECT_NEAR(m->sigma_t_per_mm, sigma, 1e-12);
  EXPECT_NEAR(m->sigma_s_per_mm, bm + be, 1e-12);
  EXPECT_NEAR(m->g, g, 1e-12);
  // A mixture with a pure absorber: g stays the scatterer's (β-weighted).
  const Result<Medium> w = mixture_medium({{"milk", 6}, {"Merlot", 100}}, 23, ColorChannel::green);
  ASSERT_TRUE(w.ok());
  EXPECT_NEAR(w->g, 0.902, 1e-12);
  // No ratio: equal parts.
  const Result<std::vector<MixturePart>> eq = parse_mixture_spec("Coke+Sprite", 10);
  ASSERT_TRUE(eq.ok());
  EXPECT_DOUBLE_EQ((*eq)[1].volume_ml, 5);
}

TEST(MaterialLibrary, RejectsBadInputWithAHint) {
  const Result<Medium> unknown = material_medium("unobtainium", 10, 23, ColorChannel::green);
  ASSERT_FALSE(unknown.ok());
  EXPECT_NE(unknown.status().hint().find("Merlot"), std::string::npos);  // lists the names
  EXPECT_FALSE(material_medium("Merlot", 0, 23, ColorChannel::green).ok());
  EXPECT_FALSE(material_medium("Merlot", 10, 0, ColorChannel::green).ok());
  EXPECT_FALSE(material_medium("Merlot", 1e9, 23, ColorChannel::green).ok());  // σ > 10/mm
  EXPECT_FALSE(parse_mixture_spec("milk + espresso 1:x", 10).ok());
  EXPECT_FALSE(parse_mixture_spec("milk + espresso 1:2:3", 10).ok());
  EXPECT_FALSE(parse_mixture_spec("milk + ", 10).ok());
  EXPECT_FALSE(parse_color_channel("ultraviolet").ok());
  EXPECT_EQ(*parse_color_channel("Blue"), ColorChannel::blue);
}

// ---- scene files -------------------------------------------------------------------

Result<Scene> scene_with_medium(const std::string& medium) {
  return parse_scene(nlohmann::json::parse(R"({"objects": [{"type": "plane", "point_mm": [0, 0, 900], "normal": [0, 0, -1]}],
                                                "medium": )" + medium + "}"),
                     "test.json");
}

TEST(MaterialScene, NamedMaterialAndMixturesLoad) {
  const Result<Scene> s = scene_with_medium(
      R"({"material": "Merlot", "volume_ml": 20, "tank_litres": 23, "channel": "red", "dop_model": "none"})");
  ASSERT_TRUE(s.ok()) << s.status().message();
  EXPECT_NEAR(s->medium->sigma_t_per_mm, 0.7639e-2 * 20 / 1500, 1e-12);
  EXPECT_EQ(s->medium->dop_model, Medium::DopModel::none);
  // Defaults: 23 l tank, green.
  const Result<Scene> d = scene_with_medium(R"({"material": "Lowfat Milk", "volume_ml": 16})");
  ASSERT_TRUE(d.ok()) << d.status().message();
  EXPECT_NEAR(d->medium->sigma_t_per_mm, 1.0748e-2, 1e-12);
  const Result<Scene> mix = scene_with_medium(R"({"material": "milk + espresso 1:3", "volume_ml": 24})");
  ASSERT_TRUE(mix.ok()) << mix.status().message();
  EXPECT_NEAR(mix->medium->sigma_t_per_mm, 1.0748e-2 * 6 / 16 + 0.5115e-2 * 18 / 8, 1e-12);
  const Result<Scene> list = scene_with_medium(
      R"({"material": [{"name": "milk", "volume_ml": 6}, {"name": "Espresso", "volume_ml": 18}]})");
  ASSERT_TRUE(list.ok()) << list.status().message();
  EXPECT_NEAR(list->medium->sigma_t_per_mm, mix->medium->sigma_t_per_mm, 1e-15);
}

TEST(MaterialScene, RejectsConflictsAndUnknownsNamingTheField) {
  const Result<Scene> both = scene_with_medium(R"({"material": "Merlot", "volume_ml": 20, "sigma_t_per_mm": 0.01})");
  ASSERT_FALSE(both.ok());
  EXPECT_NE(both.status().message().find("medium.sigma_t_per_mm"), std::string::npos) << both.status().message();
  const Result<Scene> novol = scene_with_medium(R"({"material": "Merlot"})");
  ASSERT_FALSE(novol.ok());
  EXPECT_NE(novol.status().message().find("medium.volume_ml"), std::string::npos) << novol.status().message();
  const Result<Scene> unk = scene_with_medium(R"({"material": "Unobtainium", "volume_ml": 20})");
  ASSERT_FALSE(unk.ok());
  EXPECT_NE(unk.status().message().find("medium.material"), std::string::npos) << unk.status().message();
  const Result<Scene> ch = scene_with_medium(R"({"material": "Merlot", "volume_ml": 20, "channel": "uv"})");
  ASSERT_FALSE(ch.ok());
  EXPECT_NE(ch.status().message().find("medium.channel"), std::string::npos) << ch.status().message();
}

}  // namespace
}  // namespace procam::sim
