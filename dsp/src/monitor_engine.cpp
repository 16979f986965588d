// MonitorEngine (slicer -> class match -> analyzer -> thresholds -> k-of-n). The training glue is in
// baseline_training.cpp. See docs/windows.md.
#include "ptda/dsp/monitor_engine.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
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

std::string band_cusum_unusable(const DecisionConfig& d, const Baseline& b, Method method) {
  if (method != Method::kPtda) {
    return std::string("method \"") + std::string(method_name(method)) +
           "\" (the band statistics are those of the PTDA residual)";
  }
  if (b.policy.band_count == 0) {
    return "the baseline has no band statistics (format <= 6, or trained with band_cusum = false or another "
           "method): "
           "retrain to use it";
  }
  if (b.policy.band_count != d.band.band_count) {
    return "the baseline has " + std::to_string(b.policy.band_count) + " bands, [decision] band_count is " +
           std::to_string(d.band.band_count);
  }
  return {};
}

DecisionConfig effective_band(DecisionConfig d, const Baseline& b, Method method) {
  if (d.band.enabled && !d.band.required && !band_cusum_unusable(d, b, method).empty())
    d.band.enabled = false;
  return d;
}

std::string mesh_cusum_unusable(const DecisionConfig& /*d*/, const Baseline& b) {
  if (b.domain != Domain::kTime)
    return "an order-domain baseline (the mesh detector runs in the time domain)";
  if (!b.policy.mesh_stats) {
    return "the baseline has no mesh statistics (format <= 7, or trained with mesh_cusum = false or without "
           "the gearbox's teeth): retrain to use it";
  }
  return {};
}

DecisionConfig effective_detectors(DecisionConfig d, const Baseline& b, Method method) {
  d = effective_band(d, b, method);
  if (d.mesh.enabled && !d.mesh.required && !mesh_cusum_unusable(d, b).empty()) d.mesh.enabled = false;
  return d;
}

namespace {

// The band CUSUM needs the band statistics of this very configuration: said here, before anything runs.
// On by default (not required), it is switched off where it cannot run; asked for, that is an error.
// The default-on mesh detector is switched off likewise (its explicit checks are in the constructor).
DecisionConfig checked_band(DecisionConfig d, const Baseline& b, Method method) {
  d = effective_detectors(d, b, method);
  if (!d.band.enabled) return d;
  check_band_cusum(d.band);
  if (method != Method::kPtda) {
    throw Error(std::string("monitor: [decision] band_cusum needs [monitor] method = \"ptda\" (the band "
                            "statistics are those of the PTDA residual), got \"") +
                std::string(method_name(method)) + "\"");
  }
  if (b.policy.band_count == 0) {
    throw Error(
        "monitor: [decision] band_cusum = true needs a baseline with band-energy statistics "
        "(format 7, trained with band_cusum = true); this baseline has none: retrain it with "
        "[decision] band_cusum = true");
  }
  if (b.policy.band_count != d.band.band_count) {
    throw Error("monitor: [decision] band_count = " + std::to_string(d.band.band_count) +
                " but the baseline was trained with " + std::to_string(b.policy.band_count) +
                " bands: set band_count = " + std::to_string(b.policy.band_count) + " or retrain");
  }
  for (std::size_t i = 0; i < b.classes.size(); ++i) {
    if (b.classes[i].band_stats.size() != b.policy.band_count) {
      throw Error("monitor: baseline class " + std::to_string(i) + " has " +
                  std::to_string(b.classes[i].band_stats.size()) + " band statistics, expected " +
                  std::to_string(b.policy.band_count));
    }
  }
  return d;
}

}  // namespace

namespace {

// Whether statistic s (above h since crossing number `since`, 0 = not above) ranks before the current
// top: larger, or equal and above h for longer (the band that crossed first; e.g. several at the cap).
bool band_first(double s, std::uint64_t since, double top, std::uint64_t top_since) noexcept {
  if (s > top) return true;
  return s == top && s > 0.0 && since != 0 && (top_since == 0 || since < top_since);
}

}  // namespace

DecisionConfig with_band_geometry(DecisionConfig decision, const Baseline& baseline) noexcept {
  decision.band.half_bins = baseline.window_len / 2;
  decision.band.bin_hz =
      baseline.window_len > 0 ? baseline.fs_hz / static_cast<double>(baseline.window_len) : 0.0;
  return decision;
}

MonitorEngine::MonitorEngine(const Baseline& baseline, const ExtractionConfig& cfg,
                             const DecisionConfig& decision, Method method, double fs_hz, std::int64_t t0_ns)
    : baseline_(checked(baseline, cfg, fs_hz)),
      method_(method),
      slicer_(cfg, fs_hz, t0_ns),
      analyzer_(cfg.window_len),
      decision_(with_band_geometry(checked_band(decision, baseline_, method), baseline_),
                baseline_.classes.size()),
      window_(cfg.window_len, 0.0F) {
  // The line groups are runtime state derived from the stored means: recomputed on the engine's copy,
  // so an engine built from any baseline (read, trained or made by hand) scores the residual it was
  // trained on.
  prepare_line_groups(baseline_);
  for (const ClassBaseline& c : baseline_.classes) {
    z_scale_.push_back(sequential_scale(c, method, baseline_.policy, decision.sequential.day_allowance));
  }
  if (decision.mesh.enabled && !decision.mesh.required)
    mesh_off_reason_ = mesh_cusum_unusable(decision, baseline_);
  if (decision.mesh.enabled && mesh_off_reason_.empty()) {
    // Asked for explicitly: a baseline without mesh statistics is an error, not a silent fallback (on
    // by default it is off with mesh_off_reason() instead). A class too slow for two input-shaft
    // revolutions, or without mesh lines, runs without it (mesh_classes() counts the others).
    check_mesh_cusum(decision.mesh);
    if (!baseline_.policy.mesh_stats) {
      throw Error(
          "monitor: [decision] mesh_cusum = true needs a baseline with mesh statistics (format 8, "
          "trained with mesh_cusum = true); this baseline has none: retrain it with [decision] "
          "mesh_cusum = true");
    }
    for (const ClassBaseline& c : baseline_.classes) {
      mesh_scale_.push_back(mesh_scale(c, decision.mesh.one_day_allowance));
      if (!mesh_scale_.back().any()) {
        mesh_demod_.emplace_back();
        continue;
      }
      try {
        mesh_demod_.emplace_back(
            std::in_place, mesh_geometry(baseline_.fs_hz, baseline_.window_len, baseline_.gearbox, c.segment),
            c.mean_magnitude);
      } catch (const Error& e) {
        throw Error("monitor: baseline class " + std::to_string(c.segment.id) + ": " + e.what());
      }
      if (mesh_demod_.back()->line_harmonics() == 0) {
        mesh_demod_.back().reset();
        mesh_scale_.back() = MeshScale{};
      }
    }
  }
  if (decision.band.enabled && !decision.band.required)
    band_off_reason_ = band_cusum_unusable(decision, baseline_, method);
  if (decision.band.enabled && band_off_reason_.empty()) {
    // The clean bins are derived from the stored mean as training derived them; the counts stored per
    // band prove it (a baseline edited by hand or from another build would otherwise score other bins).
    std::array<std::uint32_t, kMaxBands> counts{};
    for (std::size_t i = 0; i < baseline_.classes.size(); ++i) {
      const ClassBaseline& c = baseline_.classes[i];
      band_clean_.push_back(clean_floor_bins(c.mean_magnitude));
      band_scale_.push_back(band_scale(c, decision.band.day_allowance));
      clean_bins_per_band(band_clean_.back(), c.band_stats.size(), counts);
      for (std::size_t b = 0; b < c.band_stats.size(); ++b) {
        if (counts[b] != c.band_stats[b].clean_bins) {
          throw Error("monitor: baseline class " + std::to_string(i) + " band " + std::to_string(b) +
                      " has " + std::to_string(c.band_stats[b].clean_bins) +
                      " clean bins stored but its mean spectrum gives " + std::to_string(counts[b]) +
                      ": the band statistics do not belong to this mean (retrain)");
        }
      }
    }
  }
}

std::size_t MonitorEngine::mesh_classes() const noexcept {
  std::size_t n = 0;
  for (const auto& d : mesh_demod_) n += d.has_value() ? 1U : 0U;
  return n;
}

DecisionState::DecisionState(const DecisionConfig& decision, std::size_t classes)
    : debouncer_(decision.k, decision.n),
      seq_(decision.sequential),
      cusum_(classes),
      band_(decision.band),
      mesh_(decision.mesh) {
  if (mesh_.enabled) {
    check_mesh_cusum(mesh_);
    mesh_cap_ = mesh_.h + static_cast<double>(decision.n - std::min(decision.k, decision.n)) * mesh_.k;
    mesh_s_.assign(classes, std::array<double, kMeshFeatureCount>{});
  }
  check_sequential(seq_);
  cap_ = seq_.h_alarm + static_cast<double>(decision.n - std::min(decision.k, decision.n)) * seq_.k;
  if (band_.enabled) {
    check_band_cusum(band_);
    band_cap_ = band_.h + static_cast<double>(decision.n - std::min(decision.k, decision.n)) * band_.k;
    band_s_.assign(classes, std::array<double, kMaxBands>{});
    band_since_.assign(classes, std::array<std::uint64_t, kMaxBands>{});
  }
}

void DecisionState::scored(WindowResult& w, std::size_t cls) noexcept {
  debouncer_.push(w.verdict.abnormal());
  if (seq_.enabled && cls < cusum_.size()) {
    Cusum& c = cusum_[cls];
    c.update(w.z_rms, w.z_entropy, seq_.k, cap_, w.seq_allowance_rms, w.seq_allowance_entropy, seq_.step_cap);
    w.seq_statistic = c.statistic();
    w.seq_feature = c.feature();
  }
  if (band_.enabled && cls < band_s_.size()) {
    // S_b <- min(cap, max(0, S_b + min(x_b - k, step_cap))), x_b = z_b minus the class's day
    // allowance; a non-finite x_b counts as k + 1, as in the feature CUSUM.
    std::array<double, kMaxBands>& s = band_s_[cls];
    std::array<std::uint64_t, kMaxBands>& since = band_since_[cls];
    const std::size_t m = std::min<std::size_t>(w.band_count, kMaxBands);
    double top = 0.0;
    std::uint64_t top_since = 0;
    std::int32_t top_b = -1;
    for (std::size_t b = 0; b < m; ++b) {
      const double x =
          std::isfinite(w.band_excess[b]) ? static_cast<double>(w.band_excess[b]) : band_.k + 1.0;
      s[b] = cusum_step(s[b], x - band_.k, band_.step_cap, band_cap_);
      if (!(s[b] > band_.h)) {
        since[b] = 0;
      } else if (since[b] == 0) {
        since[b] = ++band_order_;
      }
      if (band_first(s[b], since[b], top, top_since)) {
        top = s[b];
        top_since = since[b];
        top_b = static_cast<std::int32_t>(b);
      }
    }
    w.band_statistic = top;
    w.band_index = top_b;
  }
  if (mesh_.enabled && cls < mesh_s_.size()) {
    // S <- min(cap, max(0, S + x - k)); a feature the window does not have (NaN) leaves S as it was:
    // slow windows and classes without mesh lines are not evidence either way.
    std::array<double, kMeshFeatureCount>& s = mesh_s_[cls];
    double top = 0.0;
    std::int32_t top_f = -1;
    for (std::size_t f = 0; f < kMeshFeatureCount; ++f) {
      if (std::isfinite(w.mesh_excess[f]))
        s[f] = cusum_step(s[f], w.mesh_excess[f] - mesh_.k, mesh_.step_cap, mesh_cap_);
      if (s[f] > top) {
        top = s[f];
        top_f = static_cast<std::int32_t>(f);
      }
    }
    w.mesh_statistic = top;
    w.mesh_feature = top_f;
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
  w.band_on = band_.enabled;
  if (band_.enabled) {
    double top = 0.0;
    std::uint64_t top_since = 0;
    w.band_max_index = -1;
    w.band_max_class = -1;
    for (std::size_t c = 0; c < band_s_.size(); ++c) {
      for (std::size_t b = 0; b < kMaxBands; ++b) {
        if (band_first(band_s_[c][b], band_since_[c][b], top, top_since)) {
          top = band_s_[c][b];
          top_since = band_since_[c][b];
          w.band_max_index = static_cast<std::int32_t>(b);
          w.band_max_class = static_cast<std::int32_t>(c);
        }
      }
    }
    w.band_max_statistic = top;
    w.band_alarm = top > band_.h;
    w.band_lo_hz = 0.0;
    w.band_hi_hz = 0.0;
    if (w.band_max_index >= 0 && band_.half_bins > 0 && band_.band_count > 0) {
      const auto b = static_cast<std::size_t>(w.band_max_index);
      w.band_lo_hz = static_cast<double>(band_edge(band_.half_bins, band_.band_count, b)) * band_.bin_hz;
      w.band_hi_hz =
          static_cast<double>(band_edge(band_.half_bins, band_.band_count, b + 1) - 1) * band_.bin_hz;
    }
  }
  w.mesh_on = mesh_.enabled;
  if (mesh_.enabled) {
    double top = 0.0;
    w.mesh_max_feature = -1;
    w.mesh_max_class = -1;
    for (std::size_t c = 0; c < mesh_s_.size(); ++c) {
      for (std::size_t f = 0; f < kMeshFeatureCount; ++f) {
        if (mesh_s_[c][f] > top) {
          top = mesh_s_[c][f];
          w.mesh_max_feature = static_cast<std::int32_t>(f);
          w.mesh_max_class = static_cast<std::int32_t>(c);
        }
      }
    }
    w.mesh_max_statistic = top;
    w.mesh_alarm = top > mesh_.h;
  }
  w.alarm = w.kofn_alarm || w.seq_alarm || w.band_alarm || w.mesh_alarm;
  const unsigned bits = (w.kofn_alarm ? 1U : 0U) | (w.seq_alarm ? 2U : 0U) | (w.band_alarm ? 4U : 0U) |
                        (w.mesh_alarm ? 8U : 0U);
  w.detector = static_cast<AlarmDetector>(bits);
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
  if (!band_scale_.empty()) {
    // Band energies of the residual the analyzer just formed (no extra transform).
    const BandScale& bs = band_scale_[ci];
    band_log_energies(analyzer_.residual_energy(), band_clean_[ci], bs.count, band_tmp_);
    out.band_count = static_cast<std::uint8_t>(bs.count);
    double top = -std::numeric_limits<double>::infinity();
    for (std::size_t b = 0; b < bs.count; ++b) {
      const double x = bs.active[b] != 0 ? (band_tmp_[b] - bs.mean[b]) / bs.sd[b] - bs.allowance[b] : 0.0;
      out.band_excess[b] = static_cast<float>(x);
      top = std::max(top, x);
    }
    out.band_z_max = bs.count > 0 ? top : 0.0;
  }
  if (!mesh_scale_.empty() && mesh_demod_[ci].has_value()) {
    // The window's own spectrum, which the analyzer just formed (no extra forward transform).
    const MeshValues v = mesh_demod_[ci]->compute(analyzer_.spectrum(), ref.speed_rad_s);
    const MeshScale& ms = mesh_scale_[ci];
    for (std::size_t f = 0; f < kMeshFeatureCount; ++f) {
      out.mesh_value[f] = v.v[f];
      if (ms.active[f] && std::isfinite(v.v[f]))
        out.mesh_excess[f] = (v.v[f] - ms.mean[f]) / ms.sd[f] - ms.allowance[f];
    }
  }
  decision_.scored(out, ci);
}

}  // namespace ptda::dsp
