// SPDX-License-Identifier: MIT
// Speed of the ensemble decode and of Gray column+row decoding vs OpenCV
// contrib (issue 4 "Speed"). Camera 1920x1200 8-bit; projector 1024x768, so
// the ensemble is exactly the thesis's 41 frames (4 codes x 10 planes + white).
//   BM_EnsembleDecode/threads: decoder construction (output maps allocated and
//     touched) + all add_frame work + per-code decode + vote — what a scan
//     pays, as codes_session.cpp runs it (max_weak_error_px = 1, its default).
//   BM_EnsembleAfterLastFrame/threads: the streaming latency — the last
//     frame's add_frame + decode + vote + releasing the decoder (as the
//     session's end_round), with the other 40 frames already in.
//   BM_EnsembleRefine/0|1: outputs()' sub-pixel refinement and reported
//     column on the vote map, one thread (see the bench).
//   BM_GrayColRowDecode/threads vs BM_OpenCvGetProjPixel: Gray code columns
//     and rows with inverses on the *same frames* (OpenCV's own generated
//     patterns, checked equal to ours); OpenCV's getProjPixel is called for
//     every pixel. Counter "mismatch" counts pixels whose correspondences
//     differ (valid/invalid or value).
// Run: build-*/plugins/structured-light/procam_sl_ensemble_bench
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <utility>
#include <vector>

#include "codes.hpp"
#include "gray_code.hpp"
#include "multi_round.hpp"
#include "plan_layout.hpp"
#include "round_decoder.hpp"
#include "subpixel.hpp"
#include "vote.hpp"

#ifdef PROCAM_SL_HAVE_OPENCV_SL
#include <opencv2/structured_light.hpp>
#endif

namespace procam::sl {
namespace {

constexpr uint32_t kCamW = 1920, kCamH = 1200, kProjW = 1024, kProjH = 768;

uint32_t cam_col(uint32_t x, uint32_t y) { return (x * 9 / 10 + y / 20 + 10) * kProjW / kCamW; }
uint32_t cam_row(uint32_t x, uint32_t y) { return (y * 9 / 10 + x / 40 + 10) * kProjH / kCamH; }

procam_image view_of(const std::vector<uint8_t>& px) { return sdk::gray_view(px.data(), kCamW, kCamH); }

// Camera frame of a projector pattern (U8 projector image): 220 lit, 15 dark.
std::vector<uint8_t> capture(const uint8_t* pattern) {
  std::vector<uint8_t> px(size_t{kCamW} * kCamH);
  for (uint32_t y = 0; y < kCamH; ++y)
    for (uint32_t x = 0; x < kCamW; ++x)
      px[size_t{y} * kCamW + x] = pattern[size_t{cam_row(x, y)} * kProjW + cam_col(x, y)] ? 220 : 15;
  return px;
}

struct EnsembleData {
  std::vector<ProjectedCode> codes;
  MultiLayout layout;
  std::vector<std::vector<uint8_t>> pixels;
  std::vector<procam_image> views;
  EnsembleData() {
    for (const char* id : kCodeIds) codes.push_back(make_projected_code(id, kProjW));
    layout = make_multi_layout(codes, false, false);
    sdk::Plan plan;
    render_multi_plan(layout, codes, kProjW, kProjH, nullptr, plan);
    for (uint32_t i = 0; i < plan.size(); ++i) pixels.push_back(capture(plan.pattern_u8(i).data()));
    for (const auto& p : pixels) views.push_back(view_of(p));
    if (views.size() != 41) std::abort();
  }
};
EnsembleData& ens() {
  static EnsembleData d;
  return d;
}

// What the ensemble session does at end_round (codes_session.cpp): decode the
// four codes and vote in one pass into the decoder's pre-allocated maps.
MultiResult& decode_and_vote(MultiCodeDecoder& dec) {
  VoteSpec spec;
  for (uint32_t k = 0; k < kEnsembleCodes; ++k) spec.round_code[k] = static_cast<int32_t>(k);
  spec.agree_px = 1.0f;
  return dec.finish_vote(0.03, 0.1, spec);
}

// The whole cost of a scan's decode: the decoder (allocated per round, as in
// the session, with its output maps), all 41 add_frame calls, decode + vote.
void BM_EnsembleDecode(benchmark::State& state) {
  const auto threads = static_cast<uint32_t>(state.range(0));
  EnsembleData& d = ens();
  for (auto _ : state) {
    MultiCodeDecoder dec(d.layout, d.codes, kCamW, kCamH, threads, 1, MultiCodeDecoder::Output::vote);
    for (uint32_t i = 0; i < d.views.size(); ++i)
      if (!dec.add_frame(i, d.views[i]).ok()) std::abort();
    MultiResult& r = decode_and_vote(dec);
    benchmark::DoNotOptimize(r.vote.coord.data());
    recycle_maps(std::move(r));  // as the session's end does (map_cache.hpp)
  }
}
BENCHMARK(BM_EnsembleDecode)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_EnsembleAfterLastFrame(benchmark::State& state) {
  const auto threads = static_cast<uint32_t>(state.range(0));
  EnsembleData& d = ens();
  for (auto _ : state) {
    state.PauseTiming();
    auto dec = std::make_unique<MultiCodeDecoder>(d.layout, d.codes, kCamW, kCamH, threads, 1,
                                                  MultiCodeDecoder::Output::vote);
    const auto last = static_cast<uint32_t>(d.views.size() - 1);
    for (uint32_t i = 0; i < last; ++i)
      if (!dec->add_frame(i, d.views[i]).ok()) std::abort();
    state.ResumeTiming();
    // As the session's end_round: last frame, decode + vote, maps moved out,
    // decoder released (its state goes back to the buffer cache).
    if (!dec->add_frame(last, d.views[last]).ok()) std::abort();
    MultiResult r = std::move(decode_and_vote(*dec));
    dec.reset();
    benchmark::DoNotOptimize(r.vote.coord.data());
    state.PauseTiming();
    recycle_maps(std::move(r));  // the host releases the outputs later (session end)
    state.ResumeTiming();
  }
}
BENCHMARK(BM_EnsembleAfterLastFrame)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

// Stages with all frames in: per-code decode into per-code maps (finish) and
// the fused decode + vote (finish_vote).
void BM_EnsembleStages(benchmark::State& state) {
  const auto threads = static_cast<uint32_t>(state.range(0));
  const bool vote = state.range(1) != 0;
  EnsembleData& d = ens();
  MultiCodeDecoder dec(d.layout, d.codes, kCamW, kCamH, threads, 1,
                       vote ? MultiCodeDecoder::Output::vote : MultiCodeDecoder::Output::per_code);
  for (uint32_t i = 0; i < d.views.size(); ++i)
    if (!dec.add_frame(i, d.views[i]).ok()) std::abort();
  for (auto _ : state) {
    // The maps stay in the decoder and are overwritten (this stage is the
    // decode itself; allocation is the decoder constructor's job).
    MultiResult& r = vote ? decode_and_vote(dec) : dec.finish(0.03, 0.1);
    benchmark::DoNotOptimize(vote ? r.vote.coord.data() : r.codes[0].coord.data());
  }
}
BENCHMARK(BM_EnsembleStages)->ArgsProduct({{1, 2}, {0, 1}})->ArgNames({"threads", "fused_vote"})
    ->Unit(benchmark::kMillisecond)->UseRealTime();

// What structured-light's outputs() does with the voted columns, on one
// thread (the session splits it over the rig's threads in row bands):
// refine_columns (subpixel.hpp) and report_columns (vote.hpp) on the
// ensemble's real vote map. Arg 0: the vote's map as it is (multiples of
// 1/4: the kernel sums in float, exactly); arg 1: the same map shifted by
// 1/8 column, off the quarter grid, so the kernel takes its double-sum path
// (the cost before issue 17's float sums; same pixels, same neighbours).
void BM_EnsembleRefine(benchmark::State& state) {
  static const MultiResult voted = [] {
    EnsembleData& d = ens();
    MultiCodeDecoder dec(d.layout, d.codes, kCamW, kCamH, 2, 1, MultiCodeDecoder::Output::vote);
    for (uint32_t i = 0; i < d.views.size(); ++i)
      if (!dec.add_frame(i, d.views[i]).ok()) std::abort();
    return std::move(decode_and_vote(dec));
  }();
  std::vector<float> coord = voted.vote.coord;
  if (state.range(0) == 1)
    for (float& c : coord) c += 0.125f;
  std::vector<float> refined(coord.size()), reported(coord.size());
  for (auto _ : state) {
    state.PauseTiming();
    reported = coord;
    state.ResumeTiming();
    refine_columns(coord.data(), kCamW, 0, kCamH, SubpixelOptions{}, refined.data());
    report_columns(reported.data(), voted.vote.valid.data(), voted.vote.confidence.data(), refined.data(),
                   reported.size());
    benchmark::DoNotOptimize(reported.data());
  }
  state.SetLabel(state.range(0) == 0 ? "vote map: float sums" : "off-grid map: double sums");
}
BENCHMARK(BM_EnsembleRefine)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

struct GrayData {
  StripeCode cols = make_gray_code(kProjW), rows = make_gray_code(kProjH);
  Layout layout = make_layout(cols, &rows, true);
  std::vector<std::vector<uint8_t>> pixels;  // our layout order
  std::vector<procam_image> views;
  GrayData() {
    sdk::Plan plan;
    render_plan(layout, cols, &rows, kProjW, kProjH, plan);
    for (uint32_t i = 0; i < plan.size(); ++i) pixels.push_back(capture(plan.pattern_u8(i).data()));
    for (const auto& p : pixels) views.push_back(view_of(p));
  }
};
GrayData& gray() {
  static GrayData d;
  return d;
}

RoundResult gray_decode(uint32_t threads) {
  GrayData& d = gray();
  // max_weak_error_px = 0: OpenCV has no tolerated weak planes.
  BinaryRoundDecoder dec(d.layout, d.cols, &d.rows, kCamW, kCamH, threads, 0);
  for (uint32_t i = 0; i < d.views.size(); ++i)
    if (!dec.add_frame(i, d.views[i]).ok()) std::abort();
  return dec.finish(0.03, 0.1);
}

void BM_GrayColRowDecode(benchmark::State& state) {
  const auto threads = static_cast<uint32_t>(state.range(0));
  for (auto _ : state) {
    RoundResult r = gray_decode(threads);
    benchmark::DoNotOptimize(r.cols.coord.data());
    recycle_maps(std::move(r));  // as the session's end does (map_cache.hpp)
  }
}
BENCHMARK(BM_GrayColRowDecode)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

#ifdef PROCAM_SL_HAVE_OPENCV_SL
void BM_OpenCvGetProjPixel(benchmark::State& state) {
  GrayData& d = gray();
  cv::structured_light::GrayCodePattern::Params p;
  p.width = kProjW;
  p.height = kProjH;
  auto gcp = cv::structured_light::GrayCodePattern::create(p);
  std::vector<cv::Mat> patterns;
  gcp->generate(patterns);
  // OpenCV order: col bits (pattern, inverse) MSB first, then row bits — the
  // same as our layout without white/black. Check the patterns are identical.
  if (patterns.size() + 2 != d.layout.frames.size()) std::abort();
  sdk::Plan plan;
  render_plan(d.layout, d.cols, &d.rows, kProjW, kProjH, plan);
  size_t pattern_diff = 0;
  for (size_t i = 0; i < patterns.size(); ++i) {
    const auto ours = plan.pattern_u8(static_cast<uint32_t>(i + 2));
    for (uint32_t y = 0; y < kProjH; ++y)
      for (uint32_t x = 0; x < kProjW; ++x)
        pattern_diff += (patterns[i].at<uint8_t>(static_cast<int>(y), static_cast<int>(x)) != 0) !=
                        (ours[size_t{y} * kProjW + x] != 0);
  }
  std::vector<cv::Mat> frames;  // the same camera frames we decode
  for (size_t i = 2; i < d.pixels.size(); ++i)
    frames.emplace_back(static_cast<int>(kCamH), static_cast<int>(kCamW), CV_8U, d.pixels[i].data());
  cv::Mat col(static_cast<int>(kCamH), static_cast<int>(kCamW), CV_32F), row = col.clone();
  for (auto _ : state) {
    for (int y = 0; y < static_cast<int>(kCamH); ++y)
      for (int x = 0; x < static_cast<int>(kCamW); ++x) {
        cv::Point pp;
        const bool error = gcp->getProjPixel(frames, x, y, pp);
        col.at<float>(y, x) = error ? -1.0f : static_cast<float>(pp.x);
        row.at<float>(y, x) = error ? -1.0f : static_cast<float>(pp.y);
      }
    benchmark::DoNotOptimize(col.data);
  }
  const RoundResult ours = gray_decode(2);
  size_t mismatch = 0;
  for (uint32_t y = 0; y < kCamH; ++y)
    for (uint32_t x = 0; x < kCamW; ++x) {
      const size_t i = size_t{y} * kCamW + x;
      const float oc = ours.cols.valid[i] ? ours.cols.coord[i] : -1.0f;
      const float orow = std::isnan(ours.rows.coord[i]) ? -1.0f : ours.rows.coord[i];
      mismatch += oc != col.at<float>(static_cast<int>(y), static_cast<int>(x)) ||
                  orow != row.at<float>(static_cast<int>(y), static_cast<int>(x));
    }
  state.counters["pattern_diff"] = static_cast<double>(pattern_diff);
  state.counters["mismatch"] = static_cast<double>(mismatch);
}
BENCHMARK(BM_OpenCvGetProjPixel)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(3);
#endif

}  // namespace
}  // namespace procam::sl

BENCHMARK_MAIN();
