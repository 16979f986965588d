// MonitorEngine (slicer -> class match -> analyzer -> thresholds -> k-of-n). The training glue is in
// baseline_training.cpp. See docs/windows.md.
#include "ptda/dsp/monitor_engine.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <utility>

#include "number_text.hpp"
#include "ptda/common/error.hpp"
#include "ptda/dsp/order_windows.hpp"
#include "ptda/dsp/training.hpp"

namespace ptda::dsp {
namespace {

using detail::num;

// Checked before anything is built from the baseline, so a mismatch names the real cause.
const Baseline& checked(const Baseline& b, const ExtractionConfig& cfg, double fs_hz) {
  if (b.domain == Domain::kOrder && !(fs_hz == b.fs_hz)) {
    // An order baseline fed time samples (e.g. ptdad, which has no order domain yet): say so.
    throw Error("monitor: the baseline is an order-domain baseline (" + std::to_string(b.revolutions) +
                " revolutions of " + std::to_string(b.samples_per_rev) +
                " samples) but this input is time samples at " + num(fs_hz) +
                " Hz: the order domain runs in ptda train/monitor only ([extraction] domain = \"order\")");
  }
  if (!(std::isfinite(fs_hz) && fs_hz > 0.0) || !(std::fabs(b.fs_hz - fs_hz) <= 1e-6 * fs_hz)) {
    throw Error("monitor: baseline was trained at fs_hz = " + num(b.fs_hz) + " Hz but the input runs at " +
                num(fs_hz) + " Hz (must agree within 1e-6 relative)");
  }
  if (b.window_len != cfg.window_len) {
    throw Error("monitor: baseline window_len = " + std::to_string(b.window_len) +
                " but extraction.window_len = " + std::to_string(cfg.window_len));
  }
  if (b.classes.empty()) throw Error("monitor: baseline has no segment classes");
  const std::size_t bins = b.window_len / 2 + 1;
  for (std::size_t i = 0; i < b.classes.size(); ++i) {
    const ClassBaseline& c = b.classes[i];
    if (c.mean_magnitude.size() != bins || c.tda_mean.size() != b.window_len) {
      throw Error("monitor: baseline class " + std::to_string(i) + " has " +
                  std::to_string(c.mean_magnitude.size()) + " magnitude bins and " +
                  std::to_string(c.tda_mean.size()) + " mean samples, expected " + std::to_string(bins) +
                  " and " + std::to_string(b.window_len));
    }
  }
  return b;
}

}  // namespace

MonitorEngine::MonitorEngine(const Baseline& baseline, const ExtractionConfig& cfg,
                             const DecisionConfig& decision, Method method, double fs_hz, std::int64_t t0_ns)
    : baseline_(checked(baseline, cfg, fs_hz)),
      method_(method),
      slicer_(cfg, fs_hz, t0_ns),
      analyzer_(cfg.window_len),
      decision_(decision, baseline_.classes.size()),
      window_(cfg.window_len, 0.0F) {
  // The line groups are runtime state derived from the stored means: recomputed on the engine's copy,
  // so an engine built from any baseline (read, trained or made by hand) scores the residual it was
  // trained on.
  prepare_line_groups(baseline_);
  for (const ClassBaseline& c : baseline_.classes) {
    z_scale_.push_back(sequential_scale(c, method, baseline_.policy, decision.sequential.day_allowance));
  }
}

DecisionState::DecisionState(const DecisionConfig& decision, std::size_t classes)
    : debouncer_(decision.k, decision.n), seq_(decision.sequential), cusum_(classes) {
  check_sequential(seq_);
  cap_ = seq_.h_alarm + static_cast<double>(decision.n - std::min(decision.k, decision.n)) * seq_.k;
}

void DecisionState::scored(WindowResult& w, std::size_t cls) noexcept {
  debouncer_.push(w.verdict.abnormal());
  if (seq_.enabled && cls < cusum_.size()) {
    Cusum& c = cusum_[cls];
    c.update(w.z_rms, w.z_entropy, seq_.k, cap_, w.seq_allowance_rms, w.seq_allowance_entropy);
    w.seq_statistic = c.statistic();
    w.seq_feature = c.feature();
  }
  fill(w);
}

void DecisionState::unscored(WindowResult& w) const noexcept {
  fill(w);
}

void DecisionState::fill(WindowResult& w) const noexcept {
  w.kofn_alarm = debouncer_.active();
  w.abnormal_in_last_n = debouncer_.abnormal_in_window();
  double worst = 0.0;
  for (const Cusum& c : cusum_) worst = std::max(worst, c.statistic());
  w.seq_max_statistic = worst;
  w.seq_warn = seq_.enabled && worst >= seq_.h_warn;
  w.seq_alarm = seq_.enabled && worst >= seq_.h_alarm;
  w.alarm = w.kofn_alarm || w.seq_alarm;
  w.detector = w.kofn_alarm ? (w.seq_alarm ? AlarmDetector::kBoth : AlarmDetector::kKOfN)
                            : (w.seq_alarm ? AlarmDetector::kSequential : AlarmDetector::kNone);
}

void MonitorEngine::push_speed(const SpeedSample& s) noexcept {
  slicer_.push_speed(s);
}
void MonitorEngine::push_samples(std::span<const float> block) noexcept {
  slicer_.push_samples(block);
}
void MonitorEngine::mark_gap(std::uint64_t count) noexcept {
  slicer_.mark_gap(count);
}
void MonitorEngine::finish() noexcept {
  slicer_.finish();
}

bool MonitorEngine::poll(WindowResult& out) noexcept {
  WindowRef ref;
  if (!slicer_.pop(ref, window_)) return false;
  // The slicer's completed regions are for training and reports; the engine does not keep them.
  RegionInfo region;
  while (slicer_.pop_region(region)) {
  }
  score(ref, out);
  return true;
}

void MonitorEngine::judge_window(const WindowRef& ref, std::span<const float> window,
                                 WindowResult& out) noexcept {
  if (window.size() != window_.size()) {
    out = WindowResult{};
    out.ref = ref;
    out.status = WindowStatus::kNoClass;
    decision_.unscored(out);
    return;
  }
  std::copy(window.begin(), window.end(), window_.begin());
  score(ref, out);
}

void MonitorEngine::score(const WindowRef& ref, WindowResult& out) noexcept {
  out = WindowResult{};
  out.ref = ref;
  const ClassBaseline* cls = baseline_.match(ref.speed_rad_s);
  if (cls == nullptr) {
    // Not comparable with any healthy reference: reported, but neither judged nor debounced.
    out.status = WindowStatus::kNoClass;
    decision_.unscored(out);
    return;
  }
  out.status = WindowStatus::kScored;
  out.class_id = static_cast<std::int32_t>(cls->segment.id);
  // Order domain: the window taken to its class's speed by the trained speed law (0 in the time domain).
  if (baseline_.speed_law_exponent != 0.0) {
    const auto g = static_cast<float>(
        speed_law_gain(cls->segment.speed_rad_s, ref.speed_rad_s, baseline_.speed_law_exponent));
    for (float& x : window_) x *= g;
  }
  out.features = analyzer_.analyze(window_, *cls, method_);
  out.thresholds = cls->thresholds[static_cast<std::size_t>(method_)];
  out.verdict = judge(out.features, out.thresholds);
  const auto ci = static_cast<std::size_t>(cls - baseline_.classes.data());
  const StandardScores z = standardize(out.features, z_scale_[ci]);
  out.z_rms = z.rms;
  out.z_entropy = z.entropy;
  out.seq_allowance_rms = z_scale_[ci].rms_allowance;
  out.seq_allowance_entropy = z_scale_[ci].entropy_allowance;
  decision_.scored(out, ci);
}

}  // namespace ptda::dsp
